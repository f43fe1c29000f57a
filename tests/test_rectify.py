"""Raw cameras to point clouds (``sswjax.api.rectify``, ``sswjax rectify``, ``match --rectify``)
on a synthetic rig: a textured scene (a slanted wall, a floor and a box) ray-cast into two
cameras with known intrinsics, radial and tangential distortion and a small rotation between
them, 240 x 160."""

import argparse
import subprocess
import sys
import warnings

import numpy as np
import pytest

from sswjax.api.auto_range import estimate_range, range_for_depths
from sswjax.api.geometry import Calibration, Rectification, StereoCalibration, point_cloud
from sswjax.api.raw_frame import raw_depth, raw_point_cloud
from sswjax.api.rectify import (OUTSIDE_VIEW, disparity_matrix, outside_view, rectification,
                                rectified_calibration, rectify_pair)
from sswjax.cli.rectify import rectify_images
from sswjax.data.calibration import read_calib, read_calibration
from sswjax.data.io import read_image, read_pfm

cv2 = pytest.importorskip("cv2")

WIDTH, HEIGHT = 240, 160
K1 = np.array([[210.0, 0, 118.0], [0, 212.0, 82.0], [0, 0, 1]])
K2 = np.array([[205.0, 0, 122.0], [0, 206.0, 78.0], [0, 0, 1]])
D1 = np.array([-0.22, 0.06, 0.001, -0.0008, 0.0])
D2 = np.array([-0.18, 0.04, -0.0006, 0.0009, 0.0])
R = cv2.Rodrigues(np.array([0.01, -0.025, 0.012]))[0]
CENTRE = np.array([0.5, 0.01, -0.01])          # the right camera's centre in the left frame
T = -R @ CENTRE                                # x_right = R x_left + T
CALIB = StereoCalibration(K1, D1, K2, D2, R, T, (WIDTH, HEIGHT))
DEPTHS = (2.0, 8.0)                            # the scene lies at 2.4 .. 5.4

_waves = np.random.default_rng(3)
FREQUENCIES = _waves.normal(size=(48, 3)) * 25.0
PHASES, AMPLITUDES = _waves.uniform(0, 2 * np.pi, 48), _waves.uniform(0.5, 1.0, 48)


def cast(origin, rays):
    """Distance along ``rays`` (..., 3) from ``origin`` to the wall ``z = 5 - 0.1 x``, the
    floor ``y = 1`` and the box [-0.5, 0.3] x [-0.2, 0.6] x [2.6, 3.2]: the nearest hit."""
    with np.errstate(divide="ignore", invalid="ignore"):
        normal = np.array([0.1, 0.0, 1.0])
        hits = [(5.0 - origin @ normal) / (rays @ normal), (1.0 - origin[1]) / rays[..., 1]]
        low = (np.array([-0.5, -0.2, 2.6]) - origin) / rays
        high = (np.array([0.3, 0.6, 3.2]) - origin) / rays
        near = np.nanmax(np.minimum(low, high), -1)
        far = np.nanmin(np.maximum(low, high), -1)
    hits.append(np.where(near <= far, near, np.inf))
    hits = np.stack(hits)
    return np.where(hits > 0, hits, np.inf).min(axis=0)


def texture(points):
    """A band-limited random texture of the 3-D point (census matches it)."""
    return 0.5 + 0.5 * np.tanh((np.sin(points @ FREQUENCIES.T + PHASES) * AMPLITUDES).sum(-1) / 3)


def render(camera, distortion, rotation, centre, samples=3):
    """uint8 (H, W) image of a camera (``rotation``: world -> camera) and its depth ``Z``."""
    v, u = np.mgrid[0:HEIGHT, 0:WIDTH].astype(np.float64)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 60, 1e-12)

    def rays(du, dv):
        pixels = np.stack([u + du, v + dv], -1).reshape(-1, 1, 2)
        ray = cv2.undistortPoints(pixels, camera, distortion, criteria=criteria)
        return np.concatenate([ray.reshape(HEIGHT, WIDTH, 2), np.ones((HEIGHT, WIDTH, 1))], -1)

    total = np.zeros((HEIGHT, WIDTH))
    offsets = (np.arange(samples) + 0.5) / samples - 0.5
    for dv in offsets:
        for du in offsets:
            world = rays(du, dv) @ rotation
            total += texture(centre + cast(centre, world)[..., None] * world)
    image = np.round(total / samples ** 2 * 255).astype(np.uint8)
    return image, cast(centre, rays(0, 0) @ rotation)   # the ray's z is 1: distance = Z


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    """The raw pair (PNG), its calibration as cv2.FileStorage writes it and the true depth of
    every raw left pixel in the raw left camera's frame."""
    folder = tmp_path_factory.mktemp("rig")
    left, depth = render(K1, D1, np.eye(3), np.zeros(3))
    right, _ = render(K2, D2, R, CENTRE)
    cv2.imwrite(str(folder / "left.png"), left)
    cv2.imwrite(str(folder / "right.png"), right)
    storage = cv2.FileStorage(str(folder / "stereo.yaml"), cv2.FILE_STORAGE_WRITE)
    for key, value in {"K1": K1, "D1": D1[None], "K2": K2, "D2": D2[None], "R": R,
                       "T": T[:, None]}.items():
        storage.write(key, value)
    storage.write("image_width", WIDTH)
    storage.write("image_height", HEIGHT)
    storage.release()
    return folder, left, right, depth


def true_disparity(rect):
    """The exact disparity of every rectified left pixel (ray-cast from the rectified view)."""
    rig = rectified_calibration(rect)
    height, width = (rect.size or (WIDTH, HEIGHT))[::-1]
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    ray = np.stack([(u - rig.principal[0]) / rig.focal, (v - rig.principal[1]) / rig.focal,
                    np.ones_like(u)], -1)
    depth = cast(np.zeros(3), ray @ rect.r1)
    return (rig.focal * rig.baseline / depth - rig.doffs).astype(np.float32)


# ----------------------------------------------------------------------------- the maths


def test_exact_disparity_gives_the_true_depth_and_surface(rig):
    _, left, _, depth = rig
    for alpha in (0.0, 1.0):
        rect = rectification(CALIB, alpha=alpha)
        disparity = true_disparity(rect)
        found = raw_depth(disparity, CALIB, rect)
        known = np.isfinite(found)
        assert known.mean() > (0.8 if alpha == 0 else 0.99)
        # exact but for float32 and the edges of the surfaces (a pixel's four neighbours)
        error = np.abs(found[known] - depth[known]) / depth[known]
        assert np.median(error) < 1e-6 and np.quantile(error, 0.97) < 1e-4
        cloud = raw_point_cloud(disparity, left, CALIB, rect)
        assert len(cloud.xyz) == known.sum()
        np.testing.assert_allclose(cloud.xyz[:, 2], found[known], rtol=1e-6)
        # every point lies on the scene: the ray from the camera hits it at that distance
        distance = np.linalg.norm(cloud.xyz, axis=1)
        hit = cast(np.zeros(3), cloud.xyz / distance[:, None])
        assert np.quantile(np.abs(distance - hit) / hit, 0.97) < 1e-4


def test_already_rectified_pair_is_unchanged(texture):
    # identity rotation, no distortion, one camera matrix: rectification changes nothing
    left, right = texture(4, (HEIGHT, WIDTH, 3)), texture(5, (HEIGHT, WIDTH, 3))
    camera = np.array([[210.0, 0, 118.0], [0, 210.0, 82.0], [0, 0, 1]])
    calib = StereoCalibration(camera, np.zeros(5), camera, np.zeros(5), np.eye(3),
                              np.array([-0.3, 0.0, 0.0]), (WIDTH, HEIGHT))
    pair = rectify_pair(left, right, calib)
    np.testing.assert_allclose(pair.rectification.p1[:, :3], camera, atol=1e-6)
    np.testing.assert_allclose(pair.rectification.r1, np.eye(3), atol=1e-12)
    inner = (slice(2, -2), slice(2, -2))
    for before, after in ((left, pair.left), (right, pair.right)):
        assert np.abs(after[inner].astype(int) - before[inner]).max() <= 1
    assert pair.left_inside.all() and pair.right_inside.all()
    rig = rectified_calibration(pair.rectification)
    assert rig.focal == pytest.approx(210.0) and rig.baseline == pytest.approx(0.3)
    assert rig.doffs == 0 and rig.principal == pytest.approx((118.0, 82.0), abs=0.02)


@pytest.mark.parametrize("flags", [cv2.CALIB_ZERO_DISPARITY, 0])
def test_reprojection_agrees_with_opencv(flags):
    # The rig read off stereoRectify's P1 and P2 reprojects as cv2.reprojectImageTo3D does
    # with its Q (flags 0: principal points apart, doffs != 0); and so does our own rectification.
    r1, r2, p1, p2, q, _, _ = cv2.stereoRectify(K1, D1, K2, D2, (WIDTH, HEIGHT), R,
                                                T.reshape(3, 1), flags=flags, alpha=0)
    ours = Rectification(r1, r2, p1, p2)
    disparity = np.random.default_rng(0).uniform(5, 40, (HEIGHT, WIDTH)).astype(np.float32)
    image = np.zeros((HEIGHT, WIDTH), np.uint8)
    for rect, matrix in ((ours, q), (rectification(CALIB), rectification(CALIB).q)):
        points = point_cloud(disparity, image, rectified_calibration(rect)).xyz
        theirs = cv2.reprojectImageTo3D(disparity, matrix).reshape(-1, 3)
        np.testing.assert_allclose(points, theirs, rtol=2e-5, atol=1e-6)


def test_outside_pixels_are_replicated_and_marked(rig):
    _, left, right, _ = rig
    pair = rectify_pair(left, right, CALIB, alpha=1.0)
    outside = ~pair.left_inside
    assert 0.05 < outside.mean() < 0.5
    assert pair.left[outside].min() > 0 or (left == 0).any()   # replicated, not black
    disparity = np.full(pair.left.shape, 10.0, np.float32)
    marked = outside_view(disparity, pair.left_inside, pair.right_inside)
    assert (marked >= outside).all()
    columns = np.clip(np.arange(WIDTH) - 10, 0, WIDTH - 1)
    np.testing.assert_array_equal(marked, outside | ~pair.right_inside[:, columns])


def test_range_for_depths():
    rig = Calibration(focal=200.0, baseline=0.5, doffs=0.0)
    assert range_for_depths(rig, 2.0, 8.0, width=240) == (10, 48)      # 12.5 .. 50 + 2 px
    assert range_for_depths(rig, 2.0, np.inf, width=240) == (0, 56)    # never below -doffs
    assert range_for_depths(rig._replace(doffs=30.0), 2.0, 8.0, width=240) == (-20, 48)
    assert range_for_depths(rig, 0.1, 8.0, width=240).ndisp == 239
    for bad, message in (((8.0, 2.0), "0 < ZMIN < ZMAX"), ((0.0, 2.0), "0 < ZMIN < ZMAX"),
                         ((np.nan, 2.0), "depth_min must be a number")):
        with pytest.raises(ValueError, match=message):
            range_for_depths(rig, *bad, width=240)


def test_estimate_range_of_a_shifted_pair(texture):
    right = texture(7, (HEIGHT, WIDTH))   # gray, the coarse shape of the rig's: one compilation
    left = np.roll(right, 20, axis=1)
    found = estimate_range(left, right)
    assert found.min_disp <= 20 <= found.min_disp + found.ndisp - 1
    # 20 px is 10 coarse pixels; 3 of margin and 5 % make 27.3, rounded up to 32 disparities.
    assert found.ndisp % 8 == 0 and found.ndisp <= 32


# ----------------------------------------------------------------------------- command line


def test_raw_rig_to_cloud_on_the_true_surfaces(rig, tmp_path, run_cli, tiny):
    folder, _, _, depth = rig
    out = tmp_path
    code, _, stderr = run_cli([
        "match", folder / "left.png", folder / "right.png", "--rectify", folder / "stereo.yaml",
        "--depth-range", *DEPTHS, "-o", out / "d.pfm", "--ply", out / "cloud.ply",
        "--depth", out / "z.pfm", *tiny.args])
    assert code == 0, stderr
    assert "depths 2..8 are disparities" in stderr
    found = read_pfm(out / "z.pfm")
    assert found.shape == depth.shape and np.isfinite(found).mean() > 0.8
    known = np.isfinite(found)
    error = np.abs(found[known] - depth[known]) / depth[known]
    assert np.median(error) < 0.01
    plyfile = pytest.importorskip("plyfile")
    vertex = plyfile.PlyData.read(str(out / "cloud.ply"))["vertex"]
    np.testing.assert_allclose(vertex["z"], found[known], rtol=1e-6)
    xyz = np.stack([vertex[c] for c in "xyz"], -1).astype(np.float64)
    distance = np.linalg.norm(xyz, axis=1)
    surface = cast(np.zeros(3), xyz / distance[:, None])
    assert np.median(np.abs(distance - surface) / surface) < 0.01


def test_outside_bit_in_the_outputs(rig, tmp_path, run_cli, tiny):
    folder, left, right, _ = rig
    out = tmp_path
    code, _, stderr = run_cli([
        "match", folder / "left.png", folder / "right.png", "--rectify", folder / "stereo.yaml",
        "--alpha", "1", "--ndisp", "48", "--min-disp", "8", "-o", out / "d.pfm",
        "--validity", out / "v.png", "--invalid-as-inf", "--ply", out / "c.npz",
        "--depth", out / "z.pfm", *tiny.args])
    assert code == 0, stderr
    validity, disparity = read_image(out / "v.png"), read_pfm(out / "d.pfm")
    pair = rectify_pair(left, right, CALIB, alpha=1.0)
    marked = (validity & OUTSIDE_VIEW) > 0
    assert marked.mean() > 0.05 and (marked >= ~pair.left_inside).all()
    assert np.isinf(disparity[validity > 0]).all() and np.isfinite(disparity[validity == 0]).all()
    cloud = np.load(out / "c.npz")
    assert cloud["xyz"].dtype == np.float32 and cloud["rgb"].dtype == np.uint8
    rect = pair.rectification
    kept = np.where(validity > 0, np.inf, disparity).astype(np.float32)
    np.testing.assert_array_equal(read_pfm(out / "z.pfm"), raw_depth(kept, CALIB, rect))
    assert len(cloud["xyz"]) == np.isfinite(read_pfm(out / "z.pfm")).sum()


def test_rectify_command(rig, tmp_path, run_cli, tiny):
    folder, left, right, _ = rig
    raw = tmp_path / "raw"
    raw.mkdir()
    cv2.imwrite(str(raw / "left.png"), left.astype(np.uint16) * 257)   # 16 bits in, 16 out
    cv2.imwrite(str(raw / "right.png"), right.astype(np.uint16) * 257)
    out = tmp_path / "rectified"
    code, _, stderr = run_cli(["rectify", raw / "left.png", raw / "right.png", "--calib",
                                    folder / "stereo.yaml", "--depth-range", *DEPTHS, "-o", out])
    assert code == 0, stderr
    assert sorted(p.name for p in out.iterdir()) == ["calib.txt", "im0.png", "im1.png",
                                                     "mask0.png", "mask1.png"]
    im0 = read_image(out / "im0.png")
    assert im0.dtype == np.uint16 and im0.shape == (HEIGHT, WIDTH)
    expected = rectify_pair(left.astype(np.uint16) * 257, right.astype(np.uint16) * 257, CALIB)
    np.testing.assert_array_equal(im0, expected.left)
    text = read_calib(out / "calib.txt")
    rig_ = rectified_calibration(expected.rectification)
    assert read_calibration(out / "calib.txt").focal == pytest.approx(rig_.focal)
    assert text["width"] == WIDTH and text["ndisp"] == sum(range_for_depths(rig_, *DEPTHS,
                                                                            width=WIDTH))
    assert read_image(out / "mask0.png").min() == 255                   # alpha 0: all inside
    # the rectified folder matches as any Middlebury pair
    code, _, stderr = run_cli(["match", out / "im0.png", out / "im1.png", "--calib",
                               out / "calib.txt", "--ndisp", "auto", "-o", tmp_path / "d.pfm",
                               *tiny.args])
    assert code == 0, stderr
    assert "--ndisp auto chose disparities" in stderr


@pytest.mark.parametrize("options, message", [
    (["--rectify", "{f}/stereo.yaml", "--ndisp", "16", "--depth-range", "2", "8"],
     "--depth-range sets the range: give it or --ndisp, not both"),
    (["--rectify", "{f}/stereo.yaml"], "the following arguments are required: --ndisp"),
    (["--depth-range", "2", "8"], "--depth-range needs the rig"),
    (["--rectify", "{f}/stereo.yaml", "--depth-range", "8", "2"],
     "--depth-range 8 2: the depth range must be 0 < ZMIN < ZMAX"),
    (["--ndisp", "auto", "--min-disp", "3"], "--min-disp goes with --ndisp N"),
    (["--ndisp", "16", "--alpha", "0.5"], "--alpha goes with --rectify"),
    (["--ndisp", "16", "--alpha", "2", "--rectify", "{f}/stereo.yaml"],
     "argument --alpha: expected a number in [0, 1], got '2'"),
    (["--ndisp", "16", "--rectify", "{f}/small.yaml"],
     "calibration file {f}/small.yaml: image size 120x80 does not match the images (240x160)"),
    (["--ndisp", "16", "--rectify", "{f}/a.yaml", "{f}/b.yaml", "{f}/c.yaml"],
     "--rectify takes one calibration file, or two"),
    (["--ndisp", "16", "--rectify", "{f}/stereo.yaml", "--ply", "{o}/c.xyz"],
     "--ply {o}/c.xyz: unsupported extension '.xyz'; --ply writes .ply"),
])
def test_match_rectify_bad_input(rig, tmp_path, run_cli, options, message):
    folder = rig[0]
    small = folder / "small.yaml"
    if not small.exists():
        small.write_text((folder / "stereo.yaml").read_text().replace("image_width: 240",
                         "image_width: 120").replace("image_height: 160", "image_height: 80"))
    names = {"f": folder, "o": tmp_path}
    code, _, stderr = run_cli(["match", folder / "left.png", folder / "right.png", "-o",
                               tmp_path / "d.pfm", *(o.format(**names) for o in options)])
    assert code == 2 and stderr.count("\n") == 1, stderr
    assert message.format(**names) in stderr
    assert list(tmp_path.iterdir()) == []


def test_without_opencv_one_line(rig, tmp_path, run_cli, monkeypatch):
    monkeypatch.setitem(sys.modules, "cv2", None)
    folder = rig[0]
    code, _, stderr = run_cli(["match", folder / "left.png", folder / "right.png", "--rectify",
                               folder / "stereo.yaml", "--ndisp", "16", "-o", tmp_path / "d.pfm"])
    assert code == 2
    assert stderr == 'sswjax: error: rectification needs OpenCV: pip install "sswjax[camera]"\n'


def test_folder_rectification(rig, tmp_path):
    folder, left, right, _ = rig
    args = argparse.Namespace(rectify=[folder / "stereo.yaml"], cameras=None, alpha=None)
    for _ in range(2):   # the calibration is read once
        out = rectify_images(args, left, right)
        np.testing.assert_array_equal(out[0], rectify_pair(left, right, CALIB).left)
    assert rectify_images(argparse.Namespace(rectify=None), left, right)[0] is left


def test_match_folders_with_rectify(rig, tmp_path, run_cli, tiny):
    """Two folders with --rectify: each pair rectified as a single pair is, the same map; with
    workers it is refused in one line."""
    folder, left, right, _ = rig
    for side, image in (("L", left), ("R", right)):
        (tmp_path / side).mkdir()
        for name in ("a.png", "b.png"):
            cv2.imwrite(str(tmp_path / side / name), image)
    calib = folder / "stereo.yaml"
    code, _, stderr = run_cli(["match", tmp_path / "L", tmp_path / "R", "--rectify", calib,
                               "--ndisp", "48", *tiny.args, "-o", tmp_path / "out"])
    assert code == 0, stderr
    code, _, stderr = run_cli(["match", tmp_path / "L" / "a.png", tmp_path / "R" / "a.png",
                               "--rectify", calib, "--ndisp", "48", *tiny.args,
                               "-o", tmp_path / "single.pfm"])
    assert code == 0, stderr
    single = read_pfm(tmp_path / "single.pfm")
    for name in ("a", "b"):
        np.testing.assert_array_equal(read_pfm(tmp_path / "out" / f"{name}.pfm"), single)
    code, _, stderr = run_cli(["match", tmp_path / "L", tmp_path / "R", "--rectify", calib,
                               "--ndisp", "48", "--workers", "2", "-o", tmp_path / "out2"])
    assert code == 2 and stderr.count("\n") == 1, stderr
    assert "--rectify matches folders in this process" in stderr


def test_vertical_rig_is_one_line_without_warnings(tmp_path, run_cli):
    """A rig one camera above the other is refused before Q's 1 / Tx divides by zero: only the
    one-line error on stderr (no NumPy RuntimeWarning and its source line)."""
    small = np.array([[50.0, 0, 19.5], [0, 50.0, 11.5], [0, 0, 1]])
    storage = cv2.FileStorage(str(tmp_path / "vertical.yaml"), cv2.FILE_STORAGE_WRITE)
    for key, value in {"K1": small, "D1": np.zeros((1, 5)), "K2": small, "D2": np.zeros((1, 5)),
                       "R": np.eye(3), "T": np.array([[0.0], [-0.1], [0.0]])}.items():
        storage.write(key, value)
    storage.write("image_width", 40)
    storage.write("image_height", 24)
    storage.release()
    image = np.random.default_rng(0).integers(0, 256, (24, 40), dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "l.png"), image)
    cv2.imwrite(str(tmp_path / "r.png"), image)
    message = ("sswjax: error: the cameras are one above the other after rectification (a "
               "vertical rig): only side-by-side rigs are supported\n")
    command = subprocess.run([sys.executable, "-m", "sswjax.cli", "rectify", tmp_path / "l.png",
                              tmp_path / "r.png", "--calib", tmp_path / "vertical.yaml", "-o",
                              tmp_path / "out"], capture_output=True, text=True, timeout=300)
    assert (command.returncode, command.stderr) == (2, message)       # one line, no Warning
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        code, _, stderr = run_cli(["match", tmp_path / "l.png", tmp_path / "r.png", "--rectify",
                                   tmp_path / "vertical.yaml", "--ndisp", "8", "-o",
                                   tmp_path / "d.pfm"])
    assert (code, stderr) == (2, message) and [str(w.message) for w in caught] == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["l.png", "r.png", "vertical.yaml"]
    with pytest.raises(ValueError, match="P1 and P2 have the same x: no baseline"):
        disparity_matrix(np.eye(3, 4), np.eye(3, 4))
