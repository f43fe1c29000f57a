"""The registry of layouts: :data:`LAYOUTS`, telling a folder's layout and loading its scenes.

Adding a layout is one :class:`~sswjax.data.layouts.base.Layout` subclass (its module) and its
entry in :data:`LAYOUTS`. The layout of a folder is told by its files (:func:`detect_layout`);
layouts with the same file names (Middlebury 2001 and 2003; 2005 and 2006) are told apart by a
year in the folder's name, then by their known scene names. :func:`load_scenes` stops at the
first scene it cannot load; :func:`load_scenes_checked` tries every scene and returns the
others' problems beside the good ones. Arrays as in :mod:`sswjax.data.layouts.base`.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from sswjax._files import InputError, first_line
from sswjax.data.layouts.base import Layout, StereoScene, select
from sswjax.data.layouts.eth3d import ETH3D
from sswjax.data.layouts.kitti import KITTI2012, KITTI2015
from sswjax.data.layouts.middeval3 import MIDDEVAL3
from sswjax.data.layouts.middlebury import (
    MIDDLEBURY2001,
    MIDDLEBURY2003,
    MIDDLEBURY2005,
    MIDDLEBURY2006,
)

__all__ = ["DEFAULT_LAYOUT", "LAYOUTS", "detect_layout", "load_scenes", "load_scenes_checked"]

#: Every layout that :func:`detect_layout` recognises, by name, in the order it tries them.
LAYOUTS: dict[str, Layout] = {layout.name: layout for layout in (
    MIDDEVAL3, KITTI2012, KITTI2015, MIDDLEBURY2001, MIDDLEBURY2003, MIDDLEBURY2005,
    MIDDLEBURY2006, ETH3D,
)}

#: The layout of a folder that does not exist (its loader then reports it).
DEFAULT_LAYOUT = MIDDEVAL3.name


def _year(path: Path) -> str | None:
    match = re.search(r"(?<!\d)(20\d\d)(?!\d)", path.resolve().name)
    return match.group(1) if match else None


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
        return LAYOUTS[DEFAULT_LAYOUT]
    found = [layout for layout in LAYOUTS.values() if layout.matches(root, split)]
    superseded = {name for layout in found for name in layout.supersedes}
    found = [layout for layout in found if layout.name not in superseded]
    if len(found) > 1:  # same file names: a year in the folder's name, then known scene names
        year = _year(root)
        by_year = [layout for layout in found if year and layout.name.endswith(year)]
        names = {name.lower() for layout in found if layout.known_scenes
                 for name in layout.sources(root, split)}
        by_scenes = [layout for layout in found if names & set(layout.known_scenes)]
        found = by_year or by_scenes or found
    if len(found) == 1:
        return found[0]
    if found:
        raise InputError(f"cannot tell {' from '.join(x.name for x in found)} in {root} (same "
                         f"file names): put the year in the folder's name, e.g. {found[0].name}")
    known = "; ".join(f"{x.name} ({x.files})" for x in LAYOUTS.values())
    raise InputError(f"no known stereo data layout in {root}; recognised: {known}")


def _chosen(root: Path, layout: Layout | str | None, split: str, ndisp: int | None) -> Layout:
    """The layout to load ``root`` with, after checking ``ndisp`` (see :func:`load_scenes`)."""
    if ndisp is not None and (isinstance(ndisp, bool) or not isinstance(ndisp, (int, np.integer))
                              or ndisp < 1):
        raise ValueError(f"ndisp must be a positive integer, got {ndisp!r}")
    if layout is None:
        return detect_layout(root, split=split)
    if isinstance(layout, str):
        if layout not in LAYOUTS:
            raise InputError(f"unknown layout {layout!r}; recognised: {', '.join(LAYOUTS)}")
        return LAYOUTS[layout]
    return layout


def load_scenes(
    root: str | os.PathLike,
    *,
    layout: Layout | str | None = None,
    split: str = "trainingQ",
    scenes: Sequence[str] | None = None,
    ndisp: int | None = None,
) -> list[StereoScene]:
    """Load all (or selected) scenes of a data folder in any layout of :data:`LAYOUTS`.

    Stops at the first scene that cannot be loaded; :func:`load_scenes_checked` loads every
    scene it can and lists the others.

    Parameters
    ----------
    root : str or os.PathLike
        Data folder (see each layout's module for its files).
    layout : Layout or str, optional
        Layout or its name; default :func:`detect_layout`.
    split : str
        MiddEval3 split sub-folder, e.g. ``"trainingQ"`` (other layouts ignore it).
    scenes : sequence of str, optional
        Scene names to load, in this order (KITTI: frame numbers such as ``"000100"``);
        default all, sorted by name.
    ndisp : int, optional
        Disparity count of every scene, replacing ``calib.txt`` (MiddEval3, ETH3D) or the
        ground-truth rule (:func:`~sswjax.data.layouts.base.ndisp_from_ground_truth`).

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
    root = Path(root).expanduser()
    layout = _chosen(root, layout, split, ndisp)
    available = layout.sources(root, split)
    return [layout.load(name, available[name], ndisp=ndisp)
            for name in select(available, scenes, root)]


def _without_scene(name: str, message: str) -> str:
    """``message`` without its leading ``scene <name>: `` (the problem lists name the scene)."""
    prefix = f"scene {name}: "
    return message[len(prefix):] if message.startswith(prefix) else message


def load_scenes_checked(
    root: str | os.PathLike,
    *,
    layout: Layout | str | None = None,
    split: str = "trainingQ",
    scenes: Sequence[str] | None = None,
    ndisp: int | None = None,
    scorable: bool = True,
) -> tuple[list[StereoScene], list[tuple[str, str]]]:
    """Like :func:`load_scenes`, but every scene is tried: the good ones and why the others fail.

    Parameters
    ----------
    root, layout, split, scenes, ndisp
        As in :func:`load_scenes`.
    scorable : bool
        Also count as a problem what keeps a loaded scene from being scored
        (:meth:`~sswjax.data.layouts.base.Layout.problem`: missing ground truth or mask, no
        known disparity, ``ndisp`` not below the width).

    Returns
    -------
    scenes : list of StereoScene
        The scenes without a problem, in the order of ``scenes`` (default sorted by name).
    problems : list of (str, str)
        ``(scene name, reason)`` of every other scene, in the same order; the reason is one
        line, naming the file (the messages of :func:`load_scenes` without their
        ``scene <name>:``).

    Raises
    ------
    InputError
        What concerns the whole folder, as :func:`load_scenes`: the data missing or of no
        known layout, a requested scene that does not exist.
    ValueError
        If ``ndisp`` is not a positive integer.

    Examples
    --------
    >>> good, bad = load_scenes_checked("MiddEval3/trainingQ")  # doctest: +SKIP
    >>> bad  # doctest: +SKIP
    [('Vintage', 'disp0GT.pfm has no known disparity')]
    """
    root = Path(root).expanduser()
    layout = _chosen(root, layout, split, ndisp)
    available = layout.sources(root, split)
    loaded: list[StereoScene] = []
    problems: list[tuple[str, str]] = []
    for name in select(available, scenes, root):
        try:
            scene = layout.load(name, available[name], ndisp=ndisp)
        except (ValueError, OSError) as error:  # InputError, or a file the OS refuses
            problems.append((name, _without_scene(name, first_line(error))))
            continue
        problem = layout.problem(scene) if scorable else None
        if problem is None:
            loaded.append(scene)
        else:
            problems.append((name, problem))
    return loaded, problems
