"""Photos stored turned, with an EXIF ``Orientation`` tag, are read upright (issue 72, item 2).

The tagged files are written here with Pillow: the upright pixels turned the other way and the
tag that turns them back. Pillow's own ``ImageOps.exif_transpose`` is the reference for what each
of the 8 orientations means; imageio, which reads the stored pixels as they are, gives the
stored pixels of lossy files. The command-line runs match 24x40 pairs with ndisp 8 and conftest's
``tiny`` configuration (conftest's sizes), so they share one compilation with the other plumbing
tests.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest
from PIL import Image, ImageOps

import sswjax
from sswjax.cluster.pairs import image_size
from sswjax.data.io import read_image, read_oriented, read_pfm

NDISP = 8

STORED = {  # the stored pixels of an upright image, for each tag (the inverse of the tag's turn)
    1: lambda a: a,
    2: lambda a: a[:, ::-1],
    3: lambda a: a[::-1, ::-1],
    4: lambda a: a[::-1],
    5: lambda a: a.swapaxes(0, 1),
    6: lambda a: np.rot90(a, 1),
    7: lambda a: a[::-1, ::-1].swapaxes(0, 1),
    8: lambda a: np.rot90(a, -1),
}


def _exif(orientation: int) -> Image.Exif:
    exif = Image.Exif()
    exif[0x0112] = orientation
    return exif


def write_tagged(path: Path, upright: np.ndarray, orientation: int, **options) -> Path:
    """Write ``upright`` stored as a camera turned by ``orientation`` would, with the tag."""
    stored = np.ascontiguousarray(STORED[orientation](upright))
    Image.fromarray(stored).save(path, exif=_exif(orientation), **options)
    return path


def _with_exif_chunk(png: bytes, orientation: int) -> bytes:
    """``png`` with an ``eXIf`` chunk (the tag) right after its IHDR chunk."""
    data = _exif(orientation).tobytes()
    data = data[6:] if data.startswith(b"Exif\x00\x00") else data
    chunk = (struct.pack(">I", len(data)) + b"eXIf" + data
             + struct.pack(">I", zlib.crc32(b"eXIf" + data)))
    end_of_ihdr = 8 + 8 + 13 + 4
    return png[:end_of_ihdr] + chunk + png[end_of_ihdr:]


@pytest.fixture(scope="module")
def upright(texture):
    """A 24x40 pair at disparity 3, upright."""
    right = texture(0)
    return np.roll(right, 3, axis=1), right


@pytest.mark.parametrize("orientation", range(1, 9))
def test_read_image_turns_every_orientation_upright(tmp_path, upright, orientation):
    path = write_tagged(tmp_path / "im.png", upright[0], orientation)
    with Image.open(path) as image:  # the file means what the test says (Pillow's reading)
        assert np.array_equal(np.asarray(ImageOps.exif_transpose(image)), upright[0])
    image, applied = read_oriented(path)
    assert applied == orientation
    assert image.shape == (24, 40, 3) and image.dtype == np.uint8
    assert np.array_equal(image, upright[0])
    assert np.array_equal(read_image(path), upright[0])
    assert image.flags.c_contiguous


@pytest.mark.parametrize("form", ["jpg", "tif", "webp", "png16-colour", "png-gray"])
def test_read_image_turns_each_format_upright(tmp_path, upright, form):
    if form == "jpg":
        path = write_tagged(tmp_path / "im.jpg", upright[0], 6, quality=95)
        expected = np.rot90(iio.imread(path), -1)  # the stored pixels as decoded, turned
    elif form == "tif":
        path = write_tagged(tmp_path / "im.tif", upright[0], 6)
        expected = upright[0]
    elif form == "webp":
        path = write_tagged(tmp_path / "im.webp", upright[0], 6, lossless=True)
        expected = upright[0]
    elif form == "png-gray":
        expected = upright[0][..., 0]
        path = write_tagged(tmp_path / "im.png", expected, 8)
    else:  # 16 bits of colour: the image is decoded by OpenCV and keeps its 16 bits
        cv2 = pytest.importorskip("cv2")
        expected = upright[0].astype(np.uint16) * np.uint16(257) + np.uint16(3)
        stored = np.ascontiguousarray(STORED[6](expected)[..., ::-1])  # BGR for OpenCV
        ok, png = cv2.imencode(".png", stored)
        assert ok
        path = tmp_path / "im.png"
        path.write_bytes(_with_exif_chunk(png.tobytes(), 6))
    image = read_image(path)
    assert image.shape == expected.shape and image.dtype == expected.dtype
    assert np.array_equal(image, expected)


@pytest.mark.parametrize("suffix", ["png", "jpg", "tif", "webp"])
def test_image_size_from_the_header_is_upright(tmp_path, upright, suffix):
    path = write_tagged(tmp_path / f"im.{suffix}", upright[0], 6)
    assert image_size(path) == (24, 40, 3) == read_image(path).shape


@pytest.fixture(scope="module")
def upright_map(tmp_path_factory, upright, tiny):
    """The command line's map of the upright pair, and the folder of its files."""
    folder = tmp_path_factory.mktemp("upright")
    iio.imwrite(folder / "left.png", upright[0])
    iio.imwrite(folder / "right.png", upright[1])
    code, _ = _run(["match", folder / "left.png", folder / "right.png", "--ndisp", NDISP,
                    "-o", folder / "d.pfm", *tiny.args])
    assert code == 0
    return read_pfm(folder / "d.pfm")


def _run(argv):
    from sswjax.cli import main

    try:
        return main([str(a) for a in argv]), None
    except SystemExit as exit_:
        return exit_.code, None


@pytest.mark.parametrize("orientation", [3, 6, 8])
def test_cli_matches_a_turned_pair_as_the_upright_one(tmp_path, run_cli, tiny, upright,
                                                      upright_map, orientation):
    left = write_tagged(tmp_path / "left.png", upright[0], orientation)
    right = write_tagged(tmp_path / "right.png", upright[1], orientation)
    code, _, err = run_cli(["match", left, right, "--ndisp", NDISP, "-o", tmp_path / "d.pfm",
                            *tiny.args])
    assert code == 0, err
    words = {3: "3: rotated 180°", 6: "6: rotated 90° clockwise",
             8: "8: rotated 90° counter-clockwise"}[orientation]
    assert err.splitlines() == [f"sswjax: note: LEFT: applied its EXIF orientation ({words})",
                                f"sswjax: note: RIGHT: applied its EXIF orientation ({words})"]
    disparity = read_pfm(tmp_path / "d.pfm")
    assert disparity.shape == upright_map.shape == (24, 40)
    assert np.array_equal(disparity, upright_map)


def test_cli_matches_a_turned_jpeg_pair_as_its_pixels_turned(tmp_path, run_cli, tiny, upright,
                                                             upright_map):
    paths = [write_tagged(tmp_path / f"{side}.jpg", image, 6, quality=95)
             for side, image in zip(("left", "right"), upright)]
    code, _, err = run_cli(["match", *paths, "--ndisp", NDISP, "-o", tmp_path / "d.pfm",
                            *tiny.args])
    assert code == 0, err
    turned = [np.rot90(iio.imread(path), -1) for path in paths]  # imageio: stored pixels
    disparity = read_pfm(tmp_path / "d.pfm")
    assert disparity.shape == (24, 40)
    assert np.array_equal(disparity, sswjax.match(*turned, NDISP, params=tiny.params))
    assert np.mean(np.abs(disparity - upright_map) <= 1) > 0.9  # JPEG's loss, not a turn


def test_cli_one_turned_image_and_one_upright(tmp_path, run_cli, tiny, upright, upright_map):
    left = write_tagged(tmp_path / "left.png", upright[0], 6)
    right = tmp_path / "right.png"
    iio.imwrite(right, upright[1])
    code, _, err = run_cli(["match", left, right, "--ndisp", NDISP, "-o", tmp_path / "d.pfm",
                            *tiny.args])
    assert code == 0, err
    assert err == "sswjax: note: LEFT: applied its EXIF orientation (6: rotated 90° clockwise)\n"
    assert np.array_equal(read_pfm(tmp_path / "d.pfm"), upright_map)


def test_cli_sizes_that_differ_once_turned_name_the_orientation(tmp_path, run_cli, upright):
    left = tmp_path / "left.png"  # upright pixels, but a tag that turns them
    Image.fromarray(upright[0]).save(left, exif=_exif(6))
    right = tmp_path / "right.png"
    iio.imwrite(right, upright[1])
    out = tmp_path / "d.pfm"
    code, _, err = run_cli(["match", left, right, "--ndisp", NDISP, "-o", out])
    assert code == 2
    assert err == ("sswjax: error: left and right images differ in size: 24x40 and 40x24 once "
                   "LEFT's EXIF orientation (6: rotated 90° clockwise) is applied\n")
    assert [p.name for p in tmp_path.iterdir()] == ["left.png", "right.png"]


def test_cli_folders_match_a_turned_image_as_the_upright_one(tmp_path, run_cli, tiny, upright,
                                                             upright_map):
    (tmp_path / "L").mkdir()
    (tmp_path / "R").mkdir()
    write_tagged(tmp_path / "L" / "a.png", upright[0], 6)
    iio.imwrite(tmp_path / "R" / "a.png", upright[1])
    code, _, err = run_cli(["match", tmp_path / "L", tmp_path / "R", "--ndisp", NDISP,
                            "-o", tmp_path / "out", *tiny.args])
    assert code == 0, err
    assert np.array_equal(read_pfm(tmp_path / "out" / "a.pfm"), upright_map)
