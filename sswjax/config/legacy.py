"""The flat parameter names of sswjax before the configuration was nested per stage.

Until the per-stage configuration, ``Params`` was one flat set of 53 fields (``fill_radius``,
``sgm_p2``, ``strip_rows``, ...) and its JSON ``{"static": {...}, "dynamic": {...}}``. Those
files (``tuning/params/``, stored runs) still load, and ``Params.replace`` still takes the old
names: this module is the one mapping between the two.

A flat set is read as the old code read it: every name has its old default
(:data:`FLAT_DEFAULTS`), the switches (``preprocess``, ``aggregation``, ``optimizer``, ``fill``,
``lr_check``, ``n_segments``, ``refine_radius``, ``coarse_levels``) choose the stages, and each
stage takes its options from the names that fed it. What the old code ignored silently, an
option of a stage that is not used, is refused when it was given with a value other than its
default (full dumps, which list every name, load as before). ``strip_rows``,
``strip_overlap`` and ``disparity_chunk`` were execution policy: they come back apart
(:data:`EXECUTION_DEFAULTS`), for :class:`sswjax.runtime.plan.ExecutionPlan`.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping
from typing import NamedTuple

from sswjax.config.fields import ConfigError, as_float, check_value, default_of, option_fields
from sswjax.config.parts import SLOTS, kinds

__all__ = ["DYNAMIC_DEFAULTS", "EXECUTION_DEFAULTS", "FLAT_DEFAULTS", "NEWER_OPTIONS",
           "NEWER_SLOTS", "STATIC_DEFAULTS", "FlatReading", "from_flat", "old_names", "to_flat",
           "translate", "unused_error"]

NEWER_SLOTS = ("alignment", "band", "smoothing")
"""Stages added after the flat names: a flat file describes a configuration without them (they
are off), and a change by flat names keeps them as they are."""

NEWER_OPTIONS = (("selection", "fit"), ("coarse", "refit_radius"))
"""Options added after the flat names to stages that have them, as ``(slot, option)``: a flat
file describes them at their defaults, and a change by flat names keeps them as they are."""

STATIC_DEFAULTS: dict = {
    "census_height": 7, "census_width": 9, "n_segments": 2000, "slic_iterations": 10,
    "aggregation_radius": 4, "aggregation_iterations": 3, "aggregation": "ssw",
    "window_selection": "slice", "subpixel": True, "lr_check": True, "fill_radius": 2,
    "refine_radius": 2, "refine_iterations": 2, "optimizer": "none", "sgm_paths": 8,
    "sgm_dtype": "int16", "fill": "background", "fill_weight_radius": 9, "fill_band_fit": 0,
    "vote_step": 4, "fill_source": "filled", "fill_median": "square", "preprocess": "none",
    "lcn_radius": 7, "coarse_levels": 0, "upsample_radius": 1, "uniqueness_gap": 0,
    "uniqueness_radius": 2, "aggregated_lr_gap": 0,
}
"""The old static names (``{"static": {...}}`` of an old file) with their old defaults."""

DYNAMIC_DEFAULTS: dict = {
    "tad_weight": 0.05000000074505806, "gradient_weight": 0.15000000596046448,
    "census_weight": 0.800000011920929, "tad_truncation": 0.04221818596124649,
    "gradient_truncation": 0.015484430827200413, "segment_weight": 0.5996789336204529,
    "slic_compactness": 10.0, "lr_tolerance": 0.0, "sgm_p1": 0.05, "sgm_p2": 0.4,
    "sgm_sigma": 0.05, "sgm_segment_factor": 1.0, "sgm_detail_weight": 1.0,
    "plane_min_support": 0.25, "plane_inlier_scale": 1.0, "lcn_eps": 4 / 255, "fill_eps": 1e-3,
    "fill_quantile": 0.5, "upsample_jump": 3.0, "vote_sigma": 0.2, "vote_tolerance": 2.0,
}
"""The old dynamic names (``{"dynamic": {...}}``) with their old defaults."""

FLAT_DEFAULTS: dict = {**STATIC_DEFAULTS, **DYNAMIC_DEFAULTS}
"""Every old parameter name with its old default (the paper's method, ``Params()``)."""

EXECUTION_DEFAULTS: dict = {"strip_rows": 0, "strip_overlap": 32, "disparity_chunk": 4}
"""The old names that were execution policy, with their defaults."""

# Old name -> (slot, option): where each old option lives in the configuration of its stage.
_OPTIONS: dict[str, tuple[str, str]] = {
    **{name: ("cost", name) for name in ("census_height", "census_width", "tad_weight",
                                         "gradient_weight", "census_weight", "tad_truncation",
                                         "gradient_truncation")},
    "lcn_radius": ("preprocess", "radius"), "lcn_eps": ("preprocess", "eps"),
    "n_segments": ("segments", "n_segments"), "slic_iterations": ("segments", "iterations"),
    "slic_compactness": ("segments", "compactness"),
    "aggregation_radius": ("aggregation", "radius"),
    "aggregation_iterations": ("aggregation", "iterations"),
    "window_selection": ("aggregation", "window_selection"),
    "segment_weight": ("aggregation", "segment_weight"),
    "sgm_paths": ("optimizer", "paths"), "sgm_dtype": ("optimizer", "dtype"),
    "sgm_p1": ("optimizer", "p1"), "sgm_p2": ("optimizer", "p2"),
    "sgm_sigma": ("optimizer", "sigma"), "sgm_segment_factor": ("optimizer", "segment_factor"),
    "sgm_detail_weight": ("optimizer", "detail_weight"),
    "subpixel": ("selection", "subpixel"),
    "lr_tolerance": ("checks", "tolerance"), "uniqueness_gap": ("checks", "uniqueness_gap"),
    "uniqueness_radius": ("checks", "uniqueness_radius"),
    "aggregated_lr_gap": ("checks", "aggregated_gap"),
    "fill_radius": ("fill", "median_radius"), "fill_median": ("fill", "median"),
    "fill_band_fit": ("fill", "band_fit"), "fill_weight_radius": ("fill", "radius"),
    "vote_step": ("fill", "step"), "vote_sigma": ("fill", "sigma"),
    "vote_tolerance": ("fill", "tolerance"), "fill_eps": ("fill", "eps"),
    "fill_quantile": ("fill", "quantile"), "fill_source": ("fill", "source"),
    "plane_min_support": ("fill", "min_support"), "plane_inlier_scale": ("fill", "inlier_scale"),
    "refine_radius": ("refinement", "radius"), "refine_iterations": ("refinement", "iterations"),
    "coarse_levels": ("coarse", "levels"), "upsample_radius": ("coarse", "median_radius"),
    "upsample_jump": ("coarse", "jump"),
}

# Options a stage has that the old names did not feed: the old code fixed these radii.
_FIXED = {("aggregation", "gf"): ("radius",), ("aggregation", "igf"): ("radius",),
          ("aggregation", "mf"): ("radius",), ("coarse", "halving"): ("median_iterations",)}

_HINTS = {
    "lcn_": "preprocess 'lcn'", "aggregation_radius": "aggregation 'ssw', 'box' or 'bf'",
    "aggregation_iterations": "aggregation 'ssw'", "window_selection": "aggregation 'ssw'",
    "segment_weight": "aggregation 'ssw' and superpixels (n_segments > 0)",
    "slic_": "a stage that uses the superpixels", "n_segments": "a stage that uses the superpixels",
    "sgm_segment_factor": "optimizer 'sgm' and superpixels",
    "sgm_detail_weight": "optimizer 'sgm-half'", "sgm_": "optimizer 'sgm' or 'sgm-half'",
    "uniqueness_radius": "uniqueness_gap > 0", "aggregated_lr_gap": "lr_check and an optimizer",
    "fill_radius": "fill 'background', 'left-band', 'vote' or 'plane'",
    "fill_median": "fill 'background', 'left-band', 'vote' or 'plane'",
    "fill_band_fit": "fill 'left-band', 'vote' or 'wmedian'",
    "fill_weight_radius": "fill 'vote' or 'wmedian'", "vote_": "fill 'vote'",
    "fill_eps": "fill 'wmedian'", "fill_quantile": "fill 'wmedian'", "fill_source": "fill 'wmedian'",
    "plane_": "fill 'plane'", "refine_iterations": "refine_radius > 0 or coarse_levels > 0",
    "upsample_": "coarse_levels > 0", "lr_tolerance": "lr_check", "uniqueness_gap": "lr_check",
    "fill": "lr_check",
}


def old_names() -> frozenset[str]:
    """Every old flat name: parameters and execution options."""
    return frozenset(FLAT_DEFAULTS) | frozenset(EXECUTION_DEFAULTS)


def _hint(name: str) -> str:
    for prefix in sorted(_HINTS, key=len, reverse=True):
        if name.startswith(prefix):
            return _HINTS[prefix]
    return "another choice of stages"


def _kinds_of(values: Mapping) -> dict[str, str | None]:
    """The kind of each slot that the switches of a complete flat set choose (None: off)."""
    checks = bool(values["lr_check"])
    optimizer = None if values["optimizer"] == "none" else values["optimizer"]
    fill = values["fill"] if checks else None
    users = (values["aggregation"] == "ssw" or optimizer == "sgm" or fill == "plane")
    return {
        "preprocess": None if values["preprocess"] == "none" else values["preprocess"],
        "cost": "tad-gradient-census", "aggregation": values["aggregation"],
        "segments": "slic" if values["n_segments"] > 0 and users else None,
        "optimizer": optimizer, "selection": "wta", "checks": "lr" if checks else None,
        "fill": fill,
        "refinement": ("side-window-median" if values["refine_radius"] > 0
                       and values["refine_iterations"] > 0 else None),
        "coarse": "halving" if values["coarse_levels"] > 0 else None,
    }


def _skipped(slot: str, field: str, chosen: Mapping, values: Mapping) -> bool:
    """Options that keep their default although an old name feeds them: the old code ignored
    the name in that configuration."""
    if (slot, field) in (("aggregation", "segment_weight"), ("optimizer", "segment_factor")):
        return chosen["segments"] is None
    if (slot, field) == ("checks", "uniqueness_radius"):
        return values["uniqueness_gap"] == 0
    if (slot, field) == ("checks", "aggregated_gap"):
        return chosen["optimizer"] is None
    return False


class FlatReading(NamedTuple):
    """What :func:`from_flat` reads of a flat set.

    Attributes
    ----------
    slots : dict
        Slot name -> configuration (or None), for ``Params(**slots)``.
    execution : dict
        The execution names given -> their values.
    unused : dict
        The names given with a value other than their default that no stage uses -> a
        one-line reason each (:func:`unused_error` refuses them, a file warns).
    """

    slots: dict
    execution: dict
    unused: dict


def unused_error(unused: Mapping) -> ConfigError:
    """The refusal of the first of :attr:`FlatReading.unused`."""
    name = sorted(unused)[0]
    return ConfigError(name, unused[name])


def from_flat(flat: Mapping, *, explicit=None) -> FlatReading:
    """The stage configurations of a flat set of old names, and its execution options.

    Parameters
    ----------
    flat : mapping
        Old names -> values; missing names take :data:`FLAT_DEFAULTS`.
    explicit : iterable of str, optional
        The names the user gave (default: every key of ``flat``): those with a value other
        than the default that no stage uses are listed in ``unused``.

    Returns
    -------
    FlatReading

    Raises
    ------
    ConfigError
        An unknown name or kind.
    """
    unknown = sorted(set(flat) - old_names())
    if unknown:
        raise ConfigError(unknown[0], f"unknown parameter {unknown[0]!r}")
    values = {**FLAT_DEFAULTS, **{k: v for k, v in flat.items() if k in FLAT_DEFAULTS}}
    for switch in ("preprocess", "aggregation", "optimizer", "fill"):
        choices = ("none", *kinds(switch)) if SLOTS[switch].optional else tuple(kinds(switch))
        if values[switch] not in choices or not isinstance(values[switch], str):
            raise ConfigError(switch, f"parameter {switch} must be one of {choices}, got "
                              f"{values[switch]!r}")
    for switch in ("lr_check",):
        if not isinstance(values[switch], bool):
            raise ConfigError(switch, f"parameter {switch} must be true or false, got "
                              f"{values[switch]!r}")
    for switch in ("n_segments", "refine_radius", "refine_iterations", "coarse_levels"):
        if isinstance(values[switch], bool) or not isinstance(values[switch], int):
            raise ConfigError(switch, f"parameter {switch} must be an integer, got "
                              f"{values[switch]!r}")
    _check_values(flat)
    chosen = _kinds_of(values)
    feeds = {target: name for name, target in _OPTIONS.items()}
    used = {"preprocess", "aggregation", "optimizer", "lr_check", "refine_radius",
            "coarse_levels"} | ({"fill"} if chosen["checks"] else set())
    if chosen["segments"] is not None or values["n_segments"] == 0:
        used.add("n_segments")
    slots = {}
    for slot, kind in chosen.items():
        if kind is None:
            slots[slot] = None
            continue
        cls = kinds(slot)[kind]
        options = {}
        for field, _ in option_fields(cls):
            name = feeds.get((slot, field))
            if name is None or field in _FIXED.get((slot, kind), ()) \
                    or _skipped(slot, field, chosen, values):
                continue
            options[field] = as_float(dict(option_fields(cls))[field], values[name])
            used.add(name)
        if slot == "coarse":
            options.update(_coarse_median(values, used))
        slots[slot] = cls(**options)
    given = set(flat) if explicit is None else set(explicit)
    unused = {name: f"parameter {name} acts only with {_hint(name)}: it has no effect with these "
                    "parameters"
              for name in sorted(given & set(FLAT_DEFAULTS) - used)
              if values[name] != FLAT_DEFAULTS[name]}
    execution = {k: flat[k] for k in EXECUTION_DEFAULTS if k in flat}
    return FlatReading(slots, execution, unused)


_OFF_AT_ZERO = ("n_segments", "refine_radius", "refine_iterations", "coarse_levels")
"""Old names whose 0 turns a stage off (their options' ranges start at 1)."""


def _check_values(flat: Mapping) -> None:
    """Each old option's value against the declaration of the option it feeds, named by its old
    name (used or not: a bad value is refused either way)."""
    for name, value in flat.items():
        if name not in _OPTIONS or (name in _OFF_AT_ZERO and value == 0
                                    and not isinstance(value, bool)):
            continue
        slot, field = _OPTIONS[name]
        spec = next(dict(option_fields(cls))[field] for cls in kinds(slot).values()
                    if field in dict(option_fields(cls)))
        check_value(name, dataclasses.replace(spec, low=0) if name in _OFF_AT_ZERO else spec,
                    value)


def _coarse_median(values: Mapping, used: set) -> dict:
    """The median after each doubling: ``upsample_radius`` passes of ``refine_iterations``."""
    if values["refine_iterations"] == 0:
        return {"median_radius": 0}
    if values["upsample_radius"] > 0:
        used.add("refine_iterations")
        return {"median_iterations": values["refine_iterations"]}
    return {}


def to_flat(slots: Mapping) -> dict:
    """The old flat names of a configuration (slot name -> configuration or None): every name
    of :data:`FLAT_DEFAULTS`, those of unused stages at their defaults.

    Raises ``ConfigError`` when the configuration has no flat form (a choice the old names
    could not express, e.g. the guided filter's radius, or two medians with different passes).
    """
    flat = dict(FLAT_DEFAULTS)
    names = {target: name for name, target in _OPTIONS.items()}
    for slot, config in slots.items():
        if config is None:
            continue
        for field, _ in option_fields(config):
            value = getattr(config, field)
            name = names.get((slot, field))
            if (slot, field) == ("coarse", "median_iterations"):
                continue  # below: it shares refine_iterations with the refinement
            if (slot, field) in NEWER_OPTIONS:
                continue  # no flat name: a change by flat names keeps it (Params.replace)
            if field in _FIXED.get((slot, config.kind), ()) or name is None:
                if value != default_of(config, field):
                    raise ConfigError(f"{slot}.{field}", f"parameter {slot}.{field} has no flat "
                                      "name: use the per-stage form")
                continue
            flat[name] = value
    flat["preprocess"] = _kind(slots["preprocess"])
    flat["aggregation"] = slots["aggregation"].kind
    flat["optimizer"] = _kind(slots["optimizer"])
    flat["fill"] = slots["fill"].kind if slots["fill"] is not None else "background"
    flat["lr_check"] = slots["checks"] is not None
    if slots["segments"] is None:
        flat["n_segments"] = 0
    if slots["refinement"] is None:
        flat["refine_radius"] = 0
    coarse = slots["coarse"]
    if coarse is None:
        flat["coarse_levels"] = 0
    elif coarse.median_radius > 0:
        if slots["refinement"] is not None \
                and slots["refinement"].iterations != coarse.median_iterations:
            raise ConfigError("coarse.median_iterations", "parameters refinement.iterations and "
                              "coarse.median_iterations differ: they have one flat name "
                              "(refine_iterations); use the per-stage form")
        flat["refine_iterations"] = coarse.median_iterations
    return flat


def _kind(config) -> str:
    return "none" if config is None else config.kind


def translate(error: ConfigError) -> ConfigError:
    """``error`` with the per-stage names in its message replaced by the old flat names (for
    a file or call that used the old names)."""
    names = {f"{slot}.{field}": name for name, (slot, field) in _OPTIONS.items()}
    pattern = re.compile("|".join(re.escape(path) for path in sorted(names, key=len, reverse=True)))
    message = pattern.sub(lambda match: names[match.group(0)], str(error))
    return ConfigError(names.get(error.path, error.path), message)

