"""``sswjax params``: the parameters as nested JSON, and the catalogue of every stage.

``sswjax params [--preset NAME] [--params FILE] [--set PATH=VALUE ...] [-o FILE]`` prints (or
writes atomically, :func:`sswjax.config.save_params`) the parameters those options give, in
the nested form that ``--params FILE`` reads back: a file to edit. ``sswjax params --list``
prints every stage (slot) in pipeline order with its kinds (the registered part classes) and
each kind's options: static or traced, the values allowed, the default and what it does. All
of it is read from the registry and the options' declarations (:mod:`sswjax.config.parts`,
:mod:`sswjax.config.fields`), so a part registered at run time is listed like the others.
``sswjax params --upgrade OLD.json [-o NEW.json [--overwrite]]`` converts a file of the old flat
names (:mod:`sswjax.cli.upgrade`) into the nested form; what it leaves out is noted on stderr.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from sswjax.cli.common import check_outputs
from sswjax.cli.options import add_parameter_options, params_from_args
from sswjax.cli.upgrade import upgrade_file
from sswjax._files import atomic_output
from sswjax.config import DEFAULT_PRESET, SLOTS, Params, default_params, kinds
from sswjax.config.fields import default_of, option_fields
from sswjax.config.serialize import FORMAT

__all__ = ["add_params_command", "catalogue", "document", "run_params"]


def add_params_command(commands) -> None:
    """Add the ``params`` sub-command to ``commands`` (argparse's sub-parsers)."""
    parser = commands.add_parser(
        "params", help="print or write parameters as nested JSON (a file to edit for --params); "
                       "--list: every stage, its kinds and their options")
    parser.add_argument("--list", action="store_true",
                        help="list every stage in pipeline order, the kinds that can fill it "
                             "and each kind's options (static or traced, values, default)")
    parser.add_argument("--upgrade", type=Path, metavar="OLD",
                        help="convert OLD, a parameter file of the old flat names "
                             "({\"static\": ..., \"dynamic\": ...}), into the nested form; "
                             "what the nested form leaves out is noted on stderr")
    add_parameter_options(parser, "the")
    parser.add_argument("-o", "--output", type=Path, metavar="FILE",
                        help="write the JSON to FILE (atomically) instead of printing it; "
                             "'-o -' prints it")
    parser.add_argument("--overwrite", action="store_true",
                        help="with --upgrade: replace an existing -o FILE")
    parser.set_defaults(run=run_params)


def _shown(value, static: bool) -> str:
    """A default as :meth:`Option.describe` writes values: ``true``, ``7``, ``'slice'``; traced
    floats shortened to 6 digits."""
    if not static:
        return f"{float(value):.6g}"
    return json.dumps(value) if isinstance(value, bool) else repr(value)


def catalogue() -> str:
    """The text of ``sswjax params --list``: stages, kinds and options, from the registry.

    Examples
    --------
    >>> text = catalogue()
    >>> all(f"{slot} (" in text for slot in SLOTS)
    True
    """
    defaults = default_params()
    lines = [f"Stages in pipeline order, the kinds that can fill each and their options; "
             f"'{DEFAULT_PRESET}' is the default preset. Change them with --set STAGE=KIND, "
             "--set STAGE=none (optional stages) or --set STAGE.OPTION=VALUE. Static options "
             "fix the compiled graph (changing one recompiles); traced options are numbers "
             "the graph takes as inputs (and the search tunes)."]
    for name, slot in SLOTS.items():
        current = getattr(defaults, name)
        chosen = "none" if current is None else current.kind
        lines += ["", f"{name} ({'optional' if slot.optional else 'required'}; "
                      f"{DEFAULT_PRESET}: {chosen}): {slot.summary}"]
        for kind, cls in kinds(name).items():
            lines.append(f"  {kind}: {cls.summary()}")
            fields = option_fields(cls)
            if not fields:
                lines.append("      (no options)")
            width = max((len(f"{name}.{field}") for field, _ in fields), default=0)
            for field, spec in fields:
                lines.append(f"      {f'{name}.{field}':<{width}}  "
                             f"{'static' if spec.static else 'traced'}  {spec.describe()}, "
                             f"default {_shown(default_of(cls, field), spec.static)}: "
                             f"{spec.help}")
    return "\n".join(lines)


def _provenance(args: argparse.Namespace) -> dict:
    """Where the parameters came from: the preset, the file (on the preset when one is given),
    and the ``--set`` changes."""
    source = ({"params": str(args.params)} if args.params is not None else
              {"preset": args.preset or DEFAULT_PRESET})
    if args.params is not None and args.preset is not None:
        source["preset"] = args.preset
    settings = [f"{path}={value if isinstance(value, str) else json.dumps(value)}"
                for path, value in args.settings]
    return {**source, **({"set": settings} if settings else {}), "written_by": "sswjax params"}


def document(params: Params, provenance: dict | None = None) -> dict:
    """The nested JSON object of ``params``, as :func:`sswjax.config.save_params` writes it."""
    data = {"format": FORMAT, **params.to_dict()}
    if provenance is not None:
        data["provenance"] = dict(provenance)
    return data


def _write(document: dict, output: Path | None) -> None:
    """Print ``document`` (``output`` None) or write it to ``output`` atomically."""
    if output is None:
        print(json.dumps(document, indent=2))
        return
    with atomic_output(output) as tmp:
        Path(tmp).write_text(json.dumps(document, indent=2) + "\n", encoding="utf-8")
    print(f"wrote {output}")


def _upgrade(args: argparse.Namespace, output: Path | None) -> int:
    """``sswjax params --upgrade OLD [-o NEW]``."""
    given = [option for option, value in (("--preset", args.preset), ("--params", args.params),
                                          ("--set", args.settings)) if value]
    if given:
        raise ValueError(f"--upgrade converts a file as it is: it takes no {given[0]}")
    check_outputs({"-o": output}, {"--upgrade": args.upgrade})
    if output is not None and output.exists() and not args.overwrite:
        raise ValueError(f"-o {output} exists: give --overwrite to replace it")
    document, notes = upgrade_file(args.upgrade)
    for note in notes:
        print(f"sswjax: note: {args.upgrade}: {note}", file=sys.stderr)
    _write(document, output)
    return 0


def run_params(args: argparse.Namespace) -> int:
    """``sswjax params``; returns the exit status (0)."""
    if args.list:
        given = [option for option, value in (("--preset", args.preset), ("--params", args.params),
                                              ("--set", args.settings), ("-o", args.output),
                                              ("--upgrade", args.upgrade)) if value]
        if given:
            raise ValueError(f"--list prints the catalogue of stages: it takes no {given[0]}")
        print(catalogue())
        return 0
    output = None if args.output == Path("-") else args.output
    if args.upgrade is not None:
        return _upgrade(args, output)
    if args.overwrite:
        raise ValueError("--overwrite goes with --upgrade (sswjax params -o replaces its file)")
    check_outputs({"-o": output}, {"--params": args.params})
    params = params_from_args(args)
    _write(document(params, _provenance(args)), output)
    return 0
