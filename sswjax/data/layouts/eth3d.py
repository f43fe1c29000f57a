"""The ETH3D two-view layout: what its two training archives unpack to.

Folders are ``<root>/two_view_training/<scene>/{im0.png,im1.png,calib.txt}`` (the archive also
holds COLMAP's ``cameras.txt`` and ``images.txt``, not read) beside
``<root>/two_view_training_gt/<scene>/{disp0GT.pfm,mask0nocc.png}`` (PFM with ``inf`` =
unknown; the mask used as it is, 255 = non-occluded); ``root`` may also be the
``two_view_training`` folder. The images come from the gray cameras of ETH3D's rig, as 8-bit
PNG of one channel; they are read as stored, so a copy converted to RGB loads too. Arrays as in
:mod:`sswjax.data.layouts.base`: ``left`` and ``right`` may differ in channels.

The disparity count
-------------------
``calib.txt`` is in Middlebury's format (``cam0``, ``cam1``, ``doffs``, ``baseline``, ``width``,
``height``, ``ndisp``, ``isint``, ``vmin``, ``vmax``, ``dyavg``, ``dymax``), but ETH3D writes the
image width as ``ndisp`` (``width=942`` ... ``ndisp=942`` in every training scene): a bound that
allows any disparity, not a search range, and one no pair can be matched over (``ndisp`` must
be below the width). So an ``ndisp`` below the image width is used as it is; one that is not,
or none, gives way to the ground-truth rule
(:func:`~sswjax.data.layouts.base.ndisp_from_ground_truth`: the smallest multiple of 8 >= the
largest known disparity + 2), at most the image width - 1. An explicit ``ndisp`` replaces both.

That rule sizes the range from the answer, so it scores a scene but is not what a method
should search: :attr:`Eth3dLayout.estimates_range` is true, and ``sswjax evaluate`` has the SSW
methods search the range :func:`sswjax.api.auto_range.estimate_range` finds in each pair unless
``--ndisp layout`` (this rule) or ``--ndisp N`` is given (``docs/data-layouts.md`` says why).

Its scene folders look like MiddEval3's, which it therefore supersedes in detection.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path
from typing import NamedTuple

from sswjax._files import InputError
from sswjax.data.calibration import read_calib
from sswjax.data.io import read_pfm
from sswjax.data.layouts.base import (
    Layout,
    StereoScene,
    check_shape,
    ndisp_or_rule,
    read_mask,
    read_pair,
    require_files,
)

__all__ = ["ETH3D", "Eth3dFolders", "Eth3dLayout"]


class Eth3dFolders(NamedTuple):
    """The two folders of one ETH3D scene: its images and its ground truth."""

    images: Path
    ground_truth: Path


def _text(path: Path) -> str:
    try:
        return path.read_text(encoding="ascii")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read calibration file {path}: {exc}") from exc


@dataclasses.dataclass(frozen=True)
class Eth3dLayout(Layout):
    """ETH3D two-view: image scene folders in ``split`` beside GT scene folders.

    Attributes
    ----------
    left, right : str
        File names of the images in an image scene folder.
    ground_truth, mask : str
        File names of the ground truth and the occlusion mask in a ground-truth scene folder.
    split : str
        Folder of the image scene folders.
    ground_truth_split : str
        Folder, beside ``split``, of the ground-truth scene folders.
    """

    name: str = "ETH3D"
    left: str = "im0.png"
    right: str = "im1.png"
    ground_truth: str = "disp0GT.pfm"
    mask: str = "mask0nocc.png"
    split: str = "two_view_training"
    ground_truth_split: str = "two_view_training_gt"
    supersedes = ("MiddEval3",)
    ndisp_rule = ("calib.txt's ndisp when below the image width; ETH3D writes the width there, "
                  "which is no search range, so then the smallest multiple of 8 >= the largest "
                  "known disparity + 2, at most the image width - 1")
    estimates_range = True

    @property
    def files(self) -> str:
        return (f"{self.split}/<scene>/{{{self.left},{self.right},calib.txt}} + "
                f"{self.ground_truth_split}/<scene>/{{{self.ground_truth},{self.mask}}}")

    @property
    def required(self) -> tuple[tuple[str, str], ...]:
        return (("ground_truth", self.ground_truth), ("mask", self.mask))

    def scoring_file(self, scene: StereoScene, attribute: str) -> Path:
        base = scene.path.parent  # the two_view_training folder
        return base.parent / self.ground_truth_split / scene.name / dict(self.required)[attribute]

    def _base(self, root: Path) -> Path | None:
        """The ``two_view_training`` folder: under ``root``, or ``root`` itself beside its GT."""
        if (root / self.split).is_dir():
            return root / self.split
        if root.name == self.split and (root.parent / self.ground_truth_split).is_dir():
            return root
        return None

    def matches(self, root: Path, split: str) -> bool:
        return self._base(root) is not None

    def sources(self, root: Path, split: str) -> dict[str, Eth3dFolders]:
        base = self._base(root) if root.is_dir() else None
        folders = [] if base is None else sorted(
            p for p in base.iterdir()
            if p.is_dir() and any((p / n).is_file() for n in (self.left, self.right)))
        if not folders:
            raise InputError(f"no {self.name} scene folders {self.files} in {root}")
        truth = base.parent / self.ground_truth_split
        return {p.name: Eth3dFolders(p, truth / p.name) for p in folders}

    def load(self, name: str, source: Eth3dFolders, *, ndisp: int | None) -> StereoScene:
        folder, gt_folder = source
        require_files(name, folder, (self.left, self.right))
        left, right = read_pair(name, folder / self.left, folder / self.right, size_only=True)
        shape = left.shape[:2]
        ground_truth = mask = None
        if (gt_folder / self.ground_truth).is_file():
            ground_truth = read_pfm(gt_folder / self.ground_truth)
            check_shape(name, self.ground_truth, ground_truth, self.left, shape)
        if (gt_folder / self.mask).is_file():
            mask = read_mask(name, gt_folder / self.mask, shape)
        calib, width = folder / "calib.txt", shape[1]
        written = None  # calib.txt's ndisp, when it has one
        if ndisp is None and calib.is_file() and re.search(r"(?m)^\s*ndisp\s*=", _text(calib)):
            written = read_calib(calib)["ndisp"]
            ndisp = written if written < width else None
        if ndisp is None:
            missing = (
                f"scene {name}: neither ndisp in {calib} nor ground truth in {gt_folder} to "
                "size the search range; give sswjax evaluate --ndisp N" if written is None else
                f"scene {name}: ndisp={written} in {calib} is not below the image width "
                f"{width} (no search range) and there is no ground truth in {gt_folder} to "
                "size one; give sswjax evaluate --ndisp N")
            ndisp = ndisp_or_rule(name, ground_truth, self.ground_truth, missing,
                                  limit=width - 1)
        return StereoScene(name, left, right, int(ndisp), ground_truth, mask, folder)


ETH3D = Eth3dLayout()
