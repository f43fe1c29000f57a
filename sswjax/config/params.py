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
from sswjax.config.checks import LeftRightCheck
from sswjax.config.coarse import CoarseToFine
from sswjax.config.cost import MatchingCost
from sswjax.config.fields import ConfigError, as_float, is_config, option_fields, stage_config
from sswjax.config.fill import BackgroundFill, Fill
from sswjax.config.optimizer import Optimizer
from sswjax.config.parts import SLOTS, kinds
from sswjax.config.preprocess import Preprocessor
from sswjax.config.refinement import SideWindowMedian
from sswjax.config.segments import Slic
from sswjax.config.selection import WinnerTakesAll
from sswjax.config.smoothing import GatedBilateralSmoothing

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
        """A copy with some stages or options changed, applied in the order given.

        Keys are
        * a slot (``fill``) given a configuration instance, or ``None`` (the stage off);
        * a slot given a kind's name (``fill="vote"``) or a mapping of options, with or without
          ``"kind"`` (``fill={"kind": "vote", "step": 2}``, ``fill={"step": 2}``): a name is
          the mapping ``{"kind": name}``, and both follow one rule: the slot's current kind
          (or no kind named) changes the options given of the current configuration; another
          kind starts from that kind's defaults;
        * a dotted option (``"optimizer.p2"``, passed as ``**{"optimizer.p2": 1.2}``).

        Values are not validated here (:func:`sswjax.config.validate.check_params` does);
        unknown stages, kinds and options are refused with a one-line ``ConfigError``. Files of
        the old flat names (``fill_radius``, ``sgm_p2``) convert with ``sswjax params --upgrade``.

        Examples
        --------
        >>> from sswjax.config import preset
        >>> finest = preset("finest")
        >>> finest.replace(fill="vote") == finest.replace(fill={"kind": "vote"})
        True
        >>> finest.replace(fill="vote").fill.band_fit     # another kind: its defaults
        0
        >>> finest.replace(fill="wmedian") == finest      # the same kind: kept as it is
        True
        >>> p = Params().replace(aggregation={"kind": "gf", "radius": 5}).replace(fill="vote")
        >>> p.aggregation.radius, p.fill.kind
        (5, 'vote')
        """
        result = self
        for key, value in changes.items():
            if key in SLOTS:
                result = dataclasses.replace(result, **{key: _slot_value(result, key, value)})
            elif "." in key:
                result = _set_option(result, key, value)
            else:
                raise ConfigError(key, f"unknown parameter {key!r}: name a stage "
                                  f"({', '.join(SLOTS)}) or \"stage.option\"")
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


def _slot_value(params: Params, slot: str, value):
    """What ``replace(slot=value)`` puts in the slot (a configuration or None)."""
    if value is None:
        if not SLOTS[slot].optional:
            raise ConfigError(slot, f"stage {slot} cannot be None")
        return None
    if isinstance(value, str):
        value = {"kind": value}
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
