"""The parameter options and the execution-plan options of the commands.

Parameters: ``--preset NAME`` (default the ``accurate`` preset) and ``--params FILE``, which
fills what it leaves out from the preset, then every ``--set PATH=VALUE`` in order, through :meth:`sswjax.config.Params.replace`:
``PATH`` a stage (the value a kind name, or ``none`` / ``null`` to turn an optional stage off;
a JSON object sets several options) or ``stage.option``; ``VALUE`` is read as JSON when it
parses (numbers, ``true``, ``false``, ``null``), else as text. The result is validated with
:func:`sswjax.config.check_params`. Every name in the help comes from the registry
(:data:`sswjax.config.SLOTS`, :func:`sswjax.config.kinds`, :data:`sswjax.config.PRESETS`).

Execution plan: ``--strip-rows``, ``--strip-overlap``, ``--disparity-chunk`` and ``--tile``,
into the :class:`sswjax.ExecutionPlan` of the run;
``--workers N`` and ``--scheduler ADDR`` say where it runs (a Dask cluster,
:mod:`sswjax.cli.distributed`).
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Mapping, Sequence
from pathlib import Path

from sswjax.config import (
    DEFAULT_PRESET,
    PRESETS,
    SLOTS,
    ConfigError,
    Params,
    check_params,
    default_params,
    kinds,
    load_params,
    preset,
)
from sswjax.config.fields import option_fields
from sswjax.config.validate import check_value
from sswjax.runtime.buckets import ShapeBuckets
from sswjax.runtime.plan import ExecutionPlan, check_plan

__all__ = ["PLAN_OPTIONS", "add_parameter_options", "add_plan_options", "apply_settings",
           "params_from_args", "plan_from_args", "setting"]

PLAN_OPTIONS = {name: "--" + name.replace("_", "-")
                for name in ("strip_rows", "strip_overlap", "disparity_chunk", "tile")}
"""Execution plan field -> its command-line option (``strip_rows`` -> ``--strip-rows``)."""

_OFF = ("none", "null")


def _escape(text: str) -> str:
    """Help text as argparse formats it (``%`` is its placeholder)."""
    return text.replace("%", "%%")


class _Setting(tuple):
    """One ``--set``'s ``(PATH, value)``; ``text`` is the ``PATH=VALUE`` typed, which its
    errors echo (JSON reads ``1e400`` as infinity)."""

    text: str


def setting(text: str) -> tuple[str, object]:
    """argparse type of ``--set``: ``"PATH=VALUE"`` -> ``(PATH, value)``, the value read as
    JSON when it parses, else the text itself (the text typed kept for the errors).

    Examples
    --------
    >>> setting("optimizer.p2=1.2"), setting("fill=vote"), setting("checks=null")
    (('optimizer.p2', 1.2), ('fill', 'vote'), ('checks', None))
    """
    path, equals, value = text.partition("=")
    path = path.strip()
    if not equals or not path:
        raise argparse.ArgumentTypeError(f"expected PATH=VALUE (a stage or stage.option), "
                                         f"got {text!r}")
    try:
        parsed = _Setting((path, json.loads(value)))
    except ValueError:
        parsed = _Setting((path, value))
    parsed.text = text
    return parsed


def _kind_example() -> str:
    """A ``STAGE=KIND`` that the default preset accepts as it is (a kind that needs another
    stage would fail for a user who copies it): the last stage with a choice, its last kind
    that validates."""
    base = default_params()
    for slot in reversed([name for name in SLOTS if len(kinds(name)) > 1]):
        for kind in reversed(kinds(slot)):
            if getattr(base, slot) is not None and getattr(base, slot).kind == kind:
                continue  # already the preset's: shows nothing
            try:
                check_params(base.replace(**{slot: {"kind": kind}}))
            except ValueError:
                continue
            return f"{slot}={kind}"
    return f"{next(iter(SLOTS))}=none"


def _set_help() -> str:
    """``--set`` help from the registry: the stages in order with their kinds."""
    stages = "; ".join(
        f"{name}: {', '.join((['none'] if slot.optional else []) + list(kinds(name)))}"
        for name, slot in SLOTS.items())
    examples = [_kind_example()]
    for name, config in default_params().stages():
        traced = [] if config is None else [field for field, spec in option_fields(config)
                                            if not spec.static]
        if traced:
            examples.append(f"{name}.{traced[0]}={getattr(config, traced[0]):.3g}")
            break
    return _escape(
        "change a stage or an option on top of the preset or file (repeatable, in order): "
        "STAGE=KIND, STAGE=none to turn an optional stage off, or STAGE.OPTION=VALUE; VALUE is "
        "read as JSON when it parses (numbers, true, false, null, objects), else as text; e.g. "
        f"{', '.join(examples)}. Stages and kinds: {stages}. Every option, its values and "
        "default: sswjax params --list")


def add_parameter_options(parser: argparse.ArgumentParser, what: str = "the") -> None:
    """Add ``--preset NAME`` | ``--params FILE`` and the repeatable ``--set PATH=VALUE``."""
    group = parser  # both: --preset fills what --params leaves out
    presets = "; ".join(f"{name}: {entry.summary}" for name, entry in PRESETS.items())
    group.add_argument("--preset", choices=list(PRESETS),
                       help=_escape(f"{what} parameters by name (default: {DEFAULT_PRESET}). "
                                    f"{presets}"))
    group.add_argument("--params", type=Path, metavar="FILE",
                       help=f"{what} parameters from a JSON file (sswjax params -o FILE writes "
                            "one to edit); what the file leaves out comes from --preset "
                            f"(default: {DEFAULT_PRESET})")
    parser.add_argument("--set", action="append", default=[], type=setting,
                        metavar="PATH=VALUE", dest="settings", help=_set_help())


def _slot_value(slot: str, value):
    """What ``--set SLOT=VALUE`` gives :meth:`Params.replace`: None, or options with a kind."""
    if value is None or (isinstance(value, str) and value.lower() in _OFF):
        return None
    if isinstance(value, str):
        return {"kind": value}
    listed = ", ".join((["none"] if SLOTS[slot].optional else []) + list(kinds(slot)))
    if isinstance(value, Mapping):
        if not isinstance(value.get("kind", ""), str):  # a list would fail unhashable
            raise ConfigError(slot, f"stage {slot}: \"kind\" must be one of "
                              f"{', '.join(kinds(slot))}, got {value['kind']!r}")
        return value
    raise ConfigError(slot, f"stage {slot} takes a kind ({listed}) or a JSON object of its "
                      f"options, got {value!r}")


def apply_settings(params: Params, settings: Sequence[tuple[str, object]]) -> Params:
    """``params`` with every ``--set`` applied in order, validated.

    Raises :class:`~sswjax.config.ConfigError` (a ``ValueError``, one line naming the
    ``--set``) for an unknown stage, kind or option, or a value the option does not take.

    Examples
    --------
    >>> p = apply_settings(preset("accurate"), [("fill", "background"), ("optimizer.p2", 1.0)])
    >>> p.fill.kind, p.optimizer.p2
    ('background', 1.0)
    """
    for item in settings:
        path, value = item
        typed = getattr(item, "text", None)  # what the user typed, from the command line
        where = f"--set {typed}" if typed is not None else \
            f"--set {path}={json.dumps(value) if not isinstance(value, str) else value}"
        if path in PLAN_OPTIONS:
            raise ConfigError(path, f"{where}: {path} is how a call runs, not a parameter: "
                              f"use {PLAN_OPTIONS[path]} of sswjax match")
        if path not in SLOTS and "." not in path:
            raise ConfigError(path, f"{where}: unknown parameter {path!r}: name a stage "
                              f"({', '.join(SLOTS)}) or STAGE.OPTION (sswjax params --list)")
        try:
            params = _applied(params, path, value)
        except ConfigError as error:
            raise ConfigError(error.path, f"{where}: {error}") from None
    return check_params(params)


def _applied(params: Params, path: str, value) -> Params:
    """``params`` with one ``--set``; the options it names checked one by one and stored in
    their canonical type (a JSON integer given to a traced option becomes a float)."""
    if path in SLOTS:
        params = params.replace(**{path: _slot_value(path, value)})
        named = [f"{path}.{name}" for name in value if name != "kind"] \
            if isinstance(value, Mapping) else []
    else:
        params = params.replace(**{path: value})
        named = [path]
    for option in named:
        slot, _, name = option.partition(".")
        config = getattr(params, slot)
        canonical = check_value(option, dict(option_fields(config))[name], getattr(config, name))
        params = params.replace(**{option: canonical})
    return params


def params_from_args(args: argparse.Namespace) -> Params:
    """The parameters a command asked for: ``--params FILE`` (:func:`sswjax.config.load_params`,
    what it leaves out from ``--preset NAME`` or the default preset), else ``--preset NAME``,
    else the default preset; then the ``--set`` changes."""
    if getattr(args, "params", None) is not None:
        params = load_params(args.params, base=getattr(args, "preset", None))
    else:
        name = getattr(args, "preset", None)
        params = default_params() if name is None else preset(name)
    return apply_settings(params, getattr(args, "settings", []))


def _count(text: str) -> int:
    """argparse type of the plan options: an integer >= 0."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {text!r}")
    return value


def _positive(text: str) -> int:
    """argparse type of ``--workers``: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {text!r}")
    return value


def add_plan_options(parser: argparse.ArgumentParser) -> None:
    """Add ``--strip-rows N``, ``--strip-overlap N``, ``--disparity-chunk K``, ``--tile SIZE``,
    ``--no-carry-paths``, ``--workers N`` and ``--scheduler ADDR``."""
    defaults = ExecutionPlan()
    parser.add_argument("--strip-rows", type=_count, metavar="N",
                        help="match in horizontal strips of N rows: memory follows the strip "
                             "(default 0: the whole image, in strips only if it does not fit)")
    parser.add_argument("--strip-overlap", type=_count, metavar="N",
                        help="rows of context above and below each strip (default "
                             f"{defaults.strip_overlap})")
    parser.add_argument("--disparity-chunk", type=_count, metavar="K",
                        help="build and fold the cost volume K disparities at a time, 0 for "
                             f"the whole volume at once; the same map (default "
                             f"{defaults.disparity_chunk})")
    parser.add_argument("--tile", type=_count, metavar="SIZE",
                        help="match in tiles of SIZE x SIZE pixels, each seen with the collar "
                             "(--strip-overlap) and ndisp more columns either side: memory "
                             "follows the tile; with --workers or --scheduler the tiles of one "
                             "pair are the cluster's tasks (default: tiles or strips only if "
                             "the pair does not fit)")
    parser.add_argument("--no-carry-paths", action="store_true",
                        help="in strips, start each strip's semi-global paths afresh at its "
                             "edges (one sweep) instead of handing them on from strip to "
                             "strip (two sweeps, the whole image's map)")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--workers", type=_positive, metavar="N",
                       help="run on a Dask cluster of N single-threaded worker processes "
                            "started on this machine, each on a core of its own (without "
                            "--workers one process uses every core): the pairs of two "
                            "folders, or the tiles "
                            'of one pair, are its tasks (pip install "sswjax[distributed]")')
    where.add_argument("--scheduler", metavar="ADDR",
                       help="run on the running Dask cluster whose scheduler is ADDR (e.g. "
                            "tcp://host:8786; dask scheduler / dask worker, dask-jobqueue): "
                            "inputs and outputs on storage its workers share")


def plan_from_args(args: argparse.Namespace, *,
                   buckets: ShapeBuckets | None = None) -> ExecutionPlan:
    """The execution plan of a run: the plan options given on the command line, with
    ``buckets``; ``--tile`` and ``--strip-rows`` together are refused in one line.

    Examples
    --------
    >>> args = argparse.Namespace(strip_rows=64, strip_overlap=None, disparity_chunk=None)
    >>> plan_from_args(args)[:2]
    (64, 96)
    """
    values = {name: getattr(args, name) for name in PLAN_OPTIONS
              if getattr(args, name, None) is not None}
    if values.get("tile") and values.get("strip_rows"):
        raise ValueError(f"--tile {values['tile']} and --strip-rows {values['strip_rows']} both "
                         "cut the pair: give one")
    if getattr(args, "no_carry_paths", False):
        values["carry_paths"] = False
    return check_plan(ExecutionPlan(**values, buckets=buckets))
