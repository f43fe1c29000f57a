"""The ``sswjax`` command line: ``match``, ``demo``, ``evaluate``, ``download``, ``params``,
``rectify``, ``search`` and ``warmup``.

Errors in the user's input (files, sizes, parameters, memory) print one line on stderr and
exit with status 2; ``--debug`` shows the traceback instead. Every output is written to a
temporary file and renamed into place, so an existing file survives a failed run. Ctrl-C exits
with status 130; ``sswjax evaluate -o DIR`` writes each scene as soon as it is done, and its
``--resume`` continues an interrupted run without recomputing the finished scenes. A reader
that stops early (``sswjax params --list | head -1``) ends the command quietly with status 141,
as a tool killed by ``SIGPIPE`` reports to the shell (:data:`EXIT_BROKEN_PIPE`). A graph
compiling (seconds, the first time a size, range or parameters are met) is said on stderr,
``sswjax: compiling ...`` then ``sswjax: compiled in 6.2 s`` (the ``sswjax`` logger's ``INFO``
lines, :mod:`sswjax.runtime.executables`), a terminal or not; ``--quiet`` leaves them out.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import importlib
import logging
import os
import sys

from sswjax._files import first_line
from sswjax.cli.common import (EXIT_INTERRUPTED, EXIT_USAGE, Interrupted, Parser,
                               remembered_interrupts)
from sswjax.runtime.compilation import (cache_settings_restored, enable_compilation_cache,
                                        repairing_cache)
from sswjax.runtime.memory import MemoryEstimateError

__all__ = ["COMMANDS", "EXIT_BROKEN_PIPE", "USER_ERRORS", "build_parser", "commands_needed", "console", "main"]

USER_ERRORS = (ValueError, OSError, MemoryEstimateError)
"""What bad input raises (``ConfigError`` and ``InputError`` are ``ValueError``\\ s): one line,
exit status 2. Anything else is a bug and shows its traceback."""


EXIT_BROKEN_PIPE = 141
"""Exit status when the reader of standard output went away (``| head -1``): 128 + SIGPIPE,
what ``yes | head -1`` or ``git log | head -1`` report to the shell, rather than 0: what was
printed is not all of it, and ``set -o pipefail`` sees the same as with any such tool."""


COMMANDS = ("match", "demo", "evaluate", "download", "params", "rectify", "search", "warmup")
"""The sub-commands, in the order ``--help`` lists them. Module ``sswjax.cli.<name>`` defines
``add_<name>_command(subparsers)``, which adds the command's parser and sets its ``run``. A
command line imports only the module of the command it names: ``search`` brings optax,
``evaluate`` its figures and ``download`` its fetcher, about 0.1 s of a ``match``'s start-up
(``docs/notes/speed-and-memory.md``). The modules are named here rather than imported at the top so
that this is so; ``tests/test_architecture.py`` checks each of them as if it were imported."""


def commands_needed(argv: list[str]) -> tuple[str, ...]:
    """The commands whose parsers a command line needs: the one it names, else all of them.

    ``sswjax``'s own options are flags without values, so the first word that is not an option
    is the command. With ``-h`` before it, no command, or an unknown one, every command's parser
    is built, so that the help lists them all and the error names the valid choices.
    """
    for word in argv:
        if word in ("-h", "--help"):
            return COMMANDS
        if not word.startswith("-"):
            return (word,) if word in COMMANDS else COMMANDS
    return COMMANDS


def build_parser(commands: tuple[str, ...] = COMMANDS) -> argparse.ArgumentParser:
    """The parser of the given sub-commands (all by default); each sets ``run`` (a function of
    the parsed args)."""
    parser = Parser(prog="sswjax", description="Segment-Side-Window stereo matching in JAX.")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    parser.add_argument("--quiet", action="store_true",
                        help="do not say on stderr when a graph compiles (sswjax: compiling "
                             "..., then compiled in S s); notes and errors are still shown")
    parser.add_argument("--no-cache", action="store_true",
                        help="do not use the persistent compilation cache ($SSWJAX_CACHE_DIR, "
                             "default $XDG_CACHE_HOME/sswjax/xla, else ~/.cache/sswjax/xla)")
    subparsers = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for name in commands:
        module = importlib.import_module(f"sswjax.cli.{name}")
        getattr(module, f"add_{name}_command")(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit status (0, 2 for bad input, 130 on Ctrl-C, 141
    when the reader of standard output went away). The persistent compilation cache is on
    during the command (unless ``--no-cache``); JAX's cache options are as before when it
    returns.

    Examples
    --------
    >>> main(["params", "--preset", "paper", "-o", "paper.json"])   # doctest: +SKIP
    wrote paper.json
    0
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser(commands_needed(argv)).parse_args(argv)
    args.argv = argv
    with cache_settings_restored():  # a process that goes on (tests, notebooks) keeps its own
        cache = None if args.no_cache else enable_compilation_cache()
        return _run(args, cache)


def _run(args: argparse.Namespace, cache) -> int:
    """The parsed command, with the cache in ``cache`` (a folder, or ``None``: off) repaired
    as it goes; its exit status (:func:`main`)."""
    try:
        with repairing_cache(cache), remembered_interrupts(), _compile_lines(not args.quiet):
            status = args.run(args)
            sys.stdout.flush()  # a reader gone shows here, not in Python's exit
            return status
    except BrokenPipeError:
        return _reader_gone()
    except USER_ERRORS as error:
        if args.debug:
            raise
        print(f"sswjax: error: {first_line(error)}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt as interrupt:
        print(f"sswjax: {interrupt if isinstance(interrupt, Interrupted) else 'interrupted'}",
              file=sys.stderr)
        return EXIT_INTERRUPTED


class _StderrLines(logging.Handler):
    """Each record as a line ``sswjax: MESSAGE`` on the stderr of the moment; through
    ``tqdm.write`` once tqdm is loaded (a progress bar may be there: it is redrawn below the
    line, not cut), without importing it otherwise (start-up time)."""

    def emit(self, record: logging.LogRecord) -> None:
        line = f"sswjax: {record.getMessage()}"
        bars = sys.modules.get("tqdm")
        try:
            if bars is not None:
                bars.tqdm.write(line, file=sys.stderr)
            else:
                print(line, file=sys.stderr, flush=True)
        except Exception:  # noqa: BLE001 - logging's own policy: report, never raise
            self.handleError(record)


@contextlib.contextmanager
def _compile_lines(shown: bool):
    """Within it (``shown``), the ``sswjax`` logger's ``INFO`` lines (a graph compiling, its
    time) go to stderr; the logger is as it was afterwards."""
    if not shown:
        yield
        return
    logger = logging.getLogger("sswjax")
    handler, level = _StderrLines(logging.INFO), logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)


def _reader_gone() -> int:
    """Standard output's reader went away: what is still buffered for it goes to the null
    device (else Python's exit tries again, and prints an error), and nothing is said.
    Returns :data:`EXIT_BROKEN_PIPE`."""
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, sys.stdout.fileno())
    except (OSError, ValueError):  # a stdout without a descriptor (captured): nothing to drop
        pass
    finally:
        os.close(null)
    return EXIT_BROKEN_PIPE


def console() -> int:
    """The console script ``sswjax`` and ``python -m sswjax.cli``: :func:`main`, in a process
    that ends with it.

    The objects the imports made are moved out of the garbage collector's reach first
    (``gc.freeze``): they live as long as the process, and the collections of the run (a trace
    makes many) would scan them each time. The objects the run left are frozen too when it
    ends, so that Python's finalisation does not collect them one by one before the process
    exits: JAX and its compiled graphs leave about 0.2 s of that work, a sixth of a warm
    ``sswjax match`` (``docs/notes/speed-and-memory.md``). Exit handlers and the closing of modules run
    as before; only the freeing of memory that the exit returns anyway is skipped. Not for a
    process that goes on (tests, notebooks): call :func:`main` there.
    """
    gc.freeze()
    try:
        return main()
    finally:
        gc.freeze()
