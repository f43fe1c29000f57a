"""The older Middlebury stereo sets (2001, 2003, 2005, 2006): one folder per scene.

Folders are ``<root>/<scene>/<files>`` with fixed file names per set. The ground truth stores
``round(disparity * scale)`` in integers, 0 = unknown
(:func:`sswjax.data.scaled.read_scaled_disparity`): 2001 ``disp2.pgm`` at scale 8, 2003 at 4,
2005/2006 ``disp1.png`` at the scale of the image size (1 full, 2 half, 3 third size, told by
the width). A ``dmin.txt`` beside a 2005/2006 map (full size) holds an offset added to its known
disparities. These sets have no occlusion mask (``None``: scored on region "all" only) and no
disparity count (:func:`~sswjax.data.layouts.base.ndisp_from_ground_truth`, at most the image
width - 1). Arrays as in
:mod:`sswjax.data.layouts.base`; the images are ``(H, W, 3)`` ``uint8``.

2001 and 2003 share their file names, as do 2005 and 2006: :attr:`MiddleburyLayout.known_scenes`
tells them apart when the folder's name holds no year.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from sswjax._files import InputError
from sswjax.data.layouts.base import Layout, StereoScene, check_shape, ndisp_or_rule, read_pair
from sswjax.data.scaled import read_scaled_disparity

__all__ = [
    "MIDDLEBURY2001",
    "MIDDLEBURY2003",
    "MIDDLEBURY2005",
    "MIDDLEBURY2006",
    "MiddleburyLayout",
]


def _read_offset(path: Path) -> float:
    try:
        return float(path.read_text(encoding="ascii").split()[0])
    except (OSError, UnicodeDecodeError, ValueError, IndexError) as exc:
        raise InputError(f"cannot read a disparity offset from {path}: {exc}") from exc


def _scale_from_width(width: int) -> float:
    """Middlebury 2005/2006: disparity scale 1 at full size (~1300-1400 px), 2 half, 3 third."""
    return 1.0 if width >= 1000 else 2.0 if width >= 550 else 3.0


@dataclasses.dataclass(frozen=True)
class MiddleburyLayout(Layout):
    """Middlebury: ``<scene>/{<left>,<right>,<ground truth>}``.

    Attributes
    ----------
    left, right, ground_truth : str
        File names of the left image, the right image and the ground truth in a scene folder.
    scale : float or None
        Ground-truth file value per pixel of disparity; ``None``: from the image width.
    known_scenes : tuple of str
        The set's scene names (lower case).
    offset_file : str or None
        Optional file holding a disparity offset (``dmin.txt``).
    """

    name: str
    left: str
    right: str
    ground_truth: str
    scale: float | None = None
    known_scenes: tuple[str, ...] = ()
    offset_file: str | None = None
    has_masks = False

    @property
    def files(self) -> str:
        return f"<scene>/{{{','.join([self.left, self.right, self.ground_truth])}}}"

    @property
    def required(self) -> tuple[tuple[str, str], ...]:
        return (("ground_truth", self.ground_truth),)

    def _folders(self, root: Path) -> list[Path]:
        """Sub-folders of ``root`` holding any of the three files, sorted by name."""
        names = (self.left, self.right, self.ground_truth)
        return sorted(p for p in root.iterdir()
                      if p.is_dir() and any((p / n).is_file() for n in names))

    def matches(self, root: Path, split: str) -> bool:
        return bool(self._folders(root))

    def sources(self, root: Path, split: str) -> dict[str, Path]:
        folders = self._folders(root) if root.is_dir() else []
        if not folders:
            raise InputError(f"no {self.name} scene folders {self.files} in {root}")
        return {p.name: p for p in folders}

    def load(self, name: str, source: Path, *, ndisp: int | None) -> StereoScene:
        left_path, gt_path = source / self.left, source / self.ground_truth
        left, right = read_pair(name, left_path, source / self.right)
        scale = self.scale or _scale_from_width(left.shape[1])
        ground_truth = None
        if gt_path.is_file():
            ground_truth = read_scaled_disparity(gt_path, scale=scale)
            offset = None if self.offset_file is None else source / self.offset_file
            if offset is not None and offset.is_file():
                ground_truth += np.float32(_read_offset(offset))
            check_shape(name, gt_path.name, ground_truth, left_path.name, left.shape[:2])
        if ndisp is None:
            ndisp = ndisp_or_rule(
                name, ground_truth, gt_path.name,
                f"scene {name}: no ground truth ({gt_path}) to size the search range; give "
                "the disparity count (sswjax evaluate --ndisp N)", limit=left.shape[1] - 1)
        return StereoScene(name, left, right, int(ndisp), ground_truth, None, source)


_2005_2006 = dict(left="view1.png", right="view5.png", ground_truth="disp1.png",
                  offset_file="dmin.txt")

MIDDLEBURY2001 = MiddleburyLayout(
    "Middlebury2001", "im2.ppm", "im6.ppm", "disp2.pgm", scale=8.0,
    known_scenes=("barn1", "barn2", "bull", "poster", "sawtooth", "venus"))
MIDDLEBURY2003 = MiddleburyLayout(
    "Middlebury2003", "im2.ppm", "im6.ppm", "disp2.pgm", scale=4.0,
    known_scenes=("cones", "teddy"))
MIDDLEBURY2005 = MiddleburyLayout(
    "Middlebury2005", known_scenes=("art", "books", "computer", "dolls", "drumsticks",
                                    "dwarves", "laundry", "moebius", "reindeer"), **_2005_2006)
MIDDLEBURY2006 = MiddleburyLayout(
    "Middlebury2006", known_scenes=(
        "aloe", "baby1", "baby2", "baby3", "bowling1", "bowling2", "cloth1", "cloth2", "cloth3",
        "cloth4", "flowerpots", "lampshade1", "lampshade2", "midd1", "midd2", "monopoly",
        "plastic", "rocks1", "rocks2", "wood1", "wood2"), **_2005_2006)
