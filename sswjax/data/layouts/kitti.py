"""The KITTI 2012 / 2015 stereo layout: one folder per view, one file per scene in each.

Folders are ``<root>/training/<view folder>/<frame>_10.png`` (``root`` may also be the
``training`` folder), scenes named by frame (``"000100"``). The ground truth is a 16-bit PNG of
``round(disparity * 256)``, 0 = unknown (:func:`sswjax.data.scaled.read_scaled_disparity`).
``disp_noc`` holds only non-occluded pixels, so every pixel it knows is 255 in the mask; when
``disp_occ`` is there too it becomes the ground truth and the pixels only it knows are 128.
There is no disparity count: :func:`~sswjax.data.layouts.base.ndisp_from_ground_truth`, at
most the image width - 1.
Arrays as in :mod:`sswjax.data.layouts.base`; KITTI 2012 images are gray ``(H, W)``, 2015 RGB.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import NamedTuple

import numpy as np

from sswjax._files import InputError
from sswjax.data.layouts.base import Layout, StereoScene, check_shape, ndisp_or_rule, read_pair
from sswjax.data.scaled import read_scaled_disparity

__all__ = ["KITTI2012", "KITTI2015", "KittiFiles", "KittiLayout"]

_FRAME_SUFFIX = "_10.png"  # the reference frame of each sequence


class KittiFiles(NamedTuple):
    """The files of one KITTI scene (``ground_truth_all`` ``None`` when the layout has none)."""

    left: Path
    right: Path
    ground_truth: Path
    ground_truth_all: Path | None


@dataclasses.dataclass(frozen=True)
class KittiLayout(Layout):
    """KITTI: ``training/{<left>,<right>,<ground truth>}/<frame>_10.png``.

    Attributes
    ----------
    left, right, ground_truth : str
        Folders of the left images, the right images and the non-occluded ground truth.
    ground_truth_all : str or None
        Folder of the ground truth that also covers occluded pixels.
    split : str
        Sub-folder holding the view folders.
    scale : float
        Ground-truth file value per pixel of disparity.
    """

    name: str
    left: str
    right: str
    ground_truth: str
    ground_truth_all: str | None = None
    split: str = "training"
    scale: float = 256.0
    scoring = "kitti"

    @property
    def files(self) -> str:
        return f"{self.split}/{{{','.join([self.left, self.right, self.ground_truth])}}}"

    @property
    def required(self) -> tuple[tuple[str, str], ...]:
        return (("ground_truth", self.ground_truth),)

    def scoring_file(self, scene: StereoScene, attribute: str) -> Path:
        base = scene.path.parent  # the folder of the view folders
        return base / dict(self.required)[attribute] / f"{scene.name}{_FRAME_SUFFIX}"

    def _base(self, root: Path) -> Path | None:
        """The folder holding the view folders under ``root`` (or ``root`` itself)."""
        for base in (root / self.split, root):
            if (base / self.left).is_dir() and (base / self.right).is_dir():
                return base
        return None

    def matches(self, root: Path, split: str) -> bool:
        return self._base(root) is not None

    def sources(self, root: Path, split: str) -> dict[str, KittiFiles]:
        base = self._base(root)
        if base is None:
            raise InputError(f"no {self.name} folders {self.files} in {root}")
        frames = sorted(p.name[: -len(_FRAME_SUFFIX)] for p in (base / self.left).iterdir()
                        if p.name.endswith(_FRAME_SUFFIX))
        if not frames:
            raise InputError(f"no *{_FRAME_SUFFIX} images in {base / self.left}")
        every = self.ground_truth_all
        return {
            f: KittiFiles(base / self.left / f"{f}{_FRAME_SUFFIX}",
                          base / self.right / f"{f}{_FRAME_SUFFIX}",
                          base / self.ground_truth / f"{f}{_FRAME_SUFFIX}",
                          None if every is None else base / every / f"{f}{_FRAME_SUFFIX}")
            for f in frames
        }

    def load(self, name: str, source: KittiFiles, *, ndisp: int | None) -> StereoScene:
        left, right = read_pair(name, source.left, source.right)
        shape, image, every = left.shape[:2], source.left.name, source.ground_truth_all
        ground_truth = mask = None
        if source.ground_truth.is_file():
            ground_truth = read_scaled_disparity(source.ground_truth, scale=self.scale)
            check_shape(name, source.ground_truth.name, ground_truth, image, shape)
            nonocc = np.isfinite(ground_truth)
            if every is not None and every.is_file():
                ground_truth = read_scaled_disparity(every, scale=self.scale)
                check_shape(name, str(every), ground_truth, image, shape)
            mask = np.where(nonocc, 255, np.where(np.isfinite(ground_truth), 128, 0))
            mask = mask.astype(np.uint8)
        if ndisp is None:
            ndisp = ndisp_or_rule(
                name, ground_truth, source.ground_truth.name,
                f"scene {name}: no ground truth ({source.ground_truth}) to size the search "
                "range; give the disparity count (sswjax evaluate --ndisp N)",
                limit=shape[1] - 1)
        return StereoScene(name, left, right, int(ndisp), ground_truth, mask, source.left.parent)


KITTI2012 = KittiLayout("KITTI2012", "image_0", "image_1", "disp_noc", "disp_occ")
KITTI2015 = KittiLayout("KITTI2015", "image_2", "image_3", "disp_noc_0", "disp_occ_0")
