"""The scenes of ``sswjax evaluate``: every scene checked before any is matched.

All scenes are loaded first (:func:`sswjax.data.layouts.load_scenes_checked`), and what keeps
any of them from being scored (a broken or missing file, a ground truth without one known
pixel, a disparity count the width does not allow) is gathered per scene. The run then refuses
with one line naming every bad scene and why, or, with ``--skip-bad``, scores the others and
says on stderr and in ``results.md`` which were skipped and why. Each bad scene is listed as
``scene <name>: <reason>``, the reason worded as when that scene alone stops a load (the file
it names in full).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from sswjax._files import InputError
from sswjax.data.layouts import Layout, StereoScene, load_scenes_checked

__all__ = ["Problems", "checked_scenes", "listed", "ndisp_line", "skipped_markdown"]

Problems = list[tuple[str, str]]
"""``(scene name, one-line reason)`` of every scene that cannot be scored, in scene order."""


def listed(problems: Problems) -> str:
    """``"scene Teddy: <reason>; scene Vintage: <reason>"``."""
    return "; ".join(f"scene {name}: {reason}" for name, reason in problems)


def checked_scenes(root: Path, layout: Layout, args: argparse.Namespace
                   ) -> tuple[list[StereoScene], Problems]:
    """The scenes of ``root`` that can be scored, and the problems of the others.

    Parameters
    ----------
    root : pathlib.Path
        Data folder.
    layout : Layout
        Its layout.
    args : argparse.Namespace
        ``split``, ``scenes``, ``ndisp`` and ``skip_bad`` of ``sswjax evaluate``.

    Returns
    -------
    scenes : list of StereoScene
    problems : list of (str, str)
        Empty unless ``args.skip_bad``; then the skipped scenes (also said on stderr).

    Raises
    ------
    InputError
        One line, if a scene cannot be scored and ``--skip-bad`` is not given, or if none can.
    """
    root = Path(root).expanduser()
    scenes, problems = load_scenes_checked(root, layout=layout, split=args.split,
                                           scenes=args.scenes, ndisp=args.ndisp)
    if not problems:
        return scenes, problems
    total = len(scenes) + len(problems)
    if not scenes:
        which = f"none of the {total} scenes in {root} can" if total > 1 else \
            f"the one scene in {root} cannot"
        raise InputError(f"{which} be scored: {listed(problems)}")
    if not args.skip_bad:
        raise InputError(f"{len(problems)} of {total} scenes cannot be scored: "
                         f"{listed(problems)} (in {root}; --skip-bad scores the other "
                         f"{len(scenes)})")
    print(f"sswjax: skipped {len(problems)} of {total} scenes, which cannot be scored: "
          f"{listed(problems)} (in {root})", file=sys.stderr)
    return scenes, problems


def skipped_markdown(problems: Problems, root: Path) -> str:
    """The note of ``results.md`` on the scenes ``--skip-bad`` left out (``""`` if none)."""
    if not problems:
        return ""
    lines = [f"## Skipped scenes ({len(problems)}, not in any average)", "",
             f"These scenes of {root} cannot be scored (`--skip-bad`):", ""]
    lines += [f"- {name}: {reason}" for name, reason in problems]
    return "\n".join(lines)


def ndisp_line(layout: Layout, ndisp: int | str | None) -> str:
    """Where the disparity counts of the run come from, one line of ``results.md``.

    ``ndisp``: a count, ``"auto"``, or ``"layout"`` / ``None`` (the layout's rule).
    """
    if ndisp == "auto":
        default = (f", the default for {layout.name}, whose files carry no search range; "
                   "--ndisp layout searches the layout's" if layout.estimates_range else "")
        return ("Disparity range searched by the SSW methods: estimated from each pair "
                f"(--ndisp auto{default}); scored, and searched by the peers, over "
                f"{layout.name}'s: {layout.ndisp_rule}.")
    if isinstance(ndisp, int):
        return f"Disparity range searched: 0..{ndisp - 1} in every scene (--ndisp {ndisp})."
    return f"Disparity range searched ({layout.name}): {layout.ndisp_rule}."
