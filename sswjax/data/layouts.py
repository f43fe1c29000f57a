"""Stereo benchmark layouts: MiddEval3, KITTI 2012/2015, Middlebury 2001-2006 and ETH3D two-view.

Every layout is one entry of :data:`LAYOUTS` and loads into the same
:class:`~sswjax.data.datasets.StereoScene` as MiddEval3 (same array conventions):

* ``left``/``right``: as read by :func:`sswjax.data.io.read_image`, ``uint8`` ``(H, W)`` (KITTI
  2012, gray) or ``(H, W, 3)``.
* ``ground_truth``: ``float32`` ``(H, W)`` left disparity in pixels, ``inf`` = unknown. The
  files store ``round(disparity * scale)`` in integers with 0 = unknown: KITTI 16-bit PNGs at
  scale 256, Middlebury 2001 ``disp2.pgm`` at 8, 2003 at 4, 2005/2006 ``disp1.png`` at the
  scale of the image size (1 full, 2 half, 3 third size, told by the width). A ``dmin.txt``
  beside a 2005/2006 map (full size) holds an offset added to its known disparities.
* ``mask``: ``uint8`` ``(H, W)``, 255 = non-occluded, 128 = occluded, 0 = unknown. KITTI's
  ``disp_noc`` holds only non-occluded pixels, so every pixel it knows is 255; when ``disp_occ``
  is there too it becomes the ground truth and the pixels only it knows are 128. The older
  Middlebury sets have no mask (``None``): they are scored on region "all" only. ETH3D's
  ``mask0nocc.png`` is used as it is (255 = non-occluded).
* ``ndisp``: MiddEval3 reads it from ``calib.txt``, ETH3D too when its ``calib.txt`` has an
  ``ndisp=`` line. The other layouts have no disparity
  count, and the protocol is the smallest multiple of 8 that is >= max(ground truth) + 2
  (:func:`ndisp_from_ground_truth`): the ground truth only sizes the search range, as in our
  published figures for the peers. An explicit ``ndisp`` replaces it for every scene.

Folders: KITTI is ``<root>/training/<view folder>/<frame>_10.png`` (``root`` may also be the
``training`` folder), scenes named by frame (``"000100"``); Middlebury is
``<root>/<scene>/<files>``. ETH3D two-view is what its two archives unpack to:
``<root>/two_view_training/<scene>/{im0.png,im1.png,calib.txt}`` (gray images stored as PNG,
one channel or RGB) beside ``<root>/two_view_training_gt/<scene>/{disp0GT.pfm,mask0nocc.png}``
(PFM with ``inf`` = unknown); ``root`` may also be the ``two_view_training`` folder. The layout of a folder is told by its files
(:func:`detect_layout`); layouts with the same file names (2001 and 2003; 2005 and 2006) are
told apart by a year in the folder's name, then by their known scene names.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from sswjax.data.datasets import _SCENE_FILES, StereoScene, load_middeval3, read_calib
from sswjax.data.io import InputError, read_image, read_pfm

__all__ = [
    "LAYOUTS",
    "Layout",
    "detect_layout",
    "load_scenes",
    "ndisp_from_ground_truth",
    "read_scaled_disparity",
    "write_scaled_disparity",
]

_FRAME_SUFFIX = "_10.png"  # KITTI: the reference frame of each sequence


@dataclasses.dataclass(frozen=True)
class Layout:
    """How one benchmark stores its scenes.

    Attributes
    ----------
    name : str
        Name shown to the user, e.g. ``"KITTI2012"``.
    kind : str
        ``"middeval3"`` (scene folders with ``calib.txt``), ``"views"`` (one folder per view
        holding one file per scene: KITTI) or ``"scenes"`` (one folder per scene holding fixed
        file names: Middlebury) or ``"eth3d"`` (scene folders of images in ``split`` beside
        scene folders of ground truth in ``ground_truth_split``).
    left, right, ground_truth : str
        Folder names (``"views"``) or file names (``"scenes"``) of the left image, the right
        image and the non-occluded (or only) ground truth.
    ground_truth_all : str or None
        ``"views"`` only: folder of the ground truth that also covers occluded pixels.
    scale : float or None
        Ground-truth file value per pixel of disparity; ``None``: from the image width.
    split : str or None
        ``"views"``: sub-folder holding the view folders (``"training"``); ``"eth3d"``: the
        folder of the image scene folders (``"two_view_training"``).
    ground_truth_split : str or None
        ``"eth3d"`` only: the folder, beside ``split``, of the ground-truth scene folders.
    mask : str or None
        ``"eth3d"`` only: file name of the occlusion mask in a ground-truth scene folder.
    scene_names : tuple of str
        Known scene names (lower case), to tell apart layouts with the same file names.
    offset_file : str or None
        ``"scenes"`` only: optional file holding a disparity offset (``dmin.txt``).
    scoring : str
        Summary of :mod:`sswjax.evaluation.runner`: ``"middeval3"`` (official weights),
        ``"kitti"`` (mean, with D1) or ``"mean"``.
    """

    name: str
    kind: str
    left: str = ""
    right: str = ""
    ground_truth: str = ""
    ground_truth_all: str | None = None
    scale: float | None = None
    split: str | None = None
    scene_names: tuple[str, ...] = ()
    offset_file: str | None = None
    scoring: str = "mean"
    ground_truth_split: str | None = None
    mask: str | None = None

    @property
    def has_masks(self) -> bool:
        """Whether scenes carry an occlusion mask (region "nonocc")."""
        return self.kind != "scenes"

    @property
    def files(self) -> str:
        """Where the files are, for messages: ``"training/{image_0,image_1,disp_noc}"``."""
        if self.kind == "middeval3":
            return "<scene>/{" + ",".join(_SCENE_FILES) + "}"
        if self.kind == "eth3d":
            return (f"{self.split}/<scene>/{{{self.left},{self.right},calib.txt}} + "
                    f"{self.ground_truth_split}/<scene>/{{{self.ground_truth},{self.mask}}}")
        names = ",".join([self.left, self.right, self.ground_truth])
        return f"{self.split}/{{{names}}}" if self.kind == "views" else f"<scene>/{{{names}}}"


_KITTI = dict(kind="views", split="training", scale=256.0, scoring="kitti")
_MIDDLEBURY_2005_2006 = dict(kind="scenes", left="view1.png", right="view5.png",
                             ground_truth="disp1.png", offset_file="dmin.txt")

#: Every layout that :func:`detect_layout` recognises, by name.
LAYOUTS: dict[str, Layout] = {
    layout.name: layout
    for layout in (
        Layout("MiddEval3", "middeval3", scoring="middeval3"),
        Layout("KITTI2012", left="image_0", right="image_1", ground_truth="disp_noc",
               ground_truth_all="disp_occ", **_KITTI),
        Layout("KITTI2015", left="image_2", right="image_3", ground_truth="disp_noc_0",
               ground_truth_all="disp_occ_0", **_KITTI),
        Layout("Middlebury2001", "scenes", "im2.ppm", "im6.ppm", "disp2.pgm", scale=8.0,
               scene_names=("barn1", "barn2", "bull", "poster", "sawtooth", "venus")),
        Layout("Middlebury2003", "scenes", "im2.ppm", "im6.ppm", "disp2.pgm", scale=4.0,
               scene_names=("cones", "teddy")),
        Layout("Middlebury2005", scene_names=("art", "books", "computer", "dolls", "drumsticks",
                                              "dwarves", "laundry", "moebius", "reindeer"),
               **_MIDDLEBURY_2005_2006),
        Layout("Middlebury2006", scene_names=(
            "aloe", "baby1", "baby2", "baby3", "bowling1", "bowling2", "cloth1", "cloth2",
            "cloth3", "cloth4", "flowerpots", "lampshade1", "lampshade2", "midd1", "midd2",
            "monopoly", "plastic", "rocks1", "rocks2", "wood1", "wood2"), **_MIDDLEBURY_2005_2006),
        Layout("ETH3D", "eth3d", "im0.png", "im1.png", "disp0GT.pfm", split="two_view_training",
               ground_truth_split="two_view_training_gt", mask="mask0nocc.png"),
    )
}  # fmt: skip


def ndisp_from_ground_truth(ground_truth: np.ndarray) -> int:
    """Disparity count of the protocol for layouts without one: a multiple of 8 >= max + 2.

    Parameters
    ----------
    ground_truth : numpy.ndarray
        Floating ``(H, W)`` disparity in pixels; non-finite = unknown.

    Returns
    -------
    int
        The smallest multiple of 8 that is >= the largest known disparity + 2.

    Raises
    ------
    ValueError
        If no disparity is known.

    Examples
    --------
    >>> ndisp_from_ground_truth(np.array([[17.875, np.inf]], np.float32))
    24
    """
    known = np.asarray(ground_truth)[np.isfinite(ground_truth)]
    if known.size == 0:
        raise ValueError("ground truth has no known disparity to size the search range")
    return 8 * max(1, math.ceil((float(known.max()) + 2.0) / 8.0))


def read_scaled_disparity(path: str | os.PathLike, *, scale: float) -> np.ndarray:
    """Read an integer disparity image that stores ``disparity * scale`` with 0 = unknown.

    Parameters
    ----------
    path : str or os.PathLike
        Gray ``uint8`` or ``uint16`` image (PNG, PGM, ...).
    scale : float
        File value per pixel of disparity (256 for KITTI, 8 for Middlebury 2001, ...).

    Returns
    -------
    numpy.ndarray
        ``float32`` ``(H, W)`` disparity in pixels, ``inf`` where the file holds 0.

    Raises
    ------
    InputError
        If the file is missing or unreadable, or not a gray integer image.

    Examples
    --------
    >>> gt = read_scaled_disparity("training/disp_noc/000100_10.png", scale=256)  # doctest: +SKIP
    >>> gt.dtype  # doctest: +SKIP
    dtype('float32')
    """
    image = read_image(path)
    if image.ndim != 2 or image.dtype not in (np.uint8, np.uint16):
        raise InputError(f"disparity image {path} must be 8- or 16-bit gray, got {image.dtype} "
                         f"{image.shape}")
    disparity = image.astype(np.float32) / np.float32(scale)
    disparity[image == 0] = np.inf
    return disparity


def write_scaled_disparity(path: str | os.PathLike, disparity, *, scale: float = 256.0) -> None:
    """Atomically write a 16-bit PNG of ``round(disparity * scale)``, 0 = invalid (KITTI's format).

    The inverse of :func:`read_scaled_disparity` up to the rounding (``1 / (2 * scale)`` px).

    Parameters
    ----------
    path : str or os.PathLike
        Output PNG file.
    disparity : array_like floating (H, W)
        Pixels. Invalid, written as 0: non-finite, ``<= 0``, rounding to 0, or beyond
        ``65535 / scale`` (255.996 px for KITTI).
    scale : float > 0
        File value per pixel of disparity (256 for KITTI).

    Raises
    ------
    ValueError, TypeError
        On a bad shape, dtype or scale.
    InputError
        If the file cannot be written.

    Examples
    --------
    >>> write_scaled_disparity("000000_10.png", np.full((2, 3), 4.5, np.float32))  # doctest: +SKIP
    """
    import imageio.v3 as iio

    from sswjax._checks import check_floating, check_rank
    from sswjax.data.files import atomic_output

    disparity = np.asarray(disparity)
    check_rank("disparity", disparity, 2)
    check_floating("disparity", disparity)
    if isinstance(scale, bool) or not (isinstance(scale, (int, float)) and 0 < scale < np.inf):
        raise ValueError(f"scale must be a finite number > 0, got {scale!r}")
    with np.errstate(invalid="ignore", over="ignore"):
        scaled = np.round(disparity.astype(np.float64) * scale)
    valid = np.isfinite(scaled) & (disparity > 0) & (scaled <= np.iinfo(np.uint16).max)
    values = np.where(valid, scaled, 0).astype(np.uint16)
    with atomic_output(path) as tmp:
        iio.imwrite(tmp, values, extension=".png")


def _year(path: Path) -> str | None:
    match = re.search(r"(?<!\d)(20\d\d)(?!\d)", path.resolve().name)
    return match.group(1) if match else None


def _views_base(root: Path, layout: Layout) -> Path | None:
    """The folder holding ``layout``'s view folders under ``root`` (or ``root`` itself)."""
    for base in (root / layout.split, root):
        if (base / layout.left).is_dir() and (base / layout.right).is_dir():
            return base
    return None


def _scene_folders(root: Path, layout: Layout) -> list[Path]:
    """Sub-folders of ``root`` holding any of ``layout``'s three files, sorted by name."""
    names = (layout.left, layout.right, layout.ground_truth)
    return sorted(p for p in root.iterdir() if p.is_dir() and any((p / n).is_file() for n in names))


def _eth3d_base(root: Path, layout: Layout) -> Path | None:
    """The ``two_view_training`` folder: under ``root``, or ``root`` itself beside its GT."""
    if (root / layout.split).is_dir():
        return root / layout.split
    if root.name == layout.split and (root.parent / layout.ground_truth_split).is_dir():
        return root
    return None


def _matches(root: Path, layout: Layout, split: str) -> bool:
    if layout.kind == "eth3d":
        return _eth3d_base(root, layout) is not None
    if layout.kind == "views":
        return _views_base(root, layout) is not None
    if layout.kind == "scenes":
        return bool(_scene_folders(root, layout))
    if (root / split).is_dir():
        return True
    return any(p.is_dir() and any((p / f).is_file() for f in _SCENE_FILES) for p in root.iterdir())


def detect_layout(root: str | os.PathLike, *, split: str = "trainingQ") -> Layout:
    """Tell the layout of a data folder from its files.

    A folder that does not exist is MiddEval3 (the default), whose loader then reports it.

    Parameters
    ----------
    root : str or os.PathLike
        Folder given to ``sswjax evaluate --data``.
    split : str
        MiddEval3 split sub-folder that also marks a MiddEval3 folder.

    Returns
    -------
    Layout
        An entry of :data:`LAYOUTS`.

    Raises
    ------
    InputError
        If no layout matches (the message lists the recognised ones), or several do and
        neither the folder's name nor its scene names tell them apart.

    Examples
    --------
    >>> detect_layout("/work/shared/data/Middlebury2001").name  # doctest: +SKIP
    'Middlebury2001'
    """
    root = Path(root).expanduser()
    if not root.is_dir():
        return LAYOUTS["MiddEval3"]
    found = [layout for layout in LAYOUTS.values() if _matches(root, layout, split)]
    if any(layout.kind == "eth3d" for layout in found):  # its scene folders look like MiddEval3's
        found = [layout for layout in found if layout.kind != "middeval3"]
    if len(found) > 1:  # same file names: a year in the folder's name, then known scene names
        year = _year(root)
        by_year = [layout for layout in found if year and layout.name.endswith(year)]
        names = {p.name.lower() for layout in found if layout.kind == "scenes"
                 for p in _scene_folders(root, layout)}
        by_scenes = [layout for layout in found if names & set(layout.scene_names)]
        found = by_year or by_scenes or found
    if len(found) == 1:
        return found[0]
    if found:
        raise InputError(f"cannot tell {' from '.join(x.name for x in found)} in {root} (same "
                         f"file names): put the year in the folder's name, e.g. {found[0].name}")
    known = "; ".join(f"{x.name} ({x.files})" for x in LAYOUTS.values())
    raise InputError(f"no known stereo data layout in {root}; recognised: {known}")


def _read_offset(path: Path) -> float:
    try:
        return float(path.read_text(encoding="ascii").split()[0])
    except (OSError, UnicodeDecodeError, ValueError, IndexError) as exc:
        raise InputError(f"cannot read a disparity offset from {path}: {exc}") from exc


def _scale_from_width(width: int) -> float:
    """Middlebury 2005/2006: disparity scale 1 at full size (~1300-1400 px), 2 half, 3 third."""
    return 1.0 if width >= 1000 else 2.0 if width >= 550 else 3.0


def _load(name: str, left_path: Path, right_path: Path, gt_path: Path | None,
          all_path: Path | None, offset_path: Path | None, layout: Layout,
          ndisp: int | None) -> StereoScene:
    left, right = read_image(left_path), read_image(right_path)
    if left.shape != right.shape:
        raise InputError(f"scene {name}: {left_path.name} {left.shape} and {right_path.name} "
                         f"{right.shape} differ")
    scale = layout.scale or _scale_from_width(left.shape[1])
    ground_truth = mask = None
    if gt_path is not None and gt_path.is_file():
        ground_truth = read_scaled_disparity(gt_path, scale=scale)
        if offset_path is not None and offset_path.is_file():
            ground_truth += np.float32(_read_offset(offset_path))
        if ground_truth.shape != left.shape[:2]:
            raise InputError(f"scene {name}: {gt_path.name} shape {ground_truth.shape} does not "
                             f"match {left_path.name} {left.shape[:2]}")
        if layout.has_masks:
            nonocc = np.isfinite(ground_truth)
            if all_path is not None and all_path.is_file():
                ground_truth = read_scaled_disparity(all_path, scale=scale)
                if ground_truth.shape != left.shape[:2]:
                    raise InputError(f"scene {name}: {all_path} shape {ground_truth.shape} does "
                                     f"not match {left_path.name} {left.shape[:2]}")
            mask = np.where(nonocc, 255, np.where(np.isfinite(ground_truth), 128, 0))
            mask = mask.astype(np.uint8)
    if ndisp is None:
        if ground_truth is None:
            raise InputError(f"scene {name}: no ground truth ({gt_path}) to size the search "
                             "range; give the disparity count (sswjax evaluate --ndisp N)")
        try:
            ndisp = ndisp_from_ground_truth(ground_truth)
        except ValueError as exc:
            raise InputError(f"scene {name}: {gt_path.name}: {exc}") from exc
    return StereoScene(name, left, right, int(ndisp), ground_truth, mask, left_path.parent)


def _load_eth3d(name: str, folder: Path, gt_folder: Path, layout: Layout,
                ndisp: int | None) -> StereoScene:
    """One ETH3D two-view scene: images and ``calib.txt`` in ``folder``, GT in ``gt_folder``."""
    for required in (layout.left, layout.right):
        if not (folder / required).is_file():
            raise InputError(f"scene {name}: missing {required} in {folder}")
    left, right = read_image(folder / layout.left), read_image(folder / layout.right)
    if left.shape[:2] != right.shape[:2]:
        raise InputError(f"scene {name}: {layout.left} {left.shape} and {layout.right} "
                         f"{right.shape} differ in size")
    ground_truth = mask = None
    if (gt_folder / layout.ground_truth).is_file():
        ground_truth = read_pfm(gt_folder / layout.ground_truth)
        if ground_truth.shape != left.shape[:2]:
            raise InputError(f"scene {name}: {layout.ground_truth} shape {ground_truth.shape} "
                             f"does not match {layout.left} {left.shape[:2]}")
    if (gt_folder / layout.mask).is_file():
        mask = read_image(gt_folder / layout.mask)
        if mask.dtype != np.uint8 or mask.shape != left.shape[:2]:
            raise InputError(f"scene {name}: {layout.mask} must be uint8 gray {left.shape[:2]}, "
                             f"got {mask.dtype} {mask.shape}")
    calib = folder / "calib.txt"
    if ndisp is None and calib.is_file() and re.search(r"(?m)^\s*ndisp\s*=", _text(calib)):
        ndisp = read_calib(calib)["ndisp"]
    if ndisp is None:
        if ground_truth is None:
            raise InputError(f"scene {name}: neither ndisp in {calib} nor ground truth in "
                             f"{gt_folder} to size the search range; give sswjax evaluate --ndisp N")
        try:
            ndisp = ndisp_from_ground_truth(ground_truth)
        except ValueError as exc:
            raise InputError(f"scene {name}: {layout.ground_truth}: {exc}") from exc
    return StereoScene(name, left, right, int(ndisp), ground_truth, mask, folder)


def _text(path: Path) -> str:
    try:
        return path.read_text(encoding="ascii")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read calibration file {path}: {exc}") from exc


def _scene_sources(root: Path, layout: Layout) -> dict[str, tuple]:
    """Scene name -> the arguments of :func:`_load` (:func:`_load_eth3d` for ETH3D) that
    locate its files."""
    if layout.kind == "eth3d":
        base = _eth3d_base(root, layout) if root.is_dir() else None
        folders = [] if base is None else sorted(
            p for p in base.iterdir()
            if p.is_dir() and any((p / n).is_file() for n in (layout.left, layout.right)))
        if not folders:
            raise InputError(f"no {layout.name} scene folders {layout.files} in {root}")
        return {p.name: (p, base.parent / layout.ground_truth_split / p.name) for p in folders}
    if layout.kind == "views":
        base = _views_base(root, layout)
        if base is None:
            raise InputError(f"no {layout.name} folders {layout.files} in {root}")
        frames = sorted(p.name[: -len(_FRAME_SUFFIX)] for p in (base / layout.left).iterdir()
                        if p.name.endswith(_FRAME_SUFFIX))
        if not frames:
            raise InputError(f"no *{_FRAME_SUFFIX} images in {base / layout.left}")
        every = layout.ground_truth_all
        return {
            f: (base / layout.left / f"{f}{_FRAME_SUFFIX}", base / layout.right / f"{f}{_FRAME_SUFFIX}",
                base / layout.ground_truth / f"{f}{_FRAME_SUFFIX}",
                None if every is None else base / every / f"{f}{_FRAME_SUFFIX}", None)
            for f in frames
        }
    folders = _scene_folders(root, layout) if root.is_dir() else []
    if not folders:
        raise InputError(f"no {layout.name} scene folders {layout.files} in {root}")
    return {
        p.name: (p / layout.left, p / layout.right, p / layout.ground_truth, None,
                 None if layout.offset_file is None else p / layout.offset_file)
        for p in folders
    }


def load_scenes(
    root: str | os.PathLike,
    *,
    layout: Layout | str | None = None,
    split: str = "trainingQ",
    scenes: Sequence[str] | None = None,
    ndisp: int | None = None,
) -> list[StereoScene]:
    """Load all (or selected) scenes of a data folder in any layout of :data:`LAYOUTS`.

    Parameters
    ----------
    root : str or os.PathLike
        Data folder (see the module docstring for each layout's files).
    layout : Layout or str, optional
        Layout or its name; default :func:`detect_layout`.
    split : str
        MiddEval3 split sub-folder, e.g. ``"trainingQ"`` (other layouts ignore it).
    scenes : sequence of str, optional
        Scene names to load, in this order (KITTI: frame numbers such as ``"000100"``);
        default all, sorted by name.
    ndisp : int, optional
        Disparity count of every scene, replacing ``calib.txt`` (MiddEval3) or the
        ground-truth rule (:func:`ndisp_from_ground_truth`).

    Returns
    -------
    list of StereoScene

    Raises
    ------
    InputError
        If the data is missing, broken or of no known layout, or a requested scene does not
        exist.
    ValueError
        If ``ndisp`` is not a positive integer.

    Examples
    --------
    >>> [s.ndisp for s in load_scenes("/work/shared/data/Middlebury2001")]  # doctest: +SKIP
    [16, 16, 24, 24]
    """
    if ndisp is not None and (isinstance(ndisp, bool) or not isinstance(ndisp, (int, np.integer))
                              or ndisp < 1):
        raise ValueError(f"ndisp must be a positive integer, got {ndisp!r}")
    root = Path(root).expanduser()
    if layout is None:
        layout = detect_layout(root, split=split)
    elif isinstance(layout, str):
        if layout not in LAYOUTS:
            raise InputError(f"unknown layout {layout!r}; recognised: {', '.join(LAYOUTS)}")
        layout = LAYOUTS[layout]
    if layout.kind == "middeval3":
        loaded = load_middeval3(root, split=split, scenes=scenes)
        return loaded if ndisp is None else [s._replace(ndisp=int(ndisp)) for s in loaded]
    available = _scene_sources(root, layout)
    names = list(available) if scenes is None else [scenes] if isinstance(scenes, str) else list(scenes)
    unknown = [n for n in names if n not in available]
    if unknown:
        raise InputError(f"unknown scene(s) {', '.join(unknown)} in {root}; "
                         f"available: {', '.join(available)}")
    load = _load_eth3d if layout.kind == "eth3d" else _load
    return [load(n, *available[n], layout, ndisp) for n in names]
