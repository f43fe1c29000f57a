"""Depth maps and point clouds (``sswjax.api.geometry``), PLY files (``sswjax.data.ply``) and
calibration files (``sswjax.data.calibration``)."""

import numpy as np
import pytest

import sswjax
from sswjax.api.geometry import Calibration, depth_from_disparity, point_cloud
from sswjax.data.calibration import read_calibration
from sswjax.data.io import InputError
from sswjax.data.ply import write_cloud, write_ply

MOTORCYCLE_CALIB = """cam0=[999.421 0 294.182; 0 999.421 252.932; 0 0 1]
cam1=[999.421 0 326.96; 0 999.421 252.932; 0 0 1]
doffs=32.778
baseline=193.001
ndisp=70
"""


def read_ply(path):
    """A PLY reader of our own for the test: the header's vertex properties, then the records."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    assert header[:2] == ["ply", "format binary_little_endian 1.0"]
    types = {"float": "<f4", "uchar": "u1"}
    count, fields = None, []
    for line in header:
        words = line.split()
        if words[:2] == ["element", "vertex"]:
            count = int(words[2])
        elif words[0] == "property":
            fields.append((words[2], types[words[1]]))
    vertices = np.frombuffer(data, dtype=np.dtype(fields), count=count, offset=end)
    assert end + vertices.nbytes == len(data)          # nothing after the last vertex
    xyz = np.stack([vertices[c] for c in "xyz"], axis=-1)
    rgb = np.stack([vertices[c] for c in ("red", "green", "blue")], axis=-1)
    return xyz, rgb


# A 2x2 disparity with f = 100 px, baseline 0.5 m, doffs 10 px, principal point (0.5, 0.5):
# Z = 0.5 * 100 / (d + 10), X = (u - 0.5) Z / 100, Y = (v - 0.5) Z / 100.
DISPARITY = np.array([[10.0, 20.0], [15.0, -10.0]], np.float32)   # d + doffs = 20, 30, 25, 0
IMAGE = np.array([[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [9, 8, 7]]], np.uint8)
CALIB = Calibration(focal=100.0, baseline=0.5, doffs=10.0, principal=(0.5, 0.5))
EXPECTED_XYZ = np.array([
    [-0.5 * 2.5 / 100, -0.5 * 2.5 / 100, 2.5],                     # (v, u) = (0, 0): Z = 50 / 20
    [0.5 * (50 / 30) / 100, -0.5 * (50 / 30) / 100, 50 / 30],      # (0, 1): Z = 50 / 30
    [-0.5 * 2.0 / 100, 0.5 * 2.0 / 100, 2.0],                      # (1, 0): Z = 50 / 25
])                                                                 # (1, 1): d + doffs = 0, none


def test_depth_hand_computed():
    depth = depth_from_disparity(DISPARITY, focal=100, baseline=0.5, doffs=10)
    assert depth.dtype == np.float32
    np.testing.assert_allclose(depth, [[2.5, 50 / 30], [2.0, np.inf]], rtol=1e-6)
    edges = depth_from_disparity(np.array([[np.nan, np.inf, -np.inf, 1e-42]], np.float32),
                                 focal=100, baseline=0.5)
    assert edges[0, :3].tolist() == [np.inf] * 3 and edges[0, 3] == np.inf   # float32 overflow


def test_point_cloud_and_ply_hand_computed(tmp_path):
    cloud = point_cloud(DISPARITY, IMAGE, CALIB)
    assert cloud.xyz.dtype == np.float32 and cloud.rgb.dtype == np.uint8
    np.testing.assert_allclose(cloud.xyz, EXPECTED_XYZ, rtol=1e-6)
    np.testing.assert_array_equal(cloud.rgb, IMAGE.reshape(4, 3)[:3])
    # The image centre of a 2x2 image is (0.5, 0.5): the default principal point.
    centred = point_cloud(DISPARITY, IMAGE, CALIB._replace(principal=None))
    np.testing.assert_array_equal(centred.xyz, cloud.xyz)
    write_ply(tmp_path / "cloud.ply", *cloud)
    xyz, rgb = read_ply(tmp_path / "cloud.ply")
    np.testing.assert_allclose(xyz, EXPECTED_XYZ, rtol=1e-6)
    np.testing.assert_array_equal(rgb, IMAGE.reshape(4, 3)[:3])


def test_ply_read_by_plyfile(tmp_path):
    # An independent reader (the bench extras' plyfile) sees the same vertices.
    plyfile = pytest.importorskip("plyfile")
    write_ply(tmp_path / "cloud.ply", *point_cloud(DISPARITY, IMAGE, CALIB))
    vertex = plyfile.PlyData.read(str(tmp_path / "cloud.ply"))["vertex"]
    np.testing.assert_allclose(np.stack([vertex[c] for c in "xyz"], -1), EXPECTED_XYZ, rtol=1e-6)
    np.testing.assert_array_equal(vertex["green"], [0, 255, 0])


def test_ply_read_by_open3d(tmp_path):
    # Open3D, when it installs (it needs libusb here), reads the same points and colours.
    o3d = pytest.importorskip("open3d", exc_type=ImportError)
    write_ply(tmp_path / "cloud.ply", *point_cloud(DISPARITY, IMAGE, CALIB))
    cloud = o3d.io.read_point_cloud(str(tmp_path / "cloud.ply"))
    np.testing.assert_allclose(np.asarray(cloud.points), EXPECTED_XYZ, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(cloud.colors) * 255, IMAGE.reshape(4, 3)[:3])


def test_cloud_by_extension(tmp_path):
    cloud = point_cloud(DISPARITY, IMAGE, CALIB)
    write_cloud(tmp_path / "c.NPZ", *cloud)
    with np.load(tmp_path / "c.NPZ") as saved:
        assert sorted(saved.files) == ["rgb", "xyz"] and saved["xyz"].dtype == np.float32
        np.testing.assert_array_equal(saved["xyz"], cloud.xyz)
        np.testing.assert_array_equal(saved["rgb"], cloud.rgb)
    write_cloud(tmp_path / "c.ply", *cloud)
    np.testing.assert_array_equal(read_ply(tmp_path / "c.ply")[0], cloud.xyz)
    with pytest.raises(ValueError, match="a point cloud is written as .ply or .npz, not '.xyz'"):
        write_cloud(tmp_path / "c.xyz", *cloud)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.NPZ", "c.ply"]


def test_point_cloud_colours_of_every_image_format():
    gray16 = np.array([[0, 65535], [257, 65535]], np.uint16)
    cloud = point_cloud(DISPARITY, gray16, CALIB)
    np.testing.assert_array_equal(cloud.rgb, [[0, 0, 0], [255, 255, 255], [1, 1, 1]])
    floats = point_cloud(DISPARITY, IMAGE.astype(np.float32) / 255, CALIB)
    np.testing.assert_array_equal(floats.rgb, IMAGE.reshape(4, 3)[:3])
    empty = point_cloud(np.full((2, 2), np.inf, np.float32), IMAGE, CALIB)
    assert empty.xyz.shape == (0, 3) and empty.rgb.shape == (0, 3)


def test_read_calibration_middlebury(tmp_path):
    path = tmp_path / "calib.txt"
    path.write_text(MOTORCYCLE_CALIB)
    calib = read_calibration(path)
    assert calib == Calibration(999.421, 193.001, 32.778, (294.182, 252.932))
    path.write_text("cam0=[500 0 20; 0 500 6; 0 0 1]\nbaseline=60\n")   # no ndisp, no doffs
    assert read_calibration(path) == Calibration(500.0, 60.0, 0.0, (20.0, 6.0))


def test_read_calibration_of_the_shared_motorcycle_scene():
    from pathlib import Path

    path = Path(__file__).parents[2] / "shared/data/MiddEval3/trainingQ/Motorcycle/calib.txt"
    if not path.is_file():
        pytest.skip("shared MiddEval3 data not present")
    assert read_calibration(path).focal == pytest.approx(999.421)


@pytest.mark.parametrize("text, message", [
    ("baseline=60\n", "lacks cam0"),
    ("cam0=[500 0 20; 0 500 6; 0 0 1]\n", "lacks baseline"),
    ("doffs=1\n", "lacks cam0 and baseline"),
    ("cam0=[500 0 20; 0 500 6]\nbaseline=60\n", r"cam0 must be \[f 0 cx; 0 f cy; 0 0 1\]"),
    ("cam0=500\nbaseline=60\n", r"cam0 must be \[f 0 cx; 0 f cy; 0 0 1\]"),
    ("cam0=[500 0 20; 0 400 6; 0 0 1]\nbaseline=60\n", "two focal lengths 500 and 400"),
    ("cam0=[0 0 20; 0 0 6; 0 0 1]\nbaseline=60\n", "focal length must be > 0, got 0"),
    ("cam0=[-5 0 20; 0 -5 6; 0 0 1]\nbaseline=60\n", "focal length must be > 0, got -5"),
    ("cam0=[500 0 20; 0 500 6; 0 0 1]\nbaseline=-60\n", "baseline must be > 0, got -60"),
    ("cam0=[500 0 20; 0 500 6; 0 0 1]\nbaseline=far\n", "baseline must be a number, got 'far'"),
    ("cam0=[500 0 20; 0 500 6; 0 0 1]\nbaseline=60\ndoffs=nan\n", "doffs must be finite"),
    ("cam0=[500 0 20; 0 500 6; 0 0 1]\nbaseline=60\nndisp=-4\n", "needs ndisp=<positive integer>"),
    ("cam0 [500 0 20; 0 500 6; 0 0 1]\n", "is not key=value"),
])
def test_read_calibration_bad_files(tmp_path, text, message):
    path = tmp_path / "calib.txt"
    path.write_text(text)
    with pytest.raises(InputError, match=message) as error:
        read_calibration(path)
    assert str(path) in str(error.value) and "\n" not in str(error.value)


def test_read_calibration_missing_file(tmp_path):
    with pytest.raises(InputError, match="calibration file not found: .*nope.txt"):
        read_calibration(tmp_path / "nope.txt")


@pytest.mark.parametrize("call, error, message", [
    (lambda: depth_from_disparity(DISPARITY, focal=0, baseline=1), ValueError,
     "focal length must be > 0, got 0"),
    (lambda: depth_from_disparity(DISPARITY, focal=100, baseline=-1), ValueError,
     "baseline must be > 0, got -1"),
    (lambda: depth_from_disparity(DISPARITY, focal=np.inf, baseline=1), ValueError,
     "focal length must be finite"),
    (lambda: depth_from_disparity(DISPARITY, focal=100, baseline=1, doffs=np.nan), ValueError,
     "doffs must be finite"),
    (lambda: depth_from_disparity(DISPARITY, focal="100", baseline=1), ValueError,
     "focal length must be a number"),
    (lambda: depth_from_disparity(DISPARITY[0], focal=100, baseline=1), ValueError,
     "disparity must have rank 2"),
    (lambda: depth_from_disparity(DISPARITY.astype(int), focal=100, baseline=1), TypeError,
     "disparity must have a floating dtype"),
    (lambda: point_cloud(DISPARITY, IMAGE, {"focal": 100}), TypeError,
     "calib must be a sswjax.Calibration, got dict"),
    (lambda: point_cloud(DISPARITY, IMAGE[:1], CALIB), ValueError,
     "image of 2x1 and disparity of 2x2 differ in size"),
    (lambda: point_cloud(DISPARITY, IMAGE, CALIB._replace(principal=(1.0,))), ValueError,
     r"principal point must be \(cx, cy\)"),
    (lambda: point_cloud(DISPARITY, IMAGE.astype(np.int32), CALIB), ValueError,
     "image must be uint8, uint16 or float"),
    (lambda: write_ply("x.ply", np.zeros((2, 3), np.float32), np.zeros((2, 3), np.int64)),
     TypeError, "rgb must be uint8"),
    (lambda: write_ply("x.ply", np.zeros((2, 2), np.float32), np.zeros((2, 2), np.uint8)),
     ValueError, r"xyz and rgb must both be \(N, 3\)"),
])
def test_geometry_rejects_bad_arguments(call, error, message):
    with pytest.raises(error, match=message):
        call()


def test_write_ply_into_a_missing_folder_leaves_nothing(tmp_path):
    with pytest.raises(InputError, match="cannot write"):
        write_ply(tmp_path / "nope" / "cloud.ply", *point_cloud(DISPARITY, IMAGE, CALIB))
    assert list(tmp_path.iterdir()) == []


def test_top_level_exports():
    assert sswjax.point_cloud is point_cloud and sswjax.write_ply is write_ply
    assert sswjax.depth_from_disparity is depth_from_disparity


# ----------------------------------------------------------------------------- command line

def test_cli_depth_ply_and_kitti_png_by_hand(small_pair, tmp_path, run_cli, tiny):
    from sswjax.data.io import read_pfm

    folder, out = small_pair.folder, tmp_path
    code, _, stderr = run_cli([
        "match", folder / "left.png", folder / "right.png", "--ndisp", small_pair.ndisp,
        "-o", out / "d.pfm", "--depth", out / "z.pfm", "--ply", out / "c.ply",
        "--focal", 100, "--baseline", 0.5, "--doffs", 1, "--principal", 20, 12, *tiny.args])
    assert code == 0, stderr
    disparity, depth = read_pfm(out / "d.pfm"), read_pfm(out / "z.pfm")
    np.testing.assert_array_equal(depth, depth_from_disparity(disparity, focal=100, baseline=0.5,
                                                              doffs=1))
    assert np.median(depth) == pytest.approx(50 / (small_pair.shift + 1), rel=1e-3)
    xyz, rgb = read_ply(out / "c.ply")
    import imageio.v3 as iio
    expected = point_cloud(disparity, iio.imread(folder / "left.png"),
                           Calibration(100.0, 0.5, 1.0, (20.0, 12.0)))
    np.testing.assert_array_equal(xyz, expected.xyz)
    np.testing.assert_array_equal(rgb, expected.rgb)
    assert len(xyz) == np.isfinite(depth).sum()


def test_cli_npz_cloud_and_depth_range(small_pair, tmp_path, run_cli, tiny):
    folder = small_pair.folder
    code, _, stderr = run_cli([
        "match", folder / "left.png", folder / "right.png", "-o", tmp_path / "d.pfm",
        "--ply", tmp_path / "c.npz", "--focal", 100, "--baseline", 0.5,
        "--depth-range", 10, "inf", *tiny.args])     # disparities 0 .. 5 (+ 2 px): 0..7
    assert code == 0, stderr
    assert "depths 10..inf are disparities 0..7 (--min-disp 0 --ndisp 8)" in stderr
    with np.load(tmp_path / "c.npz") as cloud:
        assert cloud["xyz"].shape == (small_pair.height * small_pair.width, 3)


def test_cli_depth_png(small_pair, tmp_path, run_cli, tiny):
    from sswjax.data.io import read_pfm
    from sswjax.data.scaled import read_scaled_disparity

    folder = small_pair.folder
    rig = ["--focal", 100, "--baseline", 0.5, "--ndisp", small_pair.ndisp]
    code, _, stderr = run_cli(["match", folder / "left.png", folder / "right.png", *rig, "-o",
                               tmp_path / "d.pfm", "--depth", tmp_path / "z.PNG",
                               "--depth-scale", 1000, *tiny.args])
    assert code == 0, stderr
    depth = depth_from_disparity(read_pfm(tmp_path / "d.pfm"), focal=100, baseline=0.5)
    written = read_scaled_disparity(tmp_path / "z.PNG", scale=1000)   # 0 -> inf
    expected = np.where(np.isfinite(depth) & (depth * 1000 < 65535.5),
                        np.round(depth * 1000) / 1000, np.inf).astype(np.float32)
    assert np.isfinite(expected).mean() > 0.5
    # One step of the scale apart at most: a depth at a half step may round either way in the
    # writer's float32 and this float64 reference. Compared in steps: two float32 depths one
    # step apart near 16 m differ by 0.0010014, more than a step plus 1e-6.
    np.testing.assert_array_equal(np.isfinite(written), np.isfinite(expected))
    finite = np.isfinite(expected)
    steps = [np.round(values[finite].astype(np.float64) * 1000) for values in (written, expected)]
    assert np.abs(steps[0] - steps[1]).max() <= 1
    assert (written[finite] == expected[finite]).mean() > 0.99


def test_cli_calib_file(small_pair, tmp_path, run_cli, tiny):
    from sswjax.data.io import read_pfm

    calib = tmp_path / "calib.txt"
    calib.write_text("cam0=[200 0 19.5; 0 200 11.5; 0 0 1]\ndoffs=2\nbaseline=30\n")
    folder = small_pair.folder
    code, _, stderr = run_cli(["match", folder / "left.png", folder / "right.png", "--ndisp",
                               small_pair.ndisp, "-o", tmp_path / "d.pfm", "--calib", calib,
                               "--depth", tmp_path / "z.pfm", "--ply", tmp_path / "c.ply",
                               *tiny.args])
    assert code == 0, stderr
    disparity = read_pfm(tmp_path / "d.pfm")
    np.testing.assert_array_equal(read_pfm(tmp_path / "z.pfm"),
                                  depth_from_disparity(disparity, focal=200, baseline=30, doffs=2))
    xyz, _ = read_ply(tmp_path / "c.ply")
    # The principal point is the image centre: the cloud is centred on the optical axis.
    assert abs(np.median(xyz[:, 0])) < 0.5 and abs(np.median(xyz[:, 1])) < 0.5


GOOD_CALIB = "cam0=[200 0 19.5; 0 200 11.5; 0 0 1]\nbaseline=30\n"


@pytest.mark.parametrize("calib_text, options, message", [
    (None, ["--calib", "{tmp}/nope.txt", "--ply", "{out}/c.ply"],
     "calibration file not found: {tmp}/nope.txt"),
    ("cam0=[200 0 19.5; 0 200 11.5; 0 0 1]\n", ["--calib", "{calib}", "--depth", "{out}/z.pfm"],
     "calibration file {calib} lacks baseline"),
    ("baseline=30\n", ["--calib", "{calib}", "--depth", "{out}/z.pfm"],
     "calibration file {calib} lacks cam0"),
    ("cam0=[0 0 19.5; 0 0 11.5; 0 0 1]\nbaseline=30\n", ["--calib", "{calib}", "--ply", "{out}/c.ply"],
     "calibration file {calib}: focal length must be > 0, got 0"),
    ("cam0=[200 0 19.5; 0 200 11.5; 0 0 1]\nbaseline=-3\n", ["--calib", "{calib}", "--ply", "{out}/c.ply"],
     "calibration file {calib}: baseline must be > 0, got -3"),
    (None, ["--focal", "0", "--baseline", "1", "--depth", "{out}/z.pfm"],
     "focal length must be > 0, got 0"),
    (None, ["--focal", "-100", "--baseline", "1", "--depth", "{out}/z.pfm"],
     "focal length must be > 0, got -100"),
    (None, ["--focal", "100", "--baseline", "0", "--ply", "{out}/c.ply"],
     "baseline must be > 0, got 0"),
    (None, ["--focal", "nan", "--baseline", "1", "--ply", "{out}/c.ply"],
     "focal length must be finite, got nan"),
    (GOOD_CALIB, ["--calib", "{calib}", "--focal", "100", "--ply", "{out}/c.ply"],
     "argument --focal: not allowed with argument --calib"),
    (GOOD_CALIB, ["--calib", "{calib}", "--baseline", "3", "--ply", "{out}/c.ply"],
     "--baseline goes with --focal, not --calib (the file gives it)"),
    (None, ["--baseline", "3", "--doffs", "1", "--depth", "{out}/z.pfm"],
     "--baseline, --doffs need --focal"),
    (None, ["--focal", "100", "--depth", "{out}/z.pfm"], "--focal needs --baseline"),
    (None, ["--depth", "{out}/z.pfm"],
     "--depth and --ply need --calib FILE, --focal F --baseline B or --rectify STEREO_CALIB"),
    (GOOD_CALIB, ["--calib", "{calib}", "--ply", "{out}/missing/c.ply"],
     "output folder does not exist: {out}/missing"),
    (GOOD_CALIB, ["--calib", "{calib}", "--depth", "{out}/missing/z.pfm"],
     "output folder does not exist: {out}/missing"),
    (None, ["--kitti-png", "{out}/missing/k.png"], "output folder does not exist: {out}/missing"),
    (None, ["--kitti-png", "{out}"], "output {out} is a folder, expected a file name"),
    (GOOD_CALIB, ["--calib", "{calib}", "--depth", "{out}/z.png"],
     ("--depth {out}/z.png: unsupported extension '.png'; --depth writes .pfm, .npy, .tif or "
      ".tiff (float32), or .png with --depth-scale S (16-bit, round(depth * S))")),
    (GOOD_CALIB, ["--calib", "{calib}", "--depth", "{out}/z.pfm", "--depth-scale", "10"],
     "--depth-scale goes with --depth DEPTH.png"),
    (GOOD_CALIB, ["--calib", "{calib}", "--depth", "{out}/z.png", "--depth-scale", "0"],
     "argument --depth-scale: expected a number > 0, got '0'"),
    (GOOD_CALIB, ["--calib", "{calib}", "--depth", "{out}/z.jpg"],
     ("--depth {out}/z.jpg: unsupported extension '.jpg'; --depth writes .pfm, .npy, .tif or "
      ".tiff (float32), or .png with --depth-scale S (16-bit, round(depth * S))")),
], ids=["calib-missing", "calib-no-baseline", "calib-no-cam0", "calib-zero-focal",
        "calib-negative-baseline", "focal-zero", "focal-negative", "baseline-zero", "focal-nan",
        "calib-and-focal", "calib-and-baseline", "baseline-without-focal",
        "focal-without-baseline", "depth-without-calibration", "ply-missing-folder",
        "depth-missing-folder", "kitti-missing-folder", "kitti-is-a-folder",
        "depth-png-without-scale", "scale-without-png", "scale-zero", "depth-jpg"])
def test_match_geometry_bad_input(small_pair, tmp_path, run_cli, calib_text, options, message):
    out = tmp_path / "out"
    out.mkdir()
    calib = tmp_path / "calib.txt"
    if calib_text is not None:
        calib.write_text(calib_text)
    names = {"tmp": tmp_path, "out": out, "calib": calib}
    folder = small_pair.folder
    code, _, stderr = run_cli(["match", folder / "left.png", folder / "right.png",
                                    "--ndisp", small_pair.ndisp, "-o", out / "d.pfm",
                                    *(o.format(**names) for o in options)])
    assert code == 2
    assert stderr == f"sswjax: error: {message.format(**names)}\n"
    assert list(out.iterdir()) == []          # nothing written, no temporary debris
