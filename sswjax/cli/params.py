"""``sswjax params``: the parameters as nested JSON, and the catalogue of every stage.

``sswjax params [--preset NAME] [--params FILE] [--set PATH=VALUE ...] [-o FILE]`` prints (or
writes atomically, :func:`sswjax.config.save_params`) the parameters those options give, in
the nested form that ``--params FILE`` reads back: a file to edit. ``sswjax params --list``
prints every stage (slot) in pipeline order with its kinds (the registered part classes) and
each kind's options: static or traced, the values allowed, the default and what it does. All
of it is read from the registry and the options' declarations (:mod:`sswjax.config.parts`,
:mod:`sswjax.config.fields`), so a part registered at run time is listed like the others.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from sswjax.cli.common import check_outputs
from sswjax.cli.options import (PLAN_OPTIONS, add_parameter_options, chosen_execution,
                                params_from_args)
from sswjax.config import DEFAULT_PRESET, SLOTS, Params, default_params, kinds, save_params
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
    add_parameter_options(parser, "the")
    parser.add_argument("-o", "--output", type=Path, metavar="FILE",
                        help="write the JSON to FILE (atomically) instead of printing it; "
                             "'-o -' prints it")
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


def run_params(args: argparse.Namespace) -> int:
    """``sswjax params``; returns the exit status (0)."""
    if args.list:
        given = [option for option, value in (("--preset", args.preset), ("--params", args.params),
                                              ("--set", args.settings), ("-o", args.output))
                 if value]
        if given:
            raise ValueError(f"--list prints the catalogue of stages: it takes no {given[0]}")
        print(catalogue())
        return 0
    output = None if args.output == Path("-") else args.output
    check_outputs({"-o": output}, {"--params": args.params})
    params, execution = params_from_args(args)
    execution = chosen_execution(execution)
    if execution:
        listed = ", ".join(f"{name}={value!r}" for name, value in execution.items())
        options = " ".join(f"{PLAN_OPTIONS[name]} {value}" for name, value in execution.items())
        print(f"sswjax: note: {listed} in {args.params} is how a call runs, not a parameter: "
              f"left out; pass {options} to sswjax match", file=sys.stderr)
    provenance = _provenance(args)
    if output is None:
        print(json.dumps(document(params, provenance), indent=2))
        return 0
    save_params(output, params, provenance=provenance)
    print(f"wrote {output}")
    return 0
