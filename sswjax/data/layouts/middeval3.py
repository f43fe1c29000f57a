"""The Middlebury 2014 / MiddEval3 layout: one folder per scene, under a split folder.

A scene folder holds ``im0.png``, ``im1.png`` and ``calib.txt`` (required) and optionally
``disp0GT.pfm`` (PFM, ``inf`` = unknown) and ``mask0nocc.png`` (used as it is). Only ``ndisp``
is taken from the calibration: the ground-truth ``vmin``/``vmax`` are deliberately never used,
since a method must not know them. Arrays as in :mod:`sswjax.data.layouts.base`; the images are
``(H, W, 3)`` ``uint8``.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from pathlib import Path

from sswjax._files import InputError
from sswjax.data.calibration import read_calib
from sswjax.data.io import read_pfm
from sswjax.data.layouts.base import (
    Layout,
    StereoScene,
    check_shape,
    read_mask,
    read_pair,
    require_files,
    select,
)

__all__ = [
    "MIDDEVAL3",
    "MiddEval3Layout",
    "find_data_root",
    "load_middeval3",
    "load_scene",
    "scene_dirs",
]

_SCENE_FILES = ("im0.png", "im1.png", "calib.txt")  # required in every scene folder
_GROUND_TRUTH, _MASK = "disp0GT.pfm", "mask0nocc.png"


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
    project_root = Path(__file__).resolve().parents[3]  # sswjax/data/layouts/middeval3.py
    return project_root.parent / "shared" / "data" / "MiddEval3"


def _is_scene(folder: Path) -> bool:
    return folder.is_dir() and any((folder / f).is_file() for f in _SCENE_FILES)


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
    scenes = sorted(p for p in base.iterdir() if _is_scene(p))
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
    require_files(name, scene_dir, _SCENE_FILES)
    left, right = read_pair(name, scene_dir / "im0.png", scene_dir / "im1.png")
    ndisp = int(read_calib(scene_dir / "calib.txt")["ndisp"])

    ground_truth = mask = None
    if (scene_dir / _GROUND_TRUTH).is_file():
        ground_truth = read_pfm(scene_dir / _GROUND_TRUTH)
        check_shape(name, _GROUND_TRUTH, ground_truth, "im0.png", left.shape[:2])
    if (scene_dir / _MASK).is_file():
        mask = read_mask(name, scene_dir / _MASK, left.shape[:2])
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
    return [load_scene(available[n]) for n in select(available, scenes, root)]


@dataclasses.dataclass(frozen=True)
class MiddEval3Layout(Layout):
    """MiddEval3: ``[<split>/]<scene>/{im0.png,im1.png,calib.txt}``, ``ndisp`` from ``calib.txt``."""

    name: str = "MiddEval3"
    scoring = "middeval3"
    ndisp_rule = "ndisp of each scene's calib.txt"

    @property
    def files(self) -> str:
        return "<scene>/{" + ",".join(_SCENE_FILES) + "}"

    @property
    def required(self) -> tuple[tuple[str, str], ...]:
        return (("ground_truth", _GROUND_TRUTH), ("mask", _MASK))

    def matches(self, root: Path, split: str) -> bool:
        return (root / split).is_dir() or any(_is_scene(p) for p in root.iterdir())

    def sources(self, root: Path, split: str) -> dict[str, Path]:
        return {p.name: p for p in scene_dirs(root, split=split)}

    def load(self, name: str, source: Path, *, ndisp: int | None) -> StereoScene:
        scene = load_scene(source)
        return scene if ndisp is None else scene._replace(ndisp=int(ndisp))


MIDDEVAL3 = MiddEval3Layout()
