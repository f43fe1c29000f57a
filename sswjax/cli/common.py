"""What every command shares: the parser, the exit codes, Ctrl-C and the output files.

Errors in the user's input print one line ``sswjax: error: ...`` and exit with
:data:`EXIT_USAGE`; Ctrl-C exits with :data:`EXIT_INTERRUPTED` and the message of
:class:`Interrupted` (what was kept, and the command that continues). Outputs are checked
before any work (:func:`check_outputs`: no output is an input or another output, each can be
written where the user asked, in a format its option writes, :data:`OUTPUT_FORMATS`), then
written all or nothing (:func:`sswjax._files.atomic_outputs`) by the writers of
:func:`disparity_writers` and its kin: functions of the temporary file to write.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import os
import shlex
import signal
import sys
import textwrap
import threading
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from sswjax._files import same_file
from sswjax.data.io import FLOAT_MAP_SUFFIXES, write_disparity_png, write_float_map
from sswjax.data.scaled import write_scaled_disparity

__all__ = ["EXIT_INTERRUPTED", "EXIT_USAGE", "OUTPUT_FORMATS", "PNG_DISPARITIES",
           "check_output_files", "check_range_formats",
           "check_outputs", "command_line", "disparity_writers", "gigabytes", "HelpFormatter",
           "interrupt_flag", "Interrupted", "Parser", "raise_if_interrupted",
           "remembered_interrupts", "resume_command", "uninterrupted",
           "write_disparity_map", "Writer"]

Writer = Callable[[Path], object]
"""What writes one output: a function of the (temporary) file to write."""

_FLOAT = ".pfm, .npy, .tif or .tiff (float32)"
OUTPUT_FORMATS: dict[str, tuple[tuple[str, ...], str]] = {
    "-o": (FLOAT_MAP_SUFFIXES + (".png",),
           f"{_FLOAT}, or .png (16-bit, round(disparity * 256), 0 = invalid)"),
    "--depth": (FLOAT_MAP_SUFFIXES, _FLOAT),
    "--confidence": (FLOAT_MAP_SUFFIXES, _FLOAT),
    "--png": ((".png",), ".png (colour-mapped, 8-bit)"),
    "--validity": ((".png",), ".png (8-bit)"),
    "--kitti-png": ((".png",), ".png (16-bit, disparity x 256)"),
    "--ply": ((".ply",), ".ply (binary point cloud)"),
}
"""Option of ``sswjax match`` -> the file name endings it writes (any case), and their words
(the ``formats`` of :func:`check_outputs`)."""

PNG_DISPARITIES = (0, 255)
"""The searched disparities KITTI's 16-bit PNG (``-o d.png``, ``--kitti-png``) holds:
``round(d * 256)`` in 1..65535, 0 = invalid, so 0 to 255.99 px: a search from 0 up to at most
255. A negative disparity, or one past 255.99, would be written 0 (invalid)."""

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


_RECEIVED: list[int] = []
"""SIGINTs received under :func:`remembered_interrupts` (the process has one SIGINT handler)."""


@contextlib.contextmanager
def remembered_interrupts():
    """Within it, Ctrl-C raises ``KeyboardInterrupt`` where it lands, as Python's own handler
    does, and is also remembered, so that :func:`raise_if_interrupted` raises it again.

    Python runs a signal's handler in whatever Python code runs next. In JAX that is often a
    garbage-collection callback, whose exceptions Python drops after printing "Exception
    ignored" and a traceback: the loops over scenes and pairs would then run to the end and
    exit 0. They ask :func:`raise_if_interrupted` after each result instead, and inside such a
    callback the handler only remembers the signal (no traceback for the user). Outside the
    main thread the block runs as it is."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(number, frame):
        _RECEIVED.append(number)
        if not _in_gc_callback(frame):
            raise KeyboardInterrupt

    _RECEIVED.clear()
    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        _RECEIVED.clear()


def _in_gc_callback(frame) -> bool:
    """Whether ``frame`` (a signal handler's) runs in a function of ``gc.callbacks`` or below one."""
    codes = {getattr(getattr(callback, "__func__", callback), "__code__", None)
             for callback in gc.callbacks}
    while frame is not None:
        if frame.f_code in codes:
            return True
        frame = frame.f_back
    return False


def raise_if_interrupted() -> None:
    """Raise ``KeyboardInterrupt`` if Ctrl-C was pressed under :func:`remembered_interrupts`
    (its exception may have been dropped where it landed)."""
    if _RECEIVED:
        raise KeyboardInterrupt


@contextlib.contextmanager
def uninterrupted():
    """Within it, Ctrl-C waits: a SIGINT received is raised as ``KeyboardInterrupt`` once the
    block is done, so a result's files, its record and its count are kept together (the
    interruption's message then counts exactly what ``--resume`` skips). Outside the main
    thread, where Python cannot install a handler, the block runs as it is."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received = []
    previous = signal.signal(signal.SIGINT, lambda number, frame: received.append(number))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if received and callable(previous):
        previous(signal.SIGINT, None)  # Python's default handler raises KeyboardInterrupt
    elif received and previous == signal.SIG_DFL:
        raise KeyboardInterrupt


@contextlib.contextmanager
def interrupt_flag():
    """Yield ``() -> bool``, true once Ctrl-C was pressed; a second Ctrl-C interrupts at once.

    The search asks it after every step and stops there with its checkpoint saved. Python's
    own handler would raise ``KeyboardInterrupt`` wherever the signal lands, which in JAX is
    often a garbage-collection callback that swallows it. The second Ctrl-C raises it where it
    lands too, except in such a callback (where it would be printed with a traceback and
    dropped): the step then ends and the flag stops the search. Outside the main thread the
    flag stays false."""
    received = []
    if threading.current_thread() is not threading.main_thread():
        yield lambda: False
        return

    def handler(number, frame):
        received.append(number)
        if len(received) > 1 and not _in_gc_callback(frame):
            raise KeyboardInterrupt

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield lambda: bool(received)
    finally:
        signal.signal(signal.SIGINT, previous)


def resume_command(argv: list[str]) -> str:
    """The user's command line with ``--resume`` added (once) and ``--overwrite`` dropped (the
    run to continue is the one it started), quoted for a shell.

    Examples
    --------
    >>> resume_command(["evaluate", "-o", "my runs", "--overwrite"])
    "sswjax evaluate -o 'my runs' --resume"
    >>> resume_command(["match", "L", "R", "--resume"])
    'sswjax match L R --resume'
    """
    argv = [arg for arg in argv if arg != "--overwrite"]
    return shlex.join(["sswjax", *argv] + ([] if "--resume" in argv else ["--resume"]))


def command_line(args: argparse.Namespace) -> list[str]:
    """The arguments the command was run with (``main`` stores them in ``args.argv``)."""
    return list(getattr(args, "argv", sys.argv[1:]))


def check_output_files(*paths: Path | None) -> None:
    """Fail before any work if an output file cannot be created where the user asked.

    Raises ``ValueError`` (one line) for ``-`` (read by many tools as standard output, where
    sswjax would write a file named ``-``), a path that is a folder or an existing read-only
    file, or whose folder is missing, not a folder or not writable; ``None`` entries (outputs
    not asked for) are skipped.

    Examples
    --------
    >>> check_output_files(Path("-"))
    Traceback (most recent call last):
    ...
    ValueError: output -: this option writes a file, not standard output: name a file
    """
    for path in paths:
        if path is None:
            continue
        if str(path) == "-":
            raise ValueError("output -: this option writes a file, not standard output: "
                             "name a file")
        if path.is_dir():
            raise ValueError(f"output {path} is a folder, expected a file name")
        folder = path.parent
        if not folder.is_dir():
            if folder.exists():
                raise ValueError(f"output folder {folder} is a file, not a folder")
            raise ValueError(f"output folder does not exist: {folder}")
        if not os.access(folder, os.W_OK | os.X_OK):
            raise ValueError(f"output folder {folder} is not writable")
        if path.exists() and not os.access(path, os.W_OK):
            raise ValueError(f"output {path} is a read-only file: not replaced")


def check_outputs(outputs: Mapping[str, Path | None],
                  inputs: Mapping[str, Path | None] | None = None, *,
                  formats: Mapping[str, tuple[tuple[str, ...], str]] | None = None) -> None:
    """Fail before any work, with one line naming the options, if an output would replace an
    input or another output, cannot be written (:func:`check_output_files`), or ends in a
    format its option does not write (``formats``, e.g. :data:`OUTPUT_FORMATS`).

    Parameters
    ----------
    outputs : option -> path, e.g. ``{"-o": Path("d.pfm"), "--png": None}`` (None: not asked)
    inputs : name -> path of the files read, e.g. ``{"LEFT": ..., "--params": None}``
    formats : option -> (the endings it writes, their words); options not in it: any ending

    Paths are compared by :func:`sswjax._files.same_file`: resolved, and by inode, so another
    spelling, a symbolic or a hard link of the same file counts as the same.

    Examples
    --------
    >>> check_outputs({"-o": Path("d.pfm"), "--png": Path("./d.pfm")})
    Traceback (most recent call last):
    ...
    ValueError: -o d.pfm and --png d.pfm are the same file: give each output its own path
    """
    outputs = [(option, Path(path)) for option, path in outputs.items() if path is not None]
    inputs = [(name, Path(path)) for name, path in (inputs or {}).items() if path is not None]
    for option, path in outputs:
        for name, source in inputs:
            if same_file(path, source):
                raise ValueError(f"{option} {path} is the same file as the input {name} "
                                 f"{source}: choose another output path")
    for i, (option, path) in enumerate(outputs):
        for other, earlier in outputs[:i]:
            if same_file(path, earlier):
                raise ValueError(f"{other} {earlier} and {option} {path} are the same file: "
                                 "give each output its own path")
    for option, path in outputs:
        check_output_files(path)
        suffixes, words = (formats or {}).get(option, ((), ""))
        if suffixes and path.suffix.lower() not in suffixes:
            found = f"unsupported extension '{path.suffix}'" if path.suffix else "no extension"
            raise ValueError(f"{option} {path}: {found}; {option} writes {words}")


def check_range_formats(outputs: Mapping[str, Path | None], min_disp: int, ndisp: int) -> None:
    """Fail before matching if a 16-bit PNG map (``-o d.png``, ``--kitti-png``) cannot hold the
    searched disparities ``min_disp .. min_disp + ndisp - 1`` (:data:`PNG_DISPARITIES`): it
    would write 0 (invalid) where the map has values, and the range is known before the run.
    Other options and formats (the float maps, the colour ``--png``) take any range.

    Raises ``ValueError`` (one line naming the option and a format that holds the range).

    Examples
    --------
    >>> check_range_formats({"-o": Path("neg.png")}, -80, 64)
    Traceback (most recent call last):
    ...
    ValueError: -o neg.png: a 16-bit PNG holds disparities 0 to 255.99 (round(d * 256), 0 = invalid), and this run searches -80..-17: write the map as .pfm, .npy or .tif (float32), which hold any disparity
    """
    low, high = int(min_disp), int(min_disp) + int(ndisp) - 1
    if ndisp < 1 or PNG_DISPARITIES[0] <= low and high <= PNG_DISPARITIES[1]:
        return  # a bad ndisp is the matcher's to report
    advice = {"-o": "write the map as .pfm, .npy or .tif (float32), which hold any disparity",
              "--kitti-png": "write the map with -o OUT.pfm (.npy, .tif) instead"}
    for option, path in outputs.items():
        if option in advice and path is not None and Path(path).suffix.lower() == ".png":
            raise ValueError(f"{option} {path}: a 16-bit PNG holds disparities 0 to 255.99 "
                             f"(round(d * 256), 0 = invalid), and this run searches "
                             f"{low}..{high}: {advice[option]}")


def write_disparity_map(path: Path, disparity: np.ndarray, *, suffix: str) -> None:
    """Write a float32 ``(H, W)`` disparity map to ``path`` (a temporary file) in the format of
    ``suffix``: KITTI's 16-bit PNG (``round(d * 256)``, 0 = invalid) for ``.png``, else
    :func:`sswjax.data.io.write_float_map` (``.pfm``, ``.npy``, ``.tif``, ``.tiff``)."""
    if suffix.lower() == ".png":
        write_scaled_disparity(path, disparity, scale=256, atomic=False)
    else:
        write_float_map(path, disparity, suffix=suffix, atomic=False)


def disparity_writers(disparity: np.ndarray, output: Path | None, png: Path | None, ndisp: int,
                      *, min_disp: int = 0) -> dict[Path, Writer]:
    """The writers of a float32 ``(H, W)`` map as ``output`` (by its extension,
    :func:`write_disparity_map`) and as a colour PNG (either may be None); the PNG's colours
    span the searched range ``min_disp .. min_disp + ndisp - 1``."""
    writers: dict[Path, Writer] = {}
    if output is not None:
        writers[output] = lambda tmp: write_disparity_map(tmp, disparity, suffix=output.suffix)
    if png is not None:
        writers[png] = lambda tmp: write_disparity_png(tmp, disparity, vmin=min_disp,
                                                       vmax=min_disp + ndisp - 1, atomic=False)
    return writers


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
