import os
import struct
from io import BytesIO

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
    write_disparity_png,
    write_float_map,
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


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    shape=st.tuples(st.integers(1, 6), st.integers(1, 6)).flatmap(
        lambda hw: st.sampled_from([hw, hw + (3,)])),
    dtype=st.sampled_from([np.float32, np.float64]),
    data=st.data(),
)
def test_pfm_round_trip_any_shape_and_value(tmp_path, shape, dtype, data):
    width = 32 if dtype == np.float32 else 64
    values = data.draw(st.lists(st.floats(width=width, allow_nan=True, allow_infinity=True),
                                min_size=int(np.prod(shape)), max_size=int(np.prod(shape))))
    array = np.array(values, dtype=dtype).reshape(shape)
    path = tmp_path / "d.pfm"
    write_pfm(path, array)
    out = read_pfm(path)
    with np.errstate(over="ignore"):
        expected = array.astype(np.float32)  # float64 beyond float32 becomes inf, like the writer
    assert out.dtype == np.float32 and out.shape == shape
    np.testing.assert_array_equal(out.view(np.uint32), expected.view(np.uint32))  # bit for bit


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


# Files as bytes: random, after a PFM magic, or a valid file overwritten and cut.
_PFM_BYTES = st.one_of(
    st.binary(max_size=64),
    st.builds(lambda head, tail: head + tail,
              st.sampled_from([b"Pf", b"PF", b"Pf\n", b"PF\n3 2\n"]), st.binary(max_size=64)),
    st.builds(_mutate, st.integers(0, 14), st.binary(min_size=1, max_size=3), st.integers(0, 30)),
).map(lambda data: (data, None))

# Files as headers: fuzzed tokens (magic, width, height, scale) between fuzzed separators.
_SEPARATORS = st.sampled_from([b" ", b"\n", b"\r\n", b"\t", b"  \n", b"\n\n", b""])
_NUMBER_TOKENS = st.one_of(
    st.integers(-3, 12).map(lambda n: str(n).encode()),
    st.sampled_from([b"999999999999", b"1e3", b"0x10", b"3.0", b"+4", b"\xff", b"\xd9\xa3"]),
    st.binary(min_size=1, max_size=4),
)
_SCALE_TOKENS = st.one_of(
    st.sampled_from([b"-1.0", b"1.0", b"-1", b"0", b"-0.0", b"nan", b"inf", b"-inf", b"1e400", b"x"]),
    st.floats().map(lambda f: repr(f).encode()),
    st.binary(min_size=1, max_size=4),
)


def _header_file(magic, width, height, scale, separators, body):
    """The file's bytes and, for a clean header (no empty or blank token, no empty separator),
    its ``(magic, width, height)`` tokens, which a successful read must follow; else None."""
    tokens = (magic, width, height, scale)
    header = b"".join(token + separator for token, separator in zip(tokens, separators))
    clean = all(t and not any(chr(b).isspace() for b in t) for t in tokens) and all(separators)
    return header + bytes(range(256))[:body], (magic, width, height) if clean else None


_PFM_HEADERS = st.builds(
    _header_file,
    magic=st.one_of(st.sampled_from([b"Pf", b"PF", b"pf", b"P5", b"PFF"]), st.binary(min_size=1, max_size=3)),
    width=_NUMBER_TOKENS,
    height=_NUMBER_TOKENS,
    scale=_SCALE_TOKENS,
    separators=st.lists(_SEPARATORS, min_size=4, max_size=4),
    body=st.integers(0, 200),
)


@settings(max_examples=600, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(case=st.one_of(_PFM_BYTES, _PFM_HEADERS))
def test_pfm_fuzz_only_input_error(tmp_path, case):
    """Fuzzed bytes and fuzzed headers: an image, or an ``InputError`` naming the file in one line."""
    data, expected = case
    path = tmp_path / "fuzz.pfm"
    path.write_bytes(data)
    try:
        out = read_pfm(path)
    except InputError as error:
        assert "\n" not in str(error) and str(path) in str(error)
    else:
        assert out.dtype == np.float32 and out.ndim in (2, 3)
        if expected is not None:  # a clean header: the size is the header's
            magic, width, height = expected
            channels = 3 if magic == b"PF" else 1
            assert out.shape[:2] == (int(height), int(width))
            assert out.size == int(height) * int(width) * channels


def test_write_pfm_rejects_bad_input(tmp_path):
    with pytest.raises(TypeError, match="array"):
        write_pfm(tmp_path / "a.pfm", np.zeros((2, 2), np.uint8))
    with pytest.raises(ValueError, match="array"):
        write_pfm(tmp_path / "a.pfm", np.zeros((2, 2, 2), np.float32))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("suffix", [".pfm", ".npy", ".tif", ".tiff", ".NPY"])
def test_float_map_by_extension_round_trip(tmp_path, suffix):
    array = np.random.default_rng(1).uniform(-5, 200, (5, 7)).astype(np.float32)
    array[0, 0], array[1, 1] = np.inf, np.nan
    path = tmp_path / f"m{suffix}"
    write_float_map(path, array)
    back = {".pfm": read_pfm, ".npy": np.load}.get(suffix.lower(), iio.imread)(path)
    assert back.dtype == np.float32
    np.testing.assert_array_equal(back, array)
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]


def test_float_map_refuses_other_extensions(tmp_path):
    for name in ("m.png", "m"):
        with pytest.raises(ValueError, match=f"cannot write .*{name}: a map is written as .pfm, "
                                             ".npy, .tif, .tiff, not"):
            write_float_map(tmp_path / name, np.zeros((2, 2), np.float32))
    assert list(tmp_path.iterdir()) == []


def test_writers_write_a_given_temporary_file_with_atomic_false(tmp_path):
    """``atomic=False``: the file named is written itself, whatever its name ends with (the
    format comes from ``suffix``), and nothing else appears."""
    array = np.arange(6, dtype=np.float32).reshape(2, 3)
    write_pfm(tmp_path / "a.tmp", array, atomic=False)
    write_float_map(tmp_path / "b.tmp", array, suffix=".npy", atomic=False)
    write_float_map(tmp_path / "c.tmp", array, suffix=".tif", atomic=False)
    write_disparity_png(tmp_path / "d.tmp", array, atomic=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.tmp", "b.tmp", "c.tmp", "d.tmp"]
    np.testing.assert_array_equal(read_pfm(tmp_path / "a.tmp"), array)
    np.testing.assert_array_equal(np.load(tmp_path / "b.tmp"), array)
    np.testing.assert_array_equal(iio.imread(tmp_path / "c.tmp", extension=".tif"), array)
    assert iio.imread(tmp_path / "d.tmp", extension=".png").shape == (2, 3, 3)


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


@pytest.fixture(scope="module")
def small_png(texture):
    """A 6x9 colour image and its PNG bytes."""
    image = texture(6, (6, 9, 3))
    buffer = BytesIO()
    iio.imwrite(buffer, image, extension=".png")
    return image, buffer.getvalue()


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cut=st.integers(0, 400),
       flips=st.lists(st.tuples(st.integers(0, 400), st.integers(0, 255)), max_size=3))
def test_damaged_png_raises_only_input_error(tmp_path, small_png, cut, flips):
    image, png = small_png
    data = bytearray(png)
    for position, value in flips:
        if position < len(data):
            data[position] = value
    data = bytes(data[: len(data) - min(cut, len(data))])
    path = tmp_path / "damaged.png"
    path.write_bytes(data)
    try:
        out = read_image(path)
    except InputError as error:
        assert "\n" not in str(error) and str(path) in str(error)
    else:
        assert out.ndim in (2, 3) and out.dtype in (np.uint8, np.uint16)
        if not flips:  # only the trailing IEND chunk was cut: the pixels are all there
            np.testing.assert_array_equal(out, image)


def test_read_image_one_bit_png(tmp_path, texture):
    from PIL import Image

    bits = texture(5, (24, 40)) > 127
    Image.fromarray(bits).save(tmp_path / "bits.png")
    image = read_image(tmp_path / "bits.png")
    assert image.dtype == np.uint8
    np.testing.assert_array_equal(image, bits * 255)



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
