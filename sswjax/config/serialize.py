"""Parameters as JSON: the nested per-stage form, and the old flat files.

The nested form (what :func:`save_params` writes) is ``{"format": "sswjax-params/2",
"<slot>": null | {"kind": ..., "<option>": value, ...}, ..., "provenance": {...}}``. A file may
also be partial: what it leaves out comes from its base, the preset its ``"preset": NAME``
names, else the ``base`` the caller gives (``--preset`` on the command line), else the default
preset (:data:`~sswjax.config.presets.DEFAULT_PRESET`, ``accurate``); a slot's mapping without
``"kind"`` changes options of the base's part and one with another kind starts from that part's
defaults. A file that names every stage of the nested form's first version (every file
:func:`save_params` has written) is complete: it reads as written, on the paper's ``Params()``
(stages added since are off, options added since at their defaults), whatever the base. Files of
the flat names (``{"static": {...}, "dynamic": {...}}``, or the names at the top level) load
through :mod:`sswjax.config.legacy`, as they always did: what they leave out at the old
defaults (the paper's method), so a base is refused with them; their execution options
(``strip_rows``, ...) come back apart.
"""

from __future__ import annotations

import json
import os
import warnings
from collections.abc import Mapping

from sswjax._files import atomic_output, input_file
from sswjax.config.fields import ConfigError
from sswjax.config.legacy import (DYNAMIC_DEFAULTS, EXECUTION_DEFAULTS, NEWER_SLOTS,
                                  STATIC_DEFAULTS, from_flat, old_names, translate)
from sswjax.config.params import Params
from sswjax.config.parts import SLOTS
from sswjax.config.presets import DEFAULT_PRESET, PRESETS
from sswjax.config.validate import check_params

__all__ = ["FORMAT", "load_params", "params_from_dict", "read_params_file", "save_params"]

FORMAT = "sswjax-params/2"
"""The ``"format"`` of the nested JSON form."""

_IGNORED = ("provenance", "comment")

_FIRST_SLOTS = tuple(slot for slot in SLOTS if slot not in NEWER_SLOTS)
"""The stages of the nested form's first version (the flat names' stages): every file
:func:`save_params` has written names them all, so a file that does is complete."""


def _is_flat(data: Mapping) -> bool:
    """Whether a JSON object uses the old flat names (refusing one that mixes the forms)."""
    flat = [key for key in data
            if key in ("static", "dynamic")
            or (key in old_names() and (key not in SLOTS or isinstance(data[key], str)))]
    nested = [key for key in data if key in ("format", "preset")
              or (key in SLOTS and not isinstance(data[key], str))]
    if flat and nested:
        raise ConfigError(flat[0], f"parameters mix the flat name {flat[0]!r} with the per-stage "
                          f"form ({nested[0]!r}): use one")
    return bool(flat)


def _check_base(base) -> None:
    """``base`` of the readers: None or a preset's name."""
    if base is not None and (not isinstance(base, str) or base not in PRESETS):
        raise ValueError(f"unknown preset {base!r}; choose from {', '.join(PRESETS)}")


def read_params_dict(data, *, base: str | None = None) -> tuple[Params, dict]:
    """Validated ``Params`` and the execution options of a JSON object (either form).

    ``base`` (a preset's name; None: the default preset) fills what a partial nested object
    leaves out (the module docstring says which objects are complete).

    Raises ``ConfigError`` (a ``ValueError``) with a one-line message, also for a ``base``
    other than the object's own ``"preset"`` and for a ``base`` with a flat object.
    """
    _check_base(base)
    if not isinstance(data, Mapping):
        raise ConfigError("", f"parameters must be a JSON object, got {type(data).__name__}")
    if _is_flat(data):
        if base is not None:
            raise ConfigError("preset", "a file of the old flat names is read whole (what it "
                              "leaves out at its old defaults, the paper's method), not on the "
                              f"preset {base!r}: drop --preset or write the file with "
                              "sswjax params")
        return _read_flat(data)
    unknown = [key for key in data if key not in SLOTS and key not in ("format", "preset")
               and key not in _IGNORED]
    if unknown:
        raise ConfigError(unknown[0], f"unknown parameter {unknown[0]!r}; stages: "
                          f"{', '.join(SLOTS)}")
    if data.get("format", FORMAT) != FORMAT:
        raise ConfigError("format", f"unknown parameter format {data['format']!r}; this version "
                          f"reads {FORMAT!r} and the flat files before it")
    if "preset" in data:
        name = data["preset"]
        if not isinstance(name, str) or name not in PRESETS:
            raise ConfigError("preset", f"unknown preset {name!r}; choose from "
                              f"{', '.join(PRESETS)}")
        if base is not None and base != name:
            raise ConfigError("preset", f"the file starts from the preset {name!r}, not "
                              f"{base!r}: drop --preset or the file's \"preset\"")
        params = PRESETS[name].params
    elif all(slot in data for slot in _FIRST_SLOTS):
        params = Params()  # complete: as written, stages and options added since at defaults
    else:
        params = PRESETS[DEFAULT_PRESET if base is None else base].params
    for slot in SLOTS:
        if slot in data:
            value = data[slot]
            if value is not None and not isinstance(value, Mapping):
                raise ConfigError(slot, f"stage {slot} must be null or an object, got {value!r}")
            params = params.replace(**{slot: value})
    return check_params(params), {}


def _read_flat(data: Mapping) -> tuple[Params, dict]:
    flat: dict = {}
    for key, value in data.items():
        if key in ("static", "dynamic") and isinstance(value, Mapping):
            names = ({**STATIC_DEFAULTS, **EXECUTION_DEFAULTS} if key == "static"
                     else DYNAMIC_DEFAULTS)
            for name, item in value.items():
                if name not in names:
                    raise ConfigError(name, f"unknown {key} parameter {name!r}")
                flat[name] = item
        elif key in _IGNORED:
            continue
        elif key in old_names():
            flat[key] = value
        else:
            raise ConfigError(key, f"unknown parameter {key!r}")
    try:
        reading = from_flat(flat)
        params = check_params(Params(**reading.slots))
    except ConfigError as error:
        raise translate(error) from None
    if reading.unused:
        warnings.warn("ignored (as before the per-stage parameters): "
                      + "; ".join(reading.unused.values()), stacklevel=4)
    return params, reading.execution


def params_from_dict(data, *, base: str | None = None) -> Params:
    """Validated ``Params`` of a JSON object in either form (execution options dropped with a
    warning: see :func:`read_params_file`); what a partial object leaves out comes from the
    preset ``base`` (None: the default preset, ``accurate``)."""
    params, execution = read_params_dict(data, base=base)
    _warn_execution(execution)
    return params


def _warn_execution(execution: Mapping) -> None:
    chosen = {k: v for k, v in execution.items() if v != EXECUTION_DEFAULTS[k]}
    if chosen:
        listed = ", ".join(f"{k}={v!r}" for k, v in chosen.items())
        warnings.warn(f"{listed} in the parameters is how a call runs, not a parameter: pass "
                      f"plan=sswjax.ExecutionPlan({listed}) to sswjax.match", stacklevel=3)


def read_params_file(path: str | os.PathLike, *, base: str | None = None
                     ) -> tuple[Params, dict]:
    """The parameters of a JSON file and its execution options (old flat files may hold
    ``strip_rows``, ``strip_overlap`` and ``disparity_chunk``; the command line applies them).

    What a partial file leaves out comes from the preset ``base`` (None: the file's own
    ``"preset"``, else the default preset, ``accurate``; ``--preset`` on the command line).

    Raises ``ValueError`` with a one-line message for a missing file, invalid JSON, unknown
    keys, wrong types or out-of-range values, an unknown ``base``, a ``base`` other than the
    file's ``"preset"`` or given with an old flat file.
    """
    _check_base(base)
    input_file(path, "parameter file")  # a FIFO is refused, not opened (its open would wait)
    try:
        with open(path, encoding="utf-8") as handle:
            data = json.load(handle)
    except FileNotFoundError:
        raise ValueError(f"parameter file not found: {path}") from None
    except RecursionError:
        raise ValueError(f"cannot read parameter file {path}: nested too deeply") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"cannot read parameter file {path}: {error}") from None
    try:
        return read_params_dict(data, base=base)
    except ConfigError as error:
        raise ConfigError(error.path, f"{path}: {error}") from None


def load_params(path: str | os.PathLike, *, base: str | None = None) -> Params:
    """Read parameters from a JSON file written by :func:`save_params` (or by hand, or an old
    flat file).

    A file written by hand may be partial: what it leaves out comes from the preset its
    ``"preset"`` names, else from the preset ``base`` (default: the default preset,
    ``accurate``, what :func:`sswjax.match` runs without parameters). Before ``base`` the
    base was always the paper's method (``Params()``); the files :func:`save_params` writes
    are complete and read the same either way.

    Raises ``ValueError`` with a one-line message for a missing file, invalid JSON, unknown
    keys, wrong types or out-of-range values, an unknown ``base``, a ``base`` other than the
    file's ``"preset"`` or given with an old flat file.

    Examples
    --------
    >>> import json, tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "p2.json"
    >>> _ = path.write_text(json.dumps({"optimizer": {"p2": 1.3}}))
    >>> load_params(path).alignment is not None, load_params(path, base="fast").coarse.levels
    (True, 1)
    """
    params, execution = read_params_file(path, base=base)
    _warn_execution(execution)
    return params


def save_params(path: str | os.PathLike, params: Params, *, provenance: Mapping | None = None
                ) -> None:
    """Write ``params`` (and optional provenance) as nested JSON, atomically."""
    data = {"format": FORMAT, **params.to_dict()}
    if provenance is not None:
        data["provenance"] = dict(provenance)
    with atomic_output(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as handle:
            json.dump(data, handle, indent=2)
            handle.write("\n")
