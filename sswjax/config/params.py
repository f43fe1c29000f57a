"""The root of the configuration: one stage configuration per slot, one JAX pytree.

``Params`` holds one configuration per stage of :data:`sswjax.config.parts.SLOTS`, in pipeline
order; an optional stage that is off is ``None``. The pytree's leaves are the traced options of
every stage (weights, truncations, penalties, tolerances): ``jit`` traces them, ``grad``
differentiates them, the optax search moves them. The static options and the choice of parts
are its structure: changing one recompiles. How a call is executed (strips, shape buckets,
disparity blocks) is not here: that is :class:`sswjax.runtime.plan.ExecutionPlan`.

Units: image intensities are in [0, 1], so truncations are fractions of the full intensity
range; disparities are in pixels.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Mapping

from sswjax.config.aggregation import Aggregator, SideWindowAggregation
from sswjax.config.alignment import VerticalAlignment
from sswjax.config.band import DisparityBand
from sswjax.config.cost import MatchingCost, Preprocessor, Slic
from sswjax.config.fields import ConfigError, as_float, is_config, option_fields, stage_config
from sswjax.config.fill import BackgroundFill, Fill
from sswjax.config.legacy import (EXECUTION_DEFAULTS, NEWER_OPTIONS, NEWER_SLOTS, from_flat,
                                  old_names, to_flat, translate, unused_error)
from sswjax.config.optimizer import Optimizer
from sswjax.config.parts import SLOTS, kinds
from sswjax.config.refinement import CoarseToFine, GatedBilateralSmoothing, SideWindowMedian
from sswjax.config.selection import LeftRightCheck, WinnerTakesAll

__all__ = ["Params"]


@stage_config
class Params:
    """All the parameters of the method: one configuration per stage, in pipeline order.

    ``Params()`` is the paper's method (the ``paper`` preset); :func:`sswjax.preset` gives the
    others. Change it with :meth:`replace`.

    Examples
    --------
    >>> from sswjax import Params
    >>> p = Params()
    >>> p.aggregation.radius, p.optimizer is None
    (4, True)
    >>> q = p.replace(**{"cost.census_weight": 0.5, "aggregation.radius": 6})
    >>> (q.cost.census_weight, q.aggregation.radius)
    (0.5, 6)
    >>> p.replace(fill="vote").fill.kind                 # a part by its name
    'vote'
    """

    alignment: VerticalAlignment | None = None
    preprocess: Preprocessor | None = None
    cost: MatchingCost = dataclasses.field(default_factory=MatchingCost)
    segments: Slic | None = dataclasses.field(default_factory=Slic)
    aggregation: Aggregator = dataclasses.field(default_factory=SideWindowAggregation)
    optimizer: Optimizer | None = None
    selection: WinnerTakesAll = dataclasses.field(default_factory=WinnerTakesAll)
    checks: LeftRightCheck | None = dataclasses.field(default_factory=LeftRightCheck)
    fill: Fill | None = dataclasses.field(default_factory=BackgroundFill)
    refinement: SideWindowMedian | None = dataclasses.field(default_factory=SideWindowMedian)
    coarse: CoarseToFine | None = None
    band: DisparityBand | None = None
    smoothing: GatedBilateralSmoothing | None = None

    def stages(self) -> Iterator[tuple[str, object]]:
        """``(slot, configuration or None)`` of every stage, in pipeline order."""
        return ((name, getattr(self, name)) for name in SLOTS)

    def replace(self, **changes) -> Params:
        """A copy with some stages or options changed.

        Keys are
        * a slot (``fill``): a configuration instance, ``None`` (the stage off), or a mapping of
          options for the slot's current part (with ``"kind"``: a new part with those options);
        * a dotted option (``"optimizer.p2"``, passed as ``**{"optimizer.p2": 1.2}``);
        * an old flat name (``census_weight``, ``fill_radius``; a slot given a string, such as
          ``fill="vote"``, is the old switch): read as :mod:`sswjax.config.legacy` reads them,
          keeping the options the old names shared.

        Values are not validated here (:func:`sswjax.config.validate.check_params` does);
        unknown names, kinds and options are refused with a one-line ``ConfigError``.
        """
        flat = {key: value for key, value in changes.items()
                if key in old_names() and not (key in SLOTS and not isinstance(value, str))}
        result = _replace_flat(self, flat) if flat else self
        for key, value in changes.items():
            if key in flat:
                continue
            if key in SLOTS:
                result = dataclasses.replace(result, **{key: _slot_value(result, key, value)})
            elif "." in key:
                result = _set_option(result, key, value)
            else:
                raise ConfigError(key, f"unknown parameter {key!r}")
        return result

    def to_dict(self) -> dict:
        """The nested JSON-able form: slot -> ``None`` or ``{"kind": ..., option: value}``
        (traced options as floats; ``kind`` for interchangeable slots only)."""
        out = {}
        for name, config in self.stages():
            if config is None:
                out[name] = None
                continue
            entry = {"kind": config.kind} if SLOTS[name].interchangeable else {}
            for field, spec in option_fields(config):
                value = getattr(config, field)
                entry[field] = value if spec.static else float(value)
            out[name] = entry
        return out


def _replace_flat(params: Params, flat: Mapping) -> Params:
    """``params`` with old flat names changed, as the flat code changed them."""
    execution = sorted(set(flat) & set(EXECUTION_DEFAULTS))
    if execution:
        raise ConfigError(execution[0], f"{execution[0]} is how a call runs, not a parameter: "
                          f"pass plan=sswjax.ExecutionPlan({execution[0]}=...) to sswjax.match")
    try:
        slots = dict(params.stages())
        newer = {slot: slots.pop(slot) for slot in NEWER_SLOTS}
        reading = from_flat({**to_flat(slots), **flat}, explicit=flat)
    except ConfigError as error:
        raise translate(error) from None
    if reading.unused:
        raise unused_error(reading.unused)
    slots = {**reading.slots, **newer}
    for slot, field in NEWER_OPTIONS:  # kept where the stage kept its kind
        before, after = getattr(params, slot), slots[slot]
        if before is not None and after is not None and before.kind == after.kind:
            slots[slot] = after.replace(**{field: getattr(before, field)})
    return Params(**slots)


def _slot_value(params: Params, slot: str, value):
    """What ``replace(slot=value)`` puts in the slot (a configuration or None)."""
    if value is None:
        if not SLOTS[slot].optional:
            raise ConfigError(slot, f"stage {slot} cannot be None")
        return None
    if isinstance(value, Mapping):
        current = getattr(params, slot)
        kind = value.get("kind", None if current is None else current.kind)
        if kind is None and not SLOTS[slot].interchangeable and len(kinds(slot)) == 1:
            kind = next(iter(kinds(slot)))
        if kind is None:
            raise ConfigError(slot, f"stage {slot} is None: name its \"kind\", one of "
                              f"{', '.join(kinds(slot))}")
        if not isinstance(kind, str) or kind not in kinds(slot):
            raise ConfigError(slot, f"unknown {slot} kind {kind!r}; choose from "
                              f"{', '.join(kinds(slot))}")
        base = current if current is not None and current.kind == kind else kinds(slot)[kind]()
        options = {k: v for k, v in value.items() if k != "kind"}
        return _with_options(base, slot, options)
    if not is_config(value) or getattr(type(value), "slot", None) != slot \
            or kinds(slot).get(value.kind) is not type(value):
        raise ConfigError(slot, f"stage {slot} takes a configuration of one of the kinds "
                          f"{', '.join(kinds(slot))}, got {type(value).__name__}")
    return value


def _with_options(config, slot: str, options: Mapping):
    """``config`` with some options changed (a traced option given a Python integer takes it
    as a float); unknown names refused."""
    specs = dict(option_fields(config))
    unknown = sorted(set(options) - set(specs))
    if unknown:
        raise ConfigError(f"{slot}.{unknown[0]}", f"{slot} {config.kind!r} has no option "
                          f"{unknown[0]!r}; its options: {', '.join(specs) or 'none'}")
    return dataclasses.replace(config, **{name: as_float(specs[name], value)
                                          for name, value in options.items()})


def _set_option(params: Params, path: str, value) -> Params:
    """``params`` with the option at ``"slot.option"`` changed."""
    slot, _, name = path.partition(".")
    if slot not in SLOTS:
        raise ConfigError(path, f"unknown parameter {path!r}: {slot!r} is not a stage "
                          f"({', '.join(SLOTS)})")
    config = getattr(params, slot)
    if config is None:
        raise ConfigError(path, f"stage {slot} is None: set it before its option {name!r}")
    return dataclasses.replace(params, **{slot: _with_options(config, slot, {name: value})})


if tuple(field.name for field in dataclasses.fields(Params)) != tuple(SLOTS):
    raise ImportError("Params' fields must be the slots of sswjax.config.parts, in order")
