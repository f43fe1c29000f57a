"""A real pair rectified backwards: does ``match --rectify`` give the cloud a direct run gives?

A MiddEval3 pair is rectified already. This script makes it raw: it applies a known lens
distortion to both views (and a 6 % zoom) and a known rotation to the right camera, warping
the images with OpenCV (inverse maps: ``cv2.undistortPoints`` of every raw pixel into the
rectified view, then ``cv2.remap``), and writes the OpenCV calibration (``cv2.FileStorage``
YAML) of that raw rig, the one that undoes it. Then::

    sswjax match raw/im0.png raw/im1.png --rectify raw/stereo.yaml --depth-range ZMIN ZMAX \\
        -o raw/d.pfm --ply raw/cloud.ply
    sswjax match im0.png im1.png --calib calib.txt --depth-range ZMIN ZMAX \\
        -o direct/d.pfm --ply direct/cloud.ply

and both clouds are scored against the true depth (``disp0GT.pfm`` and ``calib.txt``; for the
raw cloud mapped into the raw left camera, whose frame is the rectified left one's, distorted):
each point is projected into its camera's image (``cv2.projectPoints``) and compared with the
true depth of that pixel; a point counts when its depth is within 2 % (points on pixels
without ground truth are left out). The raw run passes when it is within 3 percentage points
of the direct run with at least 80 % as many points. OpenCV's own rectification followed by
SGBM is scored the same way for reference. The depth range is the ground truth's (``vmin``,
``vmax`` of ``calib.txt``) with 5 % to spare.

    python benchmarks/raw_camera.py [--data DIR] [--scene Motorcycle] [--preset accurate]

writes ``benchmarks/results/raw_camera.md`` and ``raw_camera_cloud.png`` (the raw run's cloud,
matplotlib). Needs the ``bench`` extras.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from sswjax.api.geometry import point_cloud
from sswjax.data.calibration import read_calib, read_calibration
from sswjax.data.io import read_image, read_pfm
from sswjax.evaluation.peers import sgbm_disparity

DISTORTION = (np.array([-0.20, 0.07, 0.0012, -0.0009, 0.0]),
              np.array([-0.16, 0.05, -0.0010, 0.0011, 0.0]))
"""k1 k2 p1 p2 k3 of the raw left and right cameras."""
ROTATION = np.array([0.008, -0.012, 0.012])
"""Rodrigues vector of the raw right camera against the rectified right one (~2 degrees)."""
ZOOM = 1.06
"""Focal length of the raw cameras against the rectified ones (the distorted corners stay in)."""
TOLERANCE = 0.02


def _cv2():
    import cv2

    return cv2


def _bgr(image: np.ndarray) -> np.ndarray:
    return image[..., ::-1] if image.ndim == 3 else image


def raw_rig(calib: dict, size: tuple[int, int]):
    """The raw cameras ``(K1, D1, K2, D2, R, T)`` of a Middlebury rig: ``K`` the rectified
    camera matrices zoomed, the right camera rotated by :data:`ROTATION` in its own frame."""
    cv2 = _cv2()
    cams = [np.array([[float(v) for v in row.split()] for row in str(calib[key]).strip("[]")
                      .split(";")]) for key in ("cam0", "cam1")]
    raws = []
    for cam in cams:
        raw = cam.copy()
        raw[0, 0] *= ZOOM
        raw[1, 1] *= ZOOM
        raws.append(raw)
    rotation = cv2.Rodrigues(ROTATION)[0]
    translation = -rotation @ np.array([calib["baseline"], 0.0, 0.0])
    return cams, (raws[0], DISTORTION[0], raws[1], DISTORTION[1], rotation, translation)


def warp_to_raw(image, rectified_camera, raw_camera, distortion, rotation):
    """The raw view of a rectified image: every raw pixel's ray, undistorted and rotated into
    the rectified camera (``rotation``: raw -> rectified), sampled there (bilinear, replicated).
    Returns the image and the map (H, W, 2) of the rectified position of every raw pixel."""
    cv2 = _cv2()
    height, width = image.shape[:2]
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    pixels = np.stack([u.ravel(), v.ravel()], -1)[:, None]
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10)
    where = cv2.undistortPoints(pixels, raw_camera, distortion, R=rotation, P=rectified_camera,
                                criteria=criteria).reshape(height, width, 2).astype(np.float32)
    raw = cv2.remap(image, where[..., 0], where[..., 1], cv2.INTER_CUBIC,
                    borderMode=cv2.BORDER_REPLICATE)
    return raw, where


def true_depth(ground_truth, calib, where=None):
    """float64 (H, W): the true depth of every pixel (of the raw view at the rectified
    positions ``where``: the nearest ground truth when its 2 x 2 neighbours agree within 1 px),
    NaN where unknown."""
    rig = read_calibration(calib)
    disparity = ground_truth.astype(np.float64)
    if where is not None:
        height, width = disparity.shape
        x, y = where[..., 0], where[..., 1]
        x0 = np.clip(np.floor(x), 0, width - 2).astype(int)
        y0 = np.clip(np.floor(y), 0, height - 2).astype(int)
        taps = np.stack([disparity[y0, x0], disparity[y0, x0 + 1], disparity[y0 + 1, x0],
                         disparity[y0 + 1, x0 + 1]])
        inside = (x >= 0) & (x <= width - 1) & (y >= 0) & (y <= height - 1)
        with np.errstate(invalid="ignore"):
            agree = np.isfinite(taps).all(0) & (np.ptp(taps, axis=0) <= 1.0) & inside
        nearest = disparity[np.clip(np.rint(y), 0, height - 1).astype(int),
                            np.clip(np.rint(x), 0, width - 1).astype(int)]
        disparity = np.where(agree, nearest, np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        depth = rig.baseline * rig.focal / (disparity + rig.doffs)
    return np.where(np.isfinite(depth) & (depth > 0), depth, np.nan)


def score(xyz, camera, distortion, truth) -> dict:
    """Points, points on pixels with ground truth, % of those within :data:`TOLERANCE`, median
    relative error: each point projected into the image (``cv2.projectPoints``)."""
    cv2 = _cv2()
    height, width = truth.shape
    pixels = cv2.projectPoints(xyz.astype(np.float64).reshape(-1, 1, 3), np.zeros(3),
                               np.zeros(3), camera, distortion)[0].reshape(-1, 2)
    col, row = np.rint(pixels[:, 0]).astype(int), np.rint(pixels[:, 1]).astype(int)
    inside = (col >= 0) & (col < width) & (row >= 0) & (row < height)
    z = np.full(len(xyz), np.nan)
    z[inside] = truth[row[inside], col[inside]]
    known = np.isfinite(z)
    error = np.abs(xyz[known, 2] - z[known]) / z[known]
    return {"points": len(xyz), "scored": int(known.sum()),
            "within": float((error <= TOLERANCE).mean() * 100), "median": float(np.median(error))}


def subprocess_cli(argv) -> float:
    """Run ``sswjax ARGV`` in a fresh process; its wall time in seconds."""
    start = time.perf_counter()
    subprocess.run(["sswjax", *map(str, argv)], check=True)
    return time.perf_counter() - start


def run(scene: Path, out: Path, *, options=(), crop=None, cli=subprocess_cli, sgbm=True):
    """Make the raw pair of ``scene`` in ``out/raw``, run both commands, score the clouds.

    ``crop`` ``(x, y, width, height)`` takes a window of the pair first (the test's small
    version); ``options`` are added to both commands (a preset); ``cli(argv)`` runs one."""
    cv2 = _cv2()
    out = Path(out)
    (out / "raw").mkdir(parents=True, exist_ok=True)
    (out / "direct").mkdir(exist_ok=True)
    left, right = read_image(scene / "im0.png"), read_image(scene / "im1.png")
    truth_disparity = read_pfm(scene / "disp0GT.pfm")
    text = (scene / "calib.txt").read_text()
    if crop is not None:
        x, y, width, height = crop
        left, right = left[y:y + height, x:x + width], right[y:y + height, x:x + width]
        truth_disparity = truth_disparity[y:y + height, x:x + width]
        lines = []
        for line in text.splitlines():
            key, _, value = line.partition("=")
            if key in ("cam0", "cam1"):
                rows = [[float(v) for v in row.split()] for row in value.strip("[]").split(";")]
                rows[0][2] -= x
                rows[1][2] -= y
                value = "[" + "; ".join(" ".join(f"{v:g}" for v in row) for row in rows) + "]"
            elif key in ("width", "height"):
                value = str(width if key == "width" else height)
            lines.append(f"{key}={value}")
        text = "\n".join(lines) + "\n"
    (out / "direct" / "calib.txt").write_text(text)
    calib = read_calib(out / "direct" / "calib.txt")
    cv2.imwrite(str(out / "direct" / "im0.png"), _bgr(left))
    cv2.imwrite(str(out / "direct" / "im1.png"), _bgr(right))
    size = (left.shape[1], left.shape[0])
    cams, (k1, d1, k2, d2, rotation, translation) = raw_rig(calib, size)
    raw_left, where = warp_to_raw(left, cams[0], k1, d1, np.eye(3))
    raw_right, where_right = warp_to_raw(right, cams[1], k2, d2, rotation.T)
    cv2.imwrite(str(out / "raw" / "im0.png"), _bgr(raw_left))
    cv2.imwrite(str(out / "raw" / "im1.png"), _bgr(raw_right))
    storage = cv2.FileStorage(str(out / "raw" / "stereo.yaml"), cv2.FILE_STORAGE_WRITE)
    for key, value in {"K1": k1, "D1": d1[None], "K2": k2, "D2": d2[None], "R": rotation,
                       "T": translation[:, None]}.items():
        storage.write(key, value)
    storage.write("image_width", size[0])
    storage.write("image_height", size[1])
    storage.release()
    rig = read_calibration(out / "direct" / "calib.txt")
    known = truth_disparity[np.isfinite(truth_disparity)]
    depths = (0.95 * rig.focal * rig.baseline / (known.max() + rig.doffs),
              1.05 * rig.focal * rig.baseline / (known.min() + rig.doffs))
    depths = (float(f"{depths[0]:.3g}"), float(f"{depths[1]:.3g}"))
    commands = {
        "raw": ["match", out / "raw/im0.png", out / "raw/im1.png", "--rectify",
                out / "raw/stereo.yaml", "--depth-range", *depths, "-o", out / "raw/d.pfm",
                "--ply", out / "raw/cloud.ply", *options],
        "direct": ["match", out / "direct/im0.png", out / "direct/im1.png", "--calib",
                   out / "direct/calib.txt", "--depth-range", *depths, "-o",
                   out / "direct/d.pfm", "--ply", out / "direct/cloud.ply", *options]}
    truth = {"direct": true_depth(truth_disparity, out / "direct/calib.txt"),
             "raw": true_depth(truth_disparity, out / "direct/calib.txt", where)}
    cameras = {"direct": (cams[0], np.zeros(5)), "raw": (k1, d1)}
    rows = []
    for name, argv in commands.items():
        seconds = cli(argv)
        xyz = _read_cloud(out / name / "cloud.ply")
        rows.append({"run": f"sswjax {name}", "seconds": seconds,
                     **score(xyz, *cameras[name], truth[name])})
    if sgbm:
        rows.append({"run": "OpenCV raw (stereoRectify, remap, SGBM)", "seconds": float("nan"),
                     **score(_opencv_cloud(raw_left, raw_right, (k1, d1, k2, d2, rotation,
                                                                 translation), depths[0]),
                             k1, d1, truth["raw"])})
        disparity = sgbm_disparity(left, right, int(calib["ndisp"]))
        cloud = point_cloud(disparity, left, rig)
        rows.append({"run": "OpenCV direct (SGBM)", "seconds": float("nan"),
                     **score(cloud.xyz, cams[0], np.zeros(5), truth["direct"])})
    rows[0]["invented"] = [float(((w[..., 0] < 0) | (w[..., 0] > size[0] - 1) | (w[..., 1] < 0)
                                  | (w[..., 1] > size[1] - 1)).mean() * 100)
                           for w in (where, where_right)]
    return rows, commands, depths


def _opencv_cloud(left, right, rig, depth_min) -> np.ndarray:
    """OpenCV alone: ``stereoRectify`` (its defaults: zero disparity, alpha -1), the maps,
    ``remap``, SGBM, ``reprojectImageTo3D``, and the points rotated back by ``R1^T``."""
    cv2 = _cv2()
    k1, d1, k2, d2, rotation, translation = rig
    size = (left.shape[1], left.shape[0])
    r1, r2, p1, p2, q, _, _ = cv2.stereoRectify(k1, d1, k2, d2, size, rotation,
                                                translation.reshape(3, 1))
    views = []
    for image, k, d, r, p in ((left, k1, d1, r1, p1), (right, k2, d2, r2, p2)):
        x, y = cv2.initUndistortRectifyMap(k, d, r, p, size, cv2.CV_32FC1)
        views.append(cv2.remap(image, x, y, cv2.INTER_LINEAR))
    top = p1[0, 0] * -p2[0, 3] / p2[0, 0] / depth_min
    ndisp = min(-(-int(np.ceil(top)) // 16) * 16, (size[0] - 1) // 16 * 16)
    disparity = sgbm_disparity(*views, ndisp)
    points = cv2.reprojectImageTo3D(disparity, q).reshape(-1, 3)
    points = points[np.isfinite(points).all(1) & (points[:, 2] > 0)]
    return points @ r1          # x_raw = R1^T x_rectified


def _read_cloud(path: Path) -> np.ndarray:
    from plyfile import PlyData

    vertex = PlyData.read(str(path))["vertex"]
    return np.stack([vertex[c] for c in "xyz"], -1).astype(np.float64)


def _seconds(value: float) -> str:
    """A run's time, or a dash for the OpenCV runs (in this process, not timed)."""
    return "–" if np.isnan(value) else f"{value:.1f}"


def verdict(rows) -> tuple[bool, float, float]:
    """(passes, percentage points lost, share of the points) of the raw run against direct."""
    raw, direct = rows[0], rows[1]
    lost = direct["within"] - raw["within"]
    share = raw["points"] / direct["points"]
    return lost <= 3.0 and share >= 0.8, lost, share


def _command(argv, work: Path) -> str:
    words = [str(Path(a).relative_to(work)) if isinstance(a, Path) else str(a) for a in argv]
    return " ".join(["sswjax", *words])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2]
                        / "shared" / "data" / "MiddEval3" / "trainingQ")
    parser.add_argument("--scenes", nargs="+", default=["Motorcycle", "Adirondack"])
    parser.add_argument("--preset", default="accurate")
    parser.add_argument("--work", type=Path, default=Path("/tmp/sswjax-raw-camera"))
    parser.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results"))
    args = parser.parse_args(argv)
    lines = ["# A raw camera: MiddEval3 pairs rectified backwards", "",
             (f"Each trainingQ pair distorted (left k1 {DISTORTION[0][0]}, right k1 "
              f"{DISTORTION[1][0]}, tangential terms, {ZOOM}x zoom) with the right camera "
              f"rotated by {np.degrees(np.linalg.norm(ROTATION)):.2f} degrees, then matched from "
              f"the raw pair (`match --rectify`) and directly; preset {args.preset}. A point "
              f"counts when its depth is within {TOLERANCE:.0%} of the truth at its pixel "
              "(pixels with ground truth only). `python benchmarks/raw_camera.py`."), ""]
    passes = True
    for scene in args.scenes:
        work = args.work / scene
        rows, commands, depths = run(args.data / scene, work, options=["--preset", args.preset])
        ok, lost, share = verdict(rows)
        passes &= ok
        lines += [f"## {scene} (depths {depths[0]:g}..{depths[1]:g} mm)", "",
                  "| run | points | scored | within 2 % | median error | s (process) |",
                  "|---|---|---|---|---|---|"]
        for row in rows:
            lines.append(f"| {row['run']} | {row['points']} | {row['scored']} | "
                         f"{row['within']:.1f} % | {row['median'] * 100:.2f} % | "
                         f"{_seconds(row['seconds'])} |")
        lines += ["", ("Raw pixels the warp had to invent (outside the original views): "
                       f"{rows[0]['invented'][0]:.2f} % left, {rows[0]['invented'][1]:.2f} % "
                       f"right. Raw against direct: {lost:+.2f} points lost, {share:.1%} of the "
                       f"points: {'passes' if ok else 'FAILS'} (at most 3 points, at least 80 "
                       "%). The commands (in the work folder, after the script wrote raw/ and "
                       "direct/):"), "",
                  "```", *(_command(a, work) for a in commands.values()), "```", ""]
    lines += [f"![The raw run's cloud of {args.scenes[0]}](raw_camera_cloud.png)", ""]
    args.output.mkdir(parents=True, exist_ok=True)
    (args.output / "raw_camera.md").write_text("\n".join(lines))
    print("\n".join(lines))
    sys.path.insert(0, str(Path(__file__).parent))
    from point_cloud import read_cloud, render

    xyz, rgb = read_cloud(args.work / args.scenes[0] / "raw" / "cloud.ply")
    render(xyz, rgb, args.output / "raw_camera_cloud.png", points=120_000, seed=0,
           title=f"{args.scenes[0]} from a raw camera (match --rectify), raw left camera frame",
           unit="mm")
    return 0 if passes else 1


if __name__ == "__main__":
    raise SystemExit(main())
