"""``sswjax params --upgrade OLD.json``: the one converter of the old flat parameter files.

Until the per-stage configuration, the parameters were one flat set of 53 names (``fill_radius``,
``sgm_p2``, ``strip_rows``, ...) written as ``{"static": {...}, "dynamic": {...}}`` or at the
top level. The library reads only the nested per-stage form and refuses a flat file in one line
that names this command; this module is the only code that knows the old names.

A flat set is read as the old code read it: every name has its old default
(:data:`FLAT_DEFAULTS`, the paper's method), the switches (``preprocess``, ``aggregation``,
``optimizer``, ``fill``, ``lr_check``, ``n_segments``, ``refine_radius``, ``coarse_levels``)
choose the stages, and each stage takes its options from the names that fed it. A name the old
code ignored (an option of a stage that is not used) is left out with a note, and so are
``strip_rows``, ``strip_overlap`` and ``disparity_chunk``, which are how a call runs (the options
of ``sswjax match`` of the same names). Stages added since the flat names are off in the result.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from sswjax.config import SLOTS, ConfigError, Params, check_params, kinds
from sswjax.config.fields import check_value, option_fields
from sswjax.config.serialize import FORMAT, flat_key

__all__ = ["EXECUTION_NAMES", "FLAT_DEFAULTS", "OLD_NAMES", "upgrade", "upgrade_file"]

_STATIC_DEFAULTS: dict = {
    "census_height": 7, "census_width": 9, "n_segments": 2000, "slic_iterations": 10,
    "aggregation_radius": 4, "aggregation_iterations": 3, "aggregation": "ssw",
    "window_selection": "slice", "subpixel": True, "lr_check": True, "fill_radius": 2,
    "refine_radius": 2, "refine_iterations": 2, "optimizer": "none", "sgm_paths": 8,
    "sgm_dtype": "int16", "fill": "background", "fill_weight_radius": 9, "fill_band_fit": 0,
    "vote_step": 4, "fill_source": "filled", "fill_median": "square", "preprocess": "none",
    "lcn_radius": 7, "coarse_levels": 0, "upsample_radius": 1, "uniqueness_gap": 0,
    "uniqueness_radius": 2, "aggregated_lr_gap": 0,
}

_DYNAMIC_DEFAULTS: dict = {
    "tad_weight": 0.05, "gradient_weight": 0.15, "census_weight": 0.8,
    "tad_truncation": 0.042218186, "gradient_truncation": 0.015484431,
    "segment_weight": 0.59967893, "slic_compactness": 10.0, "lr_tolerance": 0.0, "sgm_p1": 0.05,
    "sgm_p2": 0.4, "sgm_sigma": 0.05, "sgm_segment_factor": 1.0, "sgm_detail_weight": 1.0,
    "plane_min_support": 0.25, "plane_inlier_scale": 1.0, "lcn_eps": 4 / 255, "fill_eps": 1e-3,
    "fill_quantile": 0.5, "upsample_jump": 3.0, "vote_sigma": 0.2, "vote_tolerance": 2.0,
}

FLAT_DEFAULTS: dict = {**_STATIC_DEFAULTS, **_DYNAMIC_DEFAULTS}
"""Every old parameter name with its old default (the paper's method)."""

EXECUTION_NAMES = {"strip_rows": 0, "strip_overlap": 32, "disparity_chunk": 4}
"""The old names that were how a call runs (``"static"`` held them), with their old defaults:
left out, with a note where a file gave another value."""

OLD_NAMES = frozenset(FLAT_DEFAULTS) | frozenset(EXECUTION_NAMES)
"""The 53 old flat names."""

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

_OFF_AT_ZERO = ("n_segments", "refine_radius", "refine_iterations", "coarse_levels")
"""Old names whose 0 turns a stage off (their options' ranges start at 1)."""

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


def _hint(name: str) -> str:
    return next((_HINTS[prefix] for prefix in sorted(_HINTS, key=len, reverse=True)
                 if name.startswith(prefix)), "another choice of stages")


def _flat_names(data: Mapping) -> dict:
    """The old names of a flat JSON object (``"static"`` / ``"dynamic"`` or the top level)."""
    flat: dict = {}
    for key, value in data.items():
        if key in ("static", "dynamic") and isinstance(value, Mapping):
            names = ({*_STATIC_DEFAULTS, *EXECUTION_NAMES} if key == "static"
                     else set(_DYNAMIC_DEFAULTS))
            for name, item in value.items():
                if name not in names:
                    raise ConfigError(name, f"unknown {key} parameter {name!r}")
                flat[name] = item
        elif key in OLD_NAMES:
            flat[key] = value
        elif key not in ("provenance", "comment"):
            raise ConfigError(key, f"unknown parameter {key!r}: not one of the old flat names")
    return flat


def _check_values(flat: Mapping) -> None:
    """Each old option's value against the declaration of the option it feeds, named by its old
    name (used or not: a bad value is refused either way), and the switches' types."""
    for switch in ("preprocess", "aggregation", "optimizer", "fill"):
        if switch in flat:
            choices = ("none", *kinds(switch)) if SLOTS[switch].optional else tuple(kinds(switch))
            if not isinstance(flat[switch], str) or flat[switch] not in choices:
                raise ConfigError(switch, f"parameter {switch} must be one of {choices}, got "
                                  f"{flat[switch]!r}")
    if not isinstance(flat.get("lr_check", True), bool):
        raise ConfigError("lr_check", f"parameter lr_check must be true or false, got "
                          f"{flat['lr_check']!r}")
    for name, value in flat.items():
        if name not in _OPTIONS:
            continue
        slot, field = _OPTIONS[name]
        spec = next(dict(option_fields(cls))[field] for cls in kinds(slot).values()
                    if field in dict(option_fields(cls)))
        if name in _OFF_AT_ZERO:
            spec = dataclasses.replace(spec, low=0)
        check_value(name, spec, value)


def _kinds_of(values: Mapping) -> dict[str, str | None]:
    """The kind of each slot that the switches of a complete flat set choose (None: off)."""
    checks = bool(values["lr_check"])
    optimizer = None if values["optimizer"] == "none" else values["optimizer"]
    fill = values["fill"] if checks else None
    users = values["aggregation"] == "ssw" or optimizer == "sgm" or fill == "plane"
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


def upgrade(data: Mapping) -> tuple[Params, list[str]]:
    """The validated ``Params`` of a flat parameter object, and notes on what it left out.

    Parameters
    ----------
    data : mapping
        The JSON object of an old file: ``{"static": {...}, "dynamic": {...}}`` or the old
        names at the top level (``"provenance"`` and ``"comment"`` ignored).

    Returns
    -------
    (Params, list of str)
        The configuration the old code ran (traced options as the shortest decimals of their
        float32 values, what the graph computes with); one line per name left out: an
        execution option, or an option the old code ignored with these switches.

    Raises
    ------
    ConfigError
        An unknown name, a wrong type or a value out of range, named by its old name.

    Examples
    --------
    >>> params, notes = upgrade({"static": {"fill": "vote", "vote_step": 2}, "strip_rows": 64})
    >>> params.fill.kind, params.fill.step, notes
    ('vote', 2, ['strip_rows=64 is how a call runs, not a parameter: pass --strip-rows 64 to sswjax match'])
    """
    if not isinstance(data, Mapping):
        raise ConfigError("", f"parameters must be a JSON object, got {type(data).__name__}")
    flat = _flat_names(data)
    _check_values(flat)
    values = {**FLAT_DEFAULTS, **{k: v for k, v in flat.items() if k in FLAT_DEFAULTS}}
    chosen = _kinds_of(values)
    feeds = {target: name for name, target in _OPTIONS.items()}
    used = {"preprocess", "aggregation", "optimizer", "lr_check", "refine_radius",
            "coarse_levels"} | ({"fill"} if chosen["checks"] else set())
    if chosen["segments"] is not None or values["n_segments"] == 0:
        used.add("n_segments")
    slots = {slot: None for slot in SLOTS}
    for slot, kind in chosen.items():
        if kind is None:
            continue
        cls = kinds(slot)[kind]
        options = {}
        for field, spec in option_fields(cls):
            name = feeds.get((slot, field))
            if name is None or field in _FIXED.get((slot, kind), ()) \
                    or _skipped(slot, field, chosen, values):
                continue
            options[field] = values[name] if spec.static else _decimal(values[name])
            used.add(name)
        if slot == "coarse":  # the median after each doubling: refine_iterations passes
            if values["refine_iterations"] == 0:
                options["median_radius"] = 0
            elif values["upsample_radius"] > 0:
                options["median_iterations"] = values["refine_iterations"]
                used.add("refine_iterations")
        slots[slot] = cls(**options)
    notes = [f"{name}={flat[name]!r} is how a call runs, not a parameter: pass "
             f"--{name.replace('_', '-')} {flat[name]} to sswjax match"
             for name, default in EXECUTION_NAMES.items() if flat.get(name, default) != default]
    notes += [f"{name}={flat[name]!r} left out: it acts only with {_hint(name)}, and has no "
              "effect with these parameters" for name in sorted(set(flat) - used)
              if name in FLAT_DEFAULTS and _differs(name, flat[name])]
    return check_params(Params(**slots)), notes


def _differs(name: str, value) -> bool:
    """Whether an old name's value differs from its old default (traced ones as float32: full
    dumps hold the old search's float32 values)."""
    if name in _DYNAMIC_DEFAULTS:
        return np.float32(value) != np.float32(_DYNAMIC_DEFAULTS[name])
    return value != FLAT_DEFAULTS[name]


def _decimal(value) -> float:
    """The shortest decimal of ``value``'s float32 (what the graph computes with): a value the
    old search stored as ``0.05000000074505806`` reads 0.05."""
    return float(np.format_float_positional(np.float32(value), unique=True, trim="0"))


def upgrade_file(path: Path) -> tuple[dict, list[str]]:
    """The nested JSON object (as :func:`sswjax.config.save_params` writes it) of the old flat
    file ``path``, its ``"provenance"`` kept, and the notes of :func:`upgrade`.

    Raises ``ValueError`` with one line for a missing or unreadable file, and for a file that
    is not flat (already nested).
    """
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ValueError(f"parameter file not found: {path}") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"cannot read parameter file {path}: {error}") from None
    if isinstance(data, Mapping) and flat_key(data) is None:
        raise ValueError(f"{path} is not a file of the old flat names: nothing to upgrade")
    try:
        params, notes = upgrade(data)
    except ConfigError as error:
        raise ConfigError(error.path, f"{path}: {error}") from None
    document = {"format": FORMAT, **params.to_dict()}
    if isinstance(data.get("provenance"), Mapping):
        document["provenance"] = dict(data["provenance"])
    return document, notes
