"""What every command shares: the parser, the exit codes, Ctrl-C and the output files.

Errors in the user's input print one line ``sswjax: error: ...`` and exit with
:data:`EXIT_USAGE`; Ctrl-C exits with :data:`EXIT_INTERRUPTED` and the message of
:class:`Interrupted` (what was kept, and the command that continues). Outputs are checked
before any work (:func:`check_output_files`) and written atomically.
"""

from __future__ import annotations

import argparse
import shlex
import sys
import textwrap
from pathlib import Path

import numpy as np

from sswjax.data.io import write_disparity_png, write_pfm

__all__ = ["EXIT_INTERRUPTED", "EXIT_USAGE", "HelpFormatter", "Interrupted", "Parser", "check_output_files",
           "command_line", "gigabytes", "resume_command", "write_disparity_outputs"]

EXIT_USAGE = 2
"""Exit status of bad input (argparse's own convention)."""

EXIT_INTERRUPTED = 130
"""Exit status on Ctrl-C: 128 + SIGINT, the shell's convention."""


class HelpFormatter(argparse.HelpFormatter):
    """argparse's help, wrapped at spaces only: names such as ``left-band`` stay whole."""

    def _split_lines(self, text: str, width: int) -> list[str]:
        return textwrap.wrap(" ".join(text.split()), width, break_on_hyphens=False)


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors, exit status :data:`EXIT_USAGE` and
    :class:`HelpFormatter`."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str):  # noqa: D102
        self.exit(EXIT_USAGE, f"sswjax: error: {message}\n")


class Interrupted(KeyboardInterrupt):
    """Ctrl-C, carrying the one-line message shown to the user (what was kept, how to resume)."""


def resume_command(argv: list[str]) -> str:
    """The user's command line with ``--resume`` added (once), quoted for a shell.

    Examples
    --------
    >>> resume_command(["evaluate", "-o", "my runs"])
    "sswjax evaluate -o 'my runs' --resume"
    >>> resume_command(["match", "L", "R", "--resume"])
    'sswjax match L R --resume'
    """
    return shlex.join(["sswjax", *argv] + ([] if "--resume" in argv else ["--resume"]))


def command_line(args: argparse.Namespace) -> list[str]:
    """The arguments the command was run with (``main`` stores them in ``args.argv``)."""
    return list(getattr(args, "argv", sys.argv[1:]))


def check_output_files(*paths: Path | None) -> None:
    """Fail before any work if an output file cannot be created where the user asked.

    Raises ``ValueError`` (one line) for a path that is a folder or whose folder is missing;
    ``None`` entries (outputs not asked for) are skipped.
    """
    for path in paths:
        if path is None:
            continue
        if path.is_dir():
            raise ValueError(f"output {path} is a folder, expected a file name")
        if not path.parent.is_dir():
            raise ValueError(f"output folder does not exist: {path.parent}")


def write_disparity_outputs(disparity: np.ndarray, pfm: Path | None, png: Path | None,
                            ndisp: int, *, min_disp: int = 0) -> None:
    """Atomically write a float32 ``(H, W)`` map as PFM and as a colour PNG (either may be
    None); the PNG's colours span the searched range ``min_disp .. min_disp + ndisp - 1``."""
    if pfm is not None:
        write_pfm(pfm, disparity)
    if png is not None:
        write_disparity_png(png, disparity, vmin=min_disp, vmax=min_disp + ndisp - 1)


def gigabytes(text: str) -> float:
    """argparse type of ``--max-memory``: a finite number of GB > 0.

    Examples
    --------
    >>> gigabytes("2.5")
    2.5
    >>> gigabytes("inf")
    Traceback (most recent call last):
    ...
    argparse.ArgumentTypeError: must be a number of GB > 0, got 'inf'
    """
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value > 0 and value != float("inf")):
        raise argparse.ArgumentTypeError(f"must be a number of GB > 0, got {text!r}")
    return value
