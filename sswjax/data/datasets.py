"""Loading Middlebury 2014 / MiddEval3 stereo scenes.

Array conventions
-----------------
* ``left``/``right``: images exactly as read by :func:`sswjax.data.io.read_image`, ``(H, W, 3)``
  (or ``(H, W)``) ``uint8`` for MiddEval3.
* ``ground_truth``: ``float32`` ``(H, W)`` left disparity in pixels, ``inf`` = unknown.
* ``mask``: ``uint8`` ``(H, W)``; 255 = non-occluded, 128 = occluded, 0 = unknown.

A scene folder holds ``im0.png``, ``im1.png`` and ``calib.txt`` (required) and optionally
``disp0GT.pfm`` and ``mask0nocc.png``. Only ``ndisp`` is taken from the calibration: the
ground-truth ``vmin``/``vmax`` are deliberately never used, since a method must not know them.
The other benchmarks (KITTI, older Middlebury sets) load into the same :class:`StereoScene`
through :mod:`sswjax.data.layouts`, which also tells a folder's layout.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np

from sswjax.data.io import InputError, read_image, read_pfm

__all__ = [
    "StereoScene",
    "find_data_root",
    "load_middeval3",
    "load_scene",
    "read_calib",
    "scene_dirs",
]


_SCENE_FILES = ("im0.png", "im1.png", "calib.txt")  # required in every scene folder


class StereoScene(NamedTuple):
    """One rectified stereo pair with its calibration and optional ground truth."""

    name: str
    left: np.ndarray
    right: np.ndarray
    ndisp: int
    ground_truth: np.ndarray | None
    mask: np.ndarray | None
    path: Path


def read_calib(path: str | os.PathLike, *, require_ndisp: bool = True) -> dict[str, str | float]:
    """Parse a MiddEval3 ``calib.txt`` file of ``key=value`` lines.

    Parameters
    ----------
    path : str or os.PathLike
        Calibration file.
    require_ndisp : bool
        Refuse a file without ``ndisp`` (default; the depth tools of :mod:`sswjax.geometry`
        read calibrations without it). A present ``ndisp`` is always checked.

    Returns
    -------
    dict
        Key -> value; numbers become ``float`` (``ndisp`` an ``int``), anything else (such as
        the ``cam0`` matrix ``"[999.421 0 294.182; ...]"``) stays a ``str``.

    Raises
    ------
    InputError
        If the file is missing or unreadable, a line is not ``key=value``, or ``ndisp`` is
        missing (with ``require_ndisp``) or not a positive integer.

    Examples
    --------
    >>> read_calib("Motorcycle/calib.txt")["ndisp"]  # doctest: +SKIP
    70
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"calibration file not found: {path}")
    try:
        text = path.read_text(encoding="ascii")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read calibration file {path}: {exc}") from exc
    calib: dict[str, str | float] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        key, sep, value = line.partition("=")
        key, value = key.strip(), value.strip()
        if not sep or not key:
            raise InputError(
                f"calibration file {path} line {number} is not key=value: {line.strip()[:40]!r}"
            )
        try:
            calib[key] = float(value)
        except ValueError:
            calib[key] = value
    ndisp = calib.get("ndisp")
    if ndisp is None and not require_ndisp:
        return calib
    if not isinstance(ndisp, float) or not ndisp.is_integer() or ndisp < 1:
        raise InputError(f"calibration file {path} needs ndisp=<positive integer>, got {ndisp!r}")
    calib["ndisp"] = int(ndisp)
    return calib


def find_data_root(*, data: str | os.PathLike | None = None) -> Path:
    """Locate the MiddEval3 data directory.

    Priority: the ``data`` argument, the ``SSWJAX_DATA`` environment variable, then
    ``<project root>/../shared/data/MiddEval3`` (project root = parent of the ``sswjax``
    package directory). The path is not checked; :func:`scene_dirs` does that.

    Parameters
    ----------
    data : str or os.PathLike, optional
        Explicit data directory (MiddEval3 or a split folder such as ``trainingQ``).

    Returns
    -------
    pathlib.Path
        The chosen directory, possibly non-existent.

    Examples
    --------
    >>> find_data_root(data="/data/MiddEval3")
    PosixPath('/data/MiddEval3')
    """
    if data is not None:
        return Path(data).expanduser()
    env = os.environ.get("SSWJAX_DATA")
    if env:
        return Path(env).expanduser()
    project_root = Path(__file__).resolve().parents[2]  # sswjax/data/datasets.py -> project
    return project_root.parent / "shared" / "data" / "MiddEval3"


def scene_dirs(root: str | os.PathLike, *, split: str = "trainingQ") -> list[Path]:
    """List the scene folders under a MiddEval3 directory or a split folder.

    Uses ``root / split`` if it exists, otherwise ``root`` itself. A scene folder is any
    sub-folder that contains ``im0.png``, ``im1.png`` or ``calib.txt`` (so that a scene with a
    missing file is reported by :func:`load_scene` rather than silently skipped).

    Parameters
    ----------
    root : str or os.PathLike
        MiddEval3 directory, or a split folder such as ``.../MiddEval3/trainingQ``.
    split : str
        Split sub-folder to prefer.

    Returns
    -------
    list of pathlib.Path
        Scene folders sorted by name (never empty).

    Raises
    ------
    InputError
        If the directory does not exist or contains no scene folders.

    Examples
    --------
    >>> [p.name for p in scene_dirs(find_data_root())][:2]  # doctest: +SKIP
    ['Adirondack', 'ArtL']
    """
    root = Path(root)
    base = root / split if (root / split).is_dir() else root
    if not base.is_dir():
        raise InputError(f"data directory not found: {root}")
    scenes = sorted(
        p for p in base.iterdir() if p.is_dir() and any((p / f).is_file() for f in _SCENE_FILES)
    )
    if not scenes:
        raise InputError(f"no scene folders (with im0.png, im1.png or calib.txt) in {base}")
    return scenes


def load_scene(scene_dir: str | os.PathLike) -> StereoScene:
    """Load one scene folder.

    Parameters
    ----------
    scene_dir : str or os.PathLike
        Folder with ``im0.png``, ``im1.png``, ``calib.txt`` and optionally ``disp0GT.pfm``
        and ``mask0nocc.png``.

    Returns
    -------
    StereoScene
        ``ground_truth`` and ``mask`` are ``None`` when their files are absent.

    Raises
    ------
    InputError
        If a required file is missing or any file is unreadable or of inconsistent shape.

    Examples
    --------
    >>> scene = load_scene("MiddEval3/trainingQ/Motorcycle")  # doctest: +SKIP
    >>> scene.ndisp, scene.left.shape  # doctest: +SKIP
    (70, (497, 741, 3))
    """
    scene_dir = Path(scene_dir)
    name = scene_dir.name
    for required in _SCENE_FILES:
        if not (scene_dir / required).is_file():
            raise InputError(f"scene {name}: missing {required} in {scene_dir}")
    left = read_image(scene_dir / "im0.png")
    right = read_image(scene_dir / "im1.png")
    if left.shape != right.shape:
        raise InputError(f"scene {name}: im0.png {left.shape} and im1.png {right.shape} differ")
    ndisp = int(read_calib(scene_dir / "calib.txt")["ndisp"])

    ground_truth = mask = None
    if (scene_dir / "disp0GT.pfm").is_file():
        ground_truth = read_pfm(scene_dir / "disp0GT.pfm")
        if ground_truth.shape != left.shape[:2]:
            raise InputError(
                f"scene {name}: disp0GT.pfm shape {ground_truth.shape} does not match "
                f"im0.png {left.shape[:2]}"
            )
    if (scene_dir / "mask0nocc.png").is_file():
        mask = read_image(scene_dir / "mask0nocc.png")
        if mask.dtype != np.uint8 or mask.shape != left.shape[:2]:
            raise InputError(
                f"scene {name}: mask0nocc.png must be uint8 gray {left.shape[:2]}, "
                f"got {mask.dtype} {mask.shape}"
            )
    return StereoScene(name, left, right, ndisp, ground_truth, mask, scene_dir)


def load_middeval3(
    root: str | os.PathLike, *, split: str = "trainingQ", scenes: Sequence[str] | None = None
) -> list[StereoScene]:
    """Load all (or selected) scenes of a MiddEval3 split.

    Parameters
    ----------
    root : str or os.PathLike
        MiddEval3 directory or the split folder itself (see :func:`scene_dirs`).
    split : str
        Split sub-folder, e.g. ``"trainingQ"``.
    scenes : sequence of str, optional
        Scene names to load, in this order; default all, sorted by name.

    Returns
    -------
    list of StereoScene

    Raises
    ------
    InputError
        If the data is missing or broken, or a requested scene does not exist.

    Examples
    --------
    >>> [s.name for s in load_middeval3(find_data_root(), scenes=["Teddy"])]  # doctest: +SKIP
    ['Teddy']
    """
    available = {p.name: p for p in scene_dirs(root, split=split)}
    if scenes is None:
        selected = list(available.values())
    else:
        names = [scenes] if isinstance(scenes, str) else list(scenes)
        unknown = [n for n in names if n not in available]
        if unknown:
            raise InputError(
                f"unknown scene(s) {', '.join(unknown)} in {root}; "
                f"available: {', '.join(available)}"
            )
        selected = [available[n] for n in names]
    return [load_scene(p) for p in selected]
