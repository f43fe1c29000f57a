"""What every stereo benchmark layout provides: :class:`StereoScene` and the :class:`Layout` base.

Array conventions (every layout loads into the same :class:`StereoScene`)
-------------------------------------------------------------------------
* ``left``/``right``: images exactly as read by :func:`sswjax.data.io.read_image`, ``uint8``
  ``(H, W)`` (gray) or ``(H, W, 3)``.
* ``ground_truth``: ``float32`` ``(H, W)`` left disparity in pixels, ``inf`` = unknown.
* ``mask``: ``uint8`` ``(H, W)``; 255 = non-occluded, 128 = occluded, 0 = unknown; ``None`` for
  layouts without one (scored on region "all" only).
* ``ndisp``: the disparity count searched. A layout reads it from its calibration when it has
  one; otherwise the protocol is the smallest multiple of 8 that is >= max(ground truth) + 2
  (:func:`ndisp_from_ground_truth`), at most the image width - 1 (the widest range a pair
  allows): the ground truth only sizes the search range, as in our published figures for the
  peers. Each layout states its rule in :attr:`Layout.ndisp_rule`. An explicit ``ndisp``
  replaces it for every scene.

A layout lists a folder's scenes (:meth:`Layout.sources`), loads one (:meth:`Layout.load`) and
says why a loaded scene cannot be scored (:meth:`Layout.problem`); the helpers below hold the
checks and messages they share.
"""

from __future__ import annotations

import abc
import math
import os
from collections.abc import Collection, Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np

from sswjax._files import InputError
from sswjax.data.io import read_image

__all__ = [
    "Layout",
    "StereoScene",
    "check_shape",
    "ndisp_from_ground_truth",
    "ndisp_or_rule",
    "read_mask",
    "read_pair",
    "require_files",
    "select",
]


class StereoScene(NamedTuple):
    """One rectified stereo pair with its disparity count and optional ground truth.

    ``path`` is the folder of the left image (of the scene, for folder-per-scene layouts).
    """

    name: str
    left: np.ndarray
    right: np.ndarray
    ndisp: int
    ground_truth: np.ndarray | None
    mask: np.ndarray | None
    path: Path


class Layout(abc.ABC):
    """How one benchmark stores its scenes; the entries of :data:`sswjax.data.layouts.LAYOUTS`.

    Attributes
    ----------
    name : str
        Name shown to the user, e.g. ``"KITTI2012"``.
    scoring : str
        Summary of :mod:`sswjax.evaluation.runner`: ``"middeval3"`` (official weights),
        ``"kitti"`` (mean, with D1) or ``"mean"``.
    has_masks : bool
        Whether scenes carry an occlusion mask (region "nonocc").
    known_scenes : tuple of str
        Known scene names (lower case), to tell apart layouts with the same file names.
    supersedes : tuple of str
        Names of layouts that also match this one's folders but are not meant when it matches.
    ndisp_rule : str
        Where a scene's disparity count comes from, in one line for reports.
    estimates_range : bool
        Whether the layout's files carry no search range, so that ``sswjax evaluate`` has the
        SSW methods search the range estimated from each pair by default (``--ndisp auto``;
        ``--ndisp layout`` searches :attr:`ndisp_rule`'s, which scores either way).
    """

    name: str
    scoring: str = "mean"
    has_masks: bool = True
    known_scenes: tuple[str, ...] = ()
    supersedes: tuple[str, ...] = ()
    ndisp_rule: str = ("the smallest multiple of 8 >= the largest known disparity + 2, at most "
                       "the image width - 1")
    estimates_range: bool = False

    @property
    @abc.abstractmethod
    def files(self) -> str:
        """Where the files are, for messages: ``"training/{image_0,image_1,disp_noc}"``."""

    @property
    @abc.abstractmethod
    def required(self) -> tuple[tuple[str, str], ...]:
        """``(scene attribute, file name)`` of what scoring needs, e.g.
        ``(("ground_truth", "disp0GT.pfm"), ("mask", "mask0nocc.png"))``."""

    @abc.abstractmethod
    def matches(self, root: Path, split: str) -> bool:
        """Whether the existing folder ``root`` holds this layout's files.

        ``split`` is the MiddEval3 split sub-folder (other layouts ignore it).
        """

    @abc.abstractmethod
    def sources(self, root: Path, split: str) -> dict[str, object]:
        """Scene name -> what locates its files (for :meth:`load`), sorted by name.

        Raises :class:`~sswjax._files.InputError` if ``root`` holds no scene of this layout.
        """

    @abc.abstractmethod
    def load(self, name: str, source: object, *, ndisp: int | None) -> StereoScene:
        """Load scene ``name`` from its ``source`` (a value of :meth:`sources`).

        ``ndisp`` replaces the scene's own disparity count; raises
        :class:`~sswjax._files.InputError` if a file is missing, broken or of the wrong shape.
        """

    def scoring_file(self, scene: StereoScene, attribute: str) -> Path:
        """The file of ``scene`` that :attr:`required` names for ``attribute`` (for messages);
        by default in the scene's folder."""
        return scene.path / dict(self.required)[attribute]

    def problem(self, scene: StereoScene) -> str | None:
        """Why ``scene`` (loaded by :meth:`load`) cannot be scored, in a few words; ``None`` if
        it can.

        A scene cannot be scored without the files of :attr:`required`, without a pixel of
        known disparity (its metrics would be ``nan``), without a known pixel marked
        non-occluded (255) in its mask when it has one, or when its ``ndisp`` is not below its
        width (no pair can be matched over such a range).
        """
        files = dict(self.required)
        for attribute, _ in self.required:
            if getattr(scene, attribute) is None:
                path = self.scoring_file(scene, attribute)
                return f"missing {path.name} in {path.parent}"
        width = scene.left.shape[1]
        if scene.ndisp >= width:
            return f"ndisp {scene.ndisp} is not below the image width {width}"
        if scene.ground_truth is None:
            return None
        known = np.isfinite(scene.ground_truth)
        if not known.any():
            return f"{files.get('ground_truth', 'the ground truth')} has no known disparity"
        if scene.mask is not None and not (known & (scene.mask == 255)).any():
            return (f"{files.get('mask', 'the mask')} marks no pixel of known disparity "
                    "non-occluded (255)")
        return None


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


def ndisp_or_rule(name: str, ground_truth: np.ndarray | None, file_name: str,
                  missing: str, *, limit: int | None = None) -> int:
    """:func:`ndisp_from_ground_truth` of scene ``name`` (at most ``limit``), as an
    :class:`InputError`.

    Parameters
    ----------
    name : str
        Scene name, for messages.
    ground_truth : numpy.ndarray or None
        ``float32`` ``(H, W)`` disparity, ``inf`` = unknown; ``None`` when absent.
    file_name : str
        Ground-truth file name, for the message when it knows no disparity.
    missing : str
        The message when ``ground_truth`` is ``None``.
    limit : int, optional
        Largest count returned: the image width - 1, the widest range a pair allows.

    Returns
    -------
    int
    """
    if ground_truth is None:
        raise InputError(missing)
    try:
        ndisp = ndisp_from_ground_truth(ground_truth)
    except ValueError as exc:
        raise InputError(f"scene {name}: {file_name}: {exc}") from exc
    return ndisp if limit is None else max(1, min(ndisp, int(limit)))


def require_files(name: str, folder: Path, file_names: Sequence[str]) -> None:
    """Raise :class:`InputError` naming the first of ``file_names`` missing in ``folder``."""
    for required in file_names:
        if not (folder / required).is_file():
            raise InputError(f"scene {name}: missing {required} in {folder}")


def read_pair(name: str, left_path: Path, right_path: Path, *,
              size_only: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The two images of scene ``name``, as :func:`~sswjax.data.io.read_image` reads them.

    Parameters
    ----------
    name : str
        Scene name, for messages.
    left_path, right_path : pathlib.Path
        Image files.
    size_only : bool
        Accept images of different channels (a gray and an RGB one) of the same ``(H, W)``.

    Returns
    -------
    left, right : numpy.ndarray
        ``(H, W)`` or ``(H, W, 3)``, the files' dtype.

    Raises
    ------
    InputError
        If a file is unreadable or the two differ in shape (in size with ``size_only``).
    """
    left, right = read_image(left_path), read_image(right_path)
    if size_only and left.shape[:2] != right.shape[:2]:
        raise InputError(f"scene {name}: {left_path.name} {left.shape} and {right_path.name} "
                         f"{right.shape} differ in size")
    if not size_only and left.shape != right.shape:
        raise InputError(f"scene {name}: {left_path.name} {left.shape} and {right_path.name} "
                         f"{right.shape} differ")
    return left, right


def check_shape(name: str, what: str, array: np.ndarray, image_name: str,
                shape: tuple[int, ...]) -> None:
    """Raise :class:`InputError` unless ``array`` (file ``what``) is ``shape`` ``(H, W)`` of the
    image ``image_name`` of scene ``name``."""
    if array.shape != shape:
        raise InputError(f"scene {name}: {what} shape {array.shape} does not match "
                         f"{image_name} {shape}")


def read_mask(name: str, path: Path, shape: tuple[int, ...]) -> np.ndarray:
    """The occlusion mask file of scene ``name`` as it is: ``uint8`` ``(H, W)`` = ``shape``.

    Raises :class:`InputError` if it is unreadable or of another dtype or shape.
    """
    mask = read_image(path)
    if mask.dtype != np.uint8 or mask.shape != shape:
        raise InputError(f"scene {name}: {path.name} must be uint8 gray {shape}, "
                         f"got {mask.dtype} {mask.shape}")
    return mask


def select(available: Collection[str], scenes: str | Sequence[str] | None,
           root: str | os.PathLike) -> list[str]:
    """The names of ``scenes`` (one name or several, in this order; default all ``available``).

    Raises :class:`InputError` naming the unknown ones, the folder ``root`` and the available.
    """
    if scenes is None:
        return list(available)
    names = [scenes] if isinstance(scenes, str) else list(scenes)
    unknown = [n for n in names if n not in available]
    if unknown:
        raise InputError(f"unknown scene(s) {', '.join(unknown)} in {root}; "
                         f"available: {', '.join(available)}")
    return names
