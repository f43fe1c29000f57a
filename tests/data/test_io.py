import os
import struct

import imageio.v3 as iio
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sswjax.data import io
from sswjax.data.io import (
    InputError,
    atomic_output,
    disparity_to_rgb,
    read_image,
    read_pfm,
    to_float_image,
    write_disparity_png,
    write_pfm,
)


# ----------------------------------------------------------------------------- PFM


@pytest.mark.parametrize("shape", [(1, 1), (1, 5), (4, 1), (3, 7), (16, 9), (2, 3, 3)])
def test_pfm_round_trip(tmp_path, shape):
    rng = np.random.default_rng(0)
    array = rng.uniform(-5, 200, size=shape).astype(np.float32)
    array.flat[0] = np.inf
    path = tmp_path / "d.pfm"
    write_pfm(path, array)
    out = read_pfm(path)
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out, array)


def test_pfm_written_bytes_are_bottom_to_top(tmp_path):
    array = np.array([[1, 2, 3], [4, 5, 6]], np.float32)
    path = tmp_path / "d.pfm"
    write_pfm(path, array)
    expected = b"Pf\n3 2\n-1.0\n" + struct.pack("<6f", 4, 5, 6, 1, 2, 3)
    assert path.read_bytes() == expected


def test_pfm_read_hand_built_bytes(tmp_path):
    path = tmp_path / "d.pfm"
    # Odd but legal whitespace between tokens; bottom row stored first.
    path.write_bytes(b"Pf \n 2\t2\n\n-0.5\n" + struct.pack("<4f", 3, 4, 1, np.inf))
    np.testing.assert_array_equal(read_pfm(path), [[1, np.inf], [3, 4]])


def test_pfm_big_endian(tmp_path):
    path = tmp_path / "d.pfm"
    path.write_bytes(b"Pf\n2 1\n1.0\n" + struct.pack(">2f", 1.5, -2.25))
    out = read_pfm(path)
    assert out.dtype == np.float32 and out.dtype.byteorder in "=|"
    np.testing.assert_array_equal(out, [[1.5, -2.25]])


def test_pfm_colour(tmp_path):
    path = tmp_path / "c.pfm"
    path.write_bytes(b"PF\n1 2\n-1.0\n" + struct.pack("<6f", 4, 5, 6, 1, 2, 3))
    np.testing.assert_array_equal(read_pfm(path), [[[1, 2, 3]], [[4, 5, 6]]])


def test_pfm_crlf_header(tmp_path):
    path = tmp_path / "d.pfm"
    path.write_bytes(b"Pf\r\n1 1\r\n-1.0\r\n" + struct.pack("<f", 7))
    np.testing.assert_array_equal(read_pfm(path), [[7]])


@pytest.mark.parametrize(
    "content, message",
    [
        (b"Pf\n3 2\n-1.0\n" + b"\0" * 23, "truncated"),
        (b"Pf\n3 2\n-1.0\n", "truncated"),
        (b"Pf\n3 2", "header"),
        (b"", "header"),
        (b"P5\n3 2\n-1.0\n" + b"\0" * 24, "magic"),
        (b"Pf\nx 2\n-1.0\n" + b"\0" * 24, "size"),
        (b"Pf\n0 2\n-1.0\n" + b"\0" * 24, "size"),
        (b"Pf\n-3 2\n-1.0\n" + b"\0" * 24, "size"),
        (b"Pf\n3 2\n0.0\n" + b"\0" * 24, "scale"),
        (b"Pf\n3 2\nabc\n" + b"\0" * 24, "scale"),
        (b"Pf\n3 2\n\xff\xfe\n" + b"\0" * 24, "scale"),
        (b"Pf\n99999999999999999999 99999999999\n-1\n" + b"\0" * 24, "truncated"),
    ],
)
def test_pfm_bad_files(tmp_path, content, message):
    path = tmp_path / "bad.pfm"
    path.write_bytes(content)
    with pytest.raises(InputError, match=message) as info:
        read_pfm(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


def test_pfm_missing_file(tmp_path):
    with pytest.raises(InputError, match="not found: .*nope.pfm"):
        read_pfm(tmp_path / "nope.pfm")


_VALID = b"Pf\n3 2\n-1.0\n" + struct.pack("<6f", *range(6))


def _mutate(pos, new, cut):
    """Overwrite bytes of a valid file at ``pos`` (header region) and drop ``cut`` end bytes."""
    data = _VALID[:pos] + new + _VALID[pos + len(new) :]
    return data[: len(data) - cut]


@settings(
    max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    data=st.one_of(
        st.binary(max_size=64),
        st.builds(
            lambda head, tail: head + tail,
            st.sampled_from([b"Pf", b"PF", b"Pf\n", b"PF\n3 2\n"]),
            st.binary(max_size=64),
        ),
        st.builds(
            _mutate,
            st.integers(0, 14),
            st.binary(min_size=1, max_size=3),
            st.integers(0, 30),
        ),
    )
)
def test_pfm_fuzz_only_input_error(tmp_path, data):
    path = tmp_path / "fuzz.pfm"
    path.write_bytes(data)
    try:
        out = read_pfm(path)
    except InputError as exc:
        assert "\n" not in str(exc)
    else:
        assert out.dtype == np.float32 and out.ndim in (2, 3)


def test_write_pfm_rejects_bad_input(tmp_path):
    with pytest.raises(TypeError, match="array"):
        write_pfm(tmp_path / "a.pfm", np.zeros((2, 2), np.uint8))
    with pytest.raises(ValueError, match="array"):
        write_pfm(tmp_path / "a.pfm", np.zeros((2, 2, 2), np.float32))
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------- atomicity


def test_write_pfm_is_atomic_on_failure(tmp_path, monkeypatch):
    path = tmp_path / "d.pfm"
    write_pfm(path, np.ones((2, 2), np.float32))
    before = path.read_bytes()

    real_open = open

    class Exploding:
        def __init__(self, f):
            self.f = f

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.f.close()

        def write(self, data):
            self.f.write(data[:3])
            raise RuntimeError("disk on fire")

    monkeypatch.setattr(io, "open", lambda *a, **k: Exploding(real_open(*a, **k)), raising=False)
    with pytest.raises(RuntimeError, match="disk on fire"):
        write_pfm(path, np.zeros((5, 5), np.float32))
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.pfm"]


def test_write_disparity_png_is_atomic_on_failure(tmp_path, monkeypatch):
    path = tmp_path / "d.png"
    path.write_bytes(b"old content")

    def failing_imwrite(uri, *args, **kwargs):
        with open(uri, "wb") as f:
            f.write(b"partial")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(io.iio, "imwrite", failing_imwrite)
    with pytest.raises(InputError, match="cannot write .*d.png: No space left"):
        write_disparity_png(path, np.zeros((3, 4), np.float32))
    assert path.read_bytes() == b"old content"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.png"]


def test_atomic_output_success_and_permissions(tmp_path):
    path = tmp_path / "out.txt"
    with atomic_output(path) as tmp:
        assert tmp.parent == tmp_path and tmp.name.endswith(".tmp")
        tmp.write_text("new")
        assert not path.exists()
    assert path.read_text() == "new"
    assert list(tmp_path.iterdir()) == [path]
    umask = os.umask(0)
    os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask


def test_atomic_output_missing_directory(tmp_path):
    with pytest.raises(InputError, match="cannot write .*missing"):
        with atomic_output(tmp_path / "missing" / "out.txt"):
            pass


# ----------------------------------------------------------------------------- images


def test_read_image_rgb8(tmp_path):
    image = np.random.default_rng(1).integers(0, 256, (5, 7, 3), dtype=np.uint8)
    iio.imwrite(tmp_path / "a.png", image)
    out = read_image(tmp_path / "a.png")
    assert out.dtype == np.uint8
    np.testing.assert_array_equal(out, image)


def test_read_image_gray16(tmp_path):
    image = np.arange(12, dtype=np.uint16).reshape(3, 4) * 5000
    iio.imwrite(tmp_path / "g.png", image)
    out = read_image(tmp_path / "g.png")
    assert out.dtype == np.uint16
    np.testing.assert_array_equal(out, image)


def test_read_image_drops_alpha(tmp_path):
    rgba = np.random.default_rng(2).integers(0, 256, (4, 6, 4), dtype=np.uint8)
    iio.imwrite(tmp_path / "rgba.png", rgba)
    np.testing.assert_array_equal(read_image(tmp_path / "rgba.png"), rgba[..., :3])
    iio.imwrite(tmp_path / "la.png", rgba[..., :2])
    np.testing.assert_array_equal(read_image(tmp_path / "la.png"), rgba[..., 0])


def test_read_image_missing_and_corrupt(tmp_path):
    with pytest.raises(InputError, match="image not found: .*nope.png"):
        read_image(tmp_path / "nope.png")
    (tmp_path / "bad.png").write_bytes(b"\x89PNG\r\n\x1a\n garbage")
    with pytest.raises(InputError, match="cannot read image .*bad.png") as info:
        read_image(tmp_path / "bad.png")
    assert "\n" not in str(info.value)


def test_to_float_image():
    np.testing.assert_array_equal(to_float_image(np.array([[0, 255]], np.uint8)), [[0, 1]])
    out = to_float_image(np.array([[0, 65535]], np.uint16))
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out, [[0, 1]])
    src = np.full((2, 2, 3), 0.25)
    out = to_float_image(src)
    assert out.dtype == np.float32 and out.shape == (2, 2, 3) and np.all(out == 0.25)


def test_to_float_image_errors():
    with pytest.raises(TypeError, match="bool"):
        to_float_image(np.zeros((2, 2), bool))
    with pytest.raises(TypeError, match="int32"):
        to_float_image(np.zeros((2, 2), np.int32))
    with pytest.raises(ValueError, match="non-finite"):
        to_float_image(np.array([[0.0, np.nan]]))
    with pytest.raises(ValueError, match="non-finite"):
        to_float_image(np.array([[0.0, 1e300]]))  # overflows float32, without a warning
    with pytest.raises(ValueError, match="shape"):
        to_float_image(np.zeros((2, 2, 4), np.uint8))
    with pytest.raises(ValueError, match="rank"):
        to_float_image(np.zeros(4, np.uint8))


# ----------------------------------------------------------------------------- display


def test_disparity_to_rgb():
    disparity = np.array([[0.0, 5.0, 10.0, np.inf, np.nan]], np.float32)
    rgb = disparity_to_rgb(disparity)
    assert rgb.dtype == np.uint8 and rgb.shape == (1, 5, 3)
    np.testing.assert_array_equal(rgb[0, 3:], 0)
    assert rgb[0, 0].sum() > 0  # the low end is dark blue, not black
    assert rgb[0, 0, 2] > rgb[0, 0, 0] and rgb[0, 2, 0] > rgb[0, 2, 2]  # blue -> red
    # An explicit range: values beyond it are clipped to the ends of the colour map.
    clipped = disparity_to_rgb(disparity, vmin=2.0, vmax=8.0)
    assert np.array_equal(clipped[0, 0], rgb[0, 0]) and np.array_equal(clipped[0, 2], rgb[0, 2])
    assert disparity_to_rgb(np.full((2, 2), np.inf, np.float32)).max() == 0
    assert disparity_to_rgb(np.full((2, 2), 3.0, np.float32)).shape == (2, 2, 3)
    with pytest.raises(ValueError, match="vmin"):
        disparity_to_rgb(disparity, vmin=5.0, vmax=5.0)


def test_write_disparity_png(tmp_path):
    disparity = np.linspace(0, 1, 12, dtype=np.float32).reshape(3, 4)
    write_disparity_png(tmp_path / "d.png", disparity, vmin=0.0, vmax=1.0)
    expected = disparity_to_rgb(disparity, vmin=0, vmax=1)
    np.testing.assert_array_equal(iio.imread(tmp_path / "d.png"), expected)
    assert [p.name for p in tmp_path.iterdir()] == ["d.png"]
