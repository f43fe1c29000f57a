"""``sswjax rectify LEFT RIGHT --calib stereo.yaml -o DIR``: a raw pair rectified for matching.

Writes ``DIR/im0.png`` and ``DIR/im1.png`` (the rectified pair, 8 or 16 bits as the input),
``DIR/calib.txt`` (Middlebury's: ``cam0``, ``cam1``, ``doffs``, ``baseline``, ``width``,
``height``, and ``ndisp``, ``vmin``, ``vmax`` with ``--depth-range``) and ``DIR/mask0.png``,
``DIR/mask1.png`` (255 where the rectified pixel came from inside the raw image, 0 where it
was edge-replicated from outside it), all together or none. The calibration is any format of
:mod:`sswjax.data.calibration` (two files for ROS). The same rectification serves ``sswjax
match LEFT RIGHT --rectify stereo.yaml`` (:func:`stereo_rig`, :func:`rectified`) and its folder
runs (:func:`rectify_images`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import imageio.v3 as iio
import numpy as np

from sswjax._files import InputError, atomic_outputs, same_file
from sswjax.api.geometry import Calibration, StereoCalibration
from sswjax.api.rectify import (OUTSIDE_VIEW, RectifiedPair, as_rectified, opencv, outside_view,
                                rectified_calibration, rectify_pair)
from sswjax.cli.common import check_output_files
from sswjax.cli.geometry import alpha_option, depth_range
from sswjax.data.calibration import COLOUR, GRAY, calibration_format, read_stereo_calibration
from sswjax.data.io import read_image

__all__ = ["add_rectify_command", "middlebury_calib", "outside_bits", "rectified",
           "rectify_images", "run_rectify", "stereo_rig", "write_png"]


def _calibration_paths(paths: list[Path], option: str) -> tuple[Path, Path | None]:
    if not 1 <= len(paths) <= 2:
        raise ValueError(f"{option} takes one calibration file, or two (ROS's left.yaml "
                         f"right.yaml), got {len(paths)}")
    return paths[0], paths[1] if len(paths) == 2 else None


def stereo_rig(paths: list[Path], size: tuple[int, int, int], *, cameras=None,
               option: str = "--rectify", note: bool = True) -> StereoCalibration:
    """The calibration of ``--rectify`` / ``--calib`` for images of ``size`` (height, width,
    channels): read, checked against the images' size (one line naming the file), OpenCV
    present when the images must be resampled.

    KITTI's ``calib_cam_to_cam.txt`` takes cameras 00 01 for gray images and 02 03 for colour
    ones (``cameras`` else), and KITTI's rectified images (their size is the file's
    ``S_rect``) its rectified rig (a note says so).
    """
    path, right = _calibration_paths(paths, option)
    kitti = calibration_format(path) == "kitti"
    if kitti and cameras is None:
        cameras = GRAY if size[2] == 1 else COLOUR
    stereo = read_stereo_calibration(path, right=right,
                                     cameras=None if cameras is None else tuple(cameras))
    height, width = size[:2]
    rect = stereo.rectification
    if (not stereo.rectified and rect is not None and rect.size == (width, height)
            and stereo.image_size != (width, height)):
        stereo = as_rectified(stereo)
        if note:
            print(f"sswjax: note: the images are {width}x{height}, the rectified size of {path}: "
                  "taken as rectified already", file=sys.stderr)
    if stereo.image_size is not None and stereo.image_size != (width, height):
        raise InputError(f"calibration file {path}: image size {stereo.image_size[0]}x"
                         f"{stereo.image_size[1]} does not match the images ({width}x{height})")
    if not stereo.rectified:
        try:
            opencv()
        except ImportError as exc:
            raise ValueError(str(exc)) from None
    return stereo._replace(image_size=(width, height))


def rectified(stereo: StereoCalibration, left, right, *, alpha=None
              ) -> tuple[RectifiedPair, Calibration]:
    """The rectified pair and its rig (:class:`~sswjax.api.geometry.Calibration`)."""
    pair = rectify_pair(left, right, stereo, alpha=alpha)
    return pair, rectified_calibration(pair.rectification)


def outside_bits(pair: RectifiedPair, disparity: np.ndarray) -> np.ndarray:
    """uint8 (H, W): :data:`~sswjax.stages.confidence.OUTSIDE_VIEW` where the rectified left
    pixel or its match came from outside the raw images, else 0."""
    return np.where(outside_view(disparity, pair.left_inside, pair.right_inside),
                    np.uint8(OUTSIDE_VIEW), np.uint8(0))


def write_png(path: Path, image: np.ndarray) -> None:
    """Write an image to ``path`` (a temporary file) as PNG in its bit depth: uint8 as 8 bits,
    uint16 as 16 (colour through OpenCV, which Pillow cannot), floats in [0, 1] as 16."""
    if image.dtype not in (np.uint8, np.uint16):
        image = np.round(np.clip(image, 0, 1) * 65535).astype(np.uint16)
    if image.dtype == np.uint16 and image.ndim == 3:
        cv2 = opencv()
        ok, data = cv2.imencode(".png", np.ascontiguousarray(image[..., ::-1]))
        if not ok:
            raise OSError("OpenCV could not encode the PNG")
        Path(path).write_bytes(data.tobytes())
        return
    iio.imwrite(path, image, extension=".png")


def middlebury_calib(rig: Calibration, size: tuple[int, int], search=None, depths=None) -> str:
    """The text of a Middlebury ``calib.txt`` for a rectified rig of ``size`` (width, height);
    with a search range ``(min_disp, ndisp)`` its ``ndisp`` (counted from 0, as Middlebury's)
    and, with the depths ``(ZMIN, ZMAX)``, ``vmin`` and ``vmax`` (their disparities)."""
    (cx, cy), f = rig.principal, rig.focal
    lines = [f"cam0=[{f:.9g} 0 {cx:.9g}; 0 {f:.9g} {cy:.9g}; 0 0 1]",
             f"cam1=[{f:.9g} 0 {cx + rig.doffs:.9g}; 0 {f:.9g} {cy:.9g}; 0 0 1]",
             f"doffs={rig.doffs:.9g}", f"baseline={rig.baseline:.9g}",
             f"width={size[0]}", f"height={size[1]}"]
    if search is not None:
        lines.append(f"ndisp={max(1, search[0] + search[1])}")
    if depths is not None:
        scale = rig.focal * rig.baseline
        vmax, vmin = scale / depths[0] - rig.doffs, scale / depths[1] - rig.doffs
        lines += [f"vmin={vmin:.3f}", f"vmax={vmax:.3f}"]
    return "\n".join(lines) + "\n"


OUTPUTS = ("im0.png", "im1.png", "calib.txt", "mask0.png", "mask1.png")
"""What ``sswjax rectify`` writes into its folder."""


def add_rectify_command(commands) -> None:
    """Add the ``rectify`` sub-command to ``commands`` (argparse's sub-parsers)."""
    parser = commands.add_parser("rectify", help="rectify a raw pair of a calibrated rig")
    parser.add_argument("left", type=Path, help="raw left image")
    parser.add_argument("right", type=Path, help="raw right image")
    parser.add_argument("--calib", type=Path, nargs="+", required=True, metavar="STEREO_CALIB",
                        help="the rig's calibration: OpenCV YAML, XML or .npz (K1 D1 K2 D2 R T), "
                             "ROS's left.yaml right.yaml, KITTI's calib_cam_to_cam.txt, "
                             "Middlebury's calib.txt")
    parser.add_argument("-o", "--output", type=Path, required=True, metavar="DIR",
                        help="folder of im0.png, im1.png, calib.txt, mask0.png, mask1.png "
                             "(created; its parent must exist)")
    parser.add_argument("--alpha", type=alpha_option, metavar="A",
                        help="0 crops to valid pixels, 1 keeps every raw pixel (default: the "
                             "calibration's own rectification, else 0)")
    parser.add_argument("--depth-range", type=float, nargs=2, metavar=("ZMIN", "ZMAX"),
                        help="also write ndisp, vmin and vmax for depths ZMIN..ZMAX (the "
                             "calibration's unit)")
    parser.add_argument("--cameras", nargs=2, metavar=("LEFT", "RIGHT"),
                        help="KITTI: the two cameras (default 00 01 gray, 02 03 colour)")
    parser.set_defaults(run=run_rectify)


def run_rectify(args: argparse.Namespace) -> int:
    """``sswjax rectify``; returns the exit status (0)."""
    out = args.output
    if out.exists() and not out.is_dir():
        raise ValueError(f"-o {out} is a file: it names the folder of the rectified pair")
    if not out.parent.is_dir():
        raise ValueError(f"output folder does not exist: {out.parent}")
    outputs = [out / name for name in OUTPUTS]
    inputs = [("LEFT", args.left), ("RIGHT", args.right)] + [("--calib", p) for p in args.calib]
    for path in outputs:
        for name, source in inputs:
            if same_file(path, source):
                raise ValueError(f"-o {out} would replace the input {name} {source} (its "
                                 f"{path.name}): choose another folder")
        if out.is_dir():
            check_output_files(path)
    left, right = read_image(args.left), read_image(args.right)
    if left.shape[:2] != right.shape[:2]:
        raise ValueError(f"LEFT {left.shape[1]}x{left.shape[0]} and RIGHT {right.shape[1]}x"
                         f"{right.shape[0]} differ in size")
    stereo = stereo_rig(args.calib, (*left.shape[:2], 1 if left.ndim == 2 else 3),
                        cameras=args.cameras, option="--calib")
    pair, rig = rectified(stereo, left, right, alpha=args.alpha)
    size = (pair.left.shape[1], pair.left.shape[0])
    search = depth_range(args, rig, size[0])
    text = middlebury_calib(rig, size, search, args.depth_range)
    created = not out.exists()
    out.mkdir(exist_ok=True)
    try:
        with atomic_outputs(outputs) as files:
            files.write(out / "im0.png", lambda tmp: write_png(tmp, pair.left))
            files.write(out / "im1.png", lambda tmp: write_png(tmp, pair.right))
            files.write(out / "calib.txt", lambda tmp: tmp.write_text(text, encoding="ascii"))
            for name, inside in (("mask0.png", pair.left_inside), ("mask1.png", pair.right_inside)):
                files.write(out / name, lambda tmp, inside=inside: write_png(
                    tmp, np.where(inside, np.uint8(255), np.uint8(0))))
    except BaseException:
        if created:
            out.rmdir()
        raise
    note = "" if search is None else f", disparities {search[0]}..{search[0] + search[1] - 1}"
    print(f"wrote {out}/{{{','.join(OUTPUTS)}}} ({size[0]}x{size[1]}, focal {rig.focal:.6g} px, "
          f"baseline {rig.baseline:.6g}{note})")
    return 0


def rectify_images(args: argparse.Namespace, left: np.ndarray, right: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """A folder run's pair rectified with ``--rectify`` (as it is without), for
    :mod:`sswjax.cli.folders`: the calibration is read once, for the first pair's size, and
    every pair must have that size."""
    paths = getattr(args, "rectify", None)
    if paths is None:
        return left, right
    size = (*left.shape[:2], 1 if left.ndim == 2 else 3)
    cached = getattr(args, "rectify_rig", None)  # (size, rig) of the pair before
    if cached is None or cached[0] != size:
        cached = (size, stereo_rig(paths, size, cameras=args.cameras, note=cached is None))
        args.rectify_rig = cached
    pair, _ = rectified(cached[1], left, right, alpha=args.alpha)
    return pair.left, pair.right
