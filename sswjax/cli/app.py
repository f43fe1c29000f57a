"""The ``sswjax`` command line: ``match``, ``demo``, ``evaluate``, ``download``, ``params``,
``rectify``, ``search`` and ``warmup``.

Errors in the user's input (files, sizes, parameters, memory) print one line on stderr and
exit with status 2; ``--debug`` shows the traceback instead. Every output is written to a
temporary file and renamed into place, so an existing file survives a failed run. Ctrl-C exits
with status 130; ``sswjax evaluate -o DIR`` writes each scene as soon as it is done, and its
``--resume`` continues an interrupted run without recomputing the finished scenes.
"""

from __future__ import annotations

import argparse
import sys

from sswjax._files import first_line
from sswjax.cli.common import (EXIT_INTERRUPTED, EXIT_USAGE, Interrupted, Parser,
                               remembered_interrupts)
from sswjax.cli.demo import add_demo_command
from sswjax.cli.download import add_download_command
from sswjax.cli.evaluate import add_evaluate_command
from sswjax.cli.match import add_match_command
from sswjax.cli.params import add_params_command
from sswjax.cli.rectify import add_rectify_command
from sswjax.cli.search import add_search_command
from sswjax.cli.warmup import add_warmup_command
from sswjax.runtime.compilation import enable_compilation_cache, repairing_cache
from sswjax.runtime.memory import MemoryEstimateError

__all__ = ["USER_ERRORS", "build_parser", "main"]

USER_ERRORS = (ValueError, OSError, MemoryEstimateError)
"""What bad input raises (``ConfigError`` and ``InputError`` are ``ValueError``\\ s): one line,
exit status 2. Anything else is a bug and shows its traceback."""


def build_parser() -> argparse.ArgumentParser:
    """The parser of every sub-command; each sets ``run`` (a function of the parsed args)."""
    parser = Parser(prog="sswjax", description="Segment-Side-Window stereo matching in JAX.")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    parser.add_argument("--no-cache", action="store_true",
                        help="do not use the persistent compilation cache ($SSWJAX_CACHE_DIR, "
                             "default ~/.cache/sswjax/xla)")
    commands = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for add in (add_match_command, add_demo_command, add_evaluate_command,
                add_download_command, add_params_command, add_rectify_command, add_search_command,
                add_warmup_command):
        add(commands)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit status (0, 2 for bad input, 130 on Ctrl-C).

    Examples
    --------
    >>> main(["params", "--preset", "paper", "-o", "paper.json"])   # doctest: +SKIP
    wrote paper.json
    0
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser().parse_args(argv)
    args.argv = argv
    cache = None if args.no_cache else enable_compilation_cache()
    try:
        with repairing_cache(cache), remembered_interrupts():
            return args.run(args)
    except USER_ERRORS as error:
        if args.debug:
            raise
        print(f"sswjax: error: {first_line(error)}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt as interrupt:
        print(f"sswjax: {interrupt if isinstance(interrupt, Interrupted) else 'interrupted'}",
              file=sys.stderr)
        return EXIT_INTERRUPTED
