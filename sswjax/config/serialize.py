"""Parameters as JSON: the nested per-stage form, and the old flat files.

The nested form (what :func:`save_params` writes) is ``{"format": "sswjax-params/2",
"<slot>": null | {"kind": ..., "<option>": value, ...}, ..., "provenance": {...}}``. A file may
also be partial: what it leaves out comes from its base, the preset its ``"preset": NAME``
names, else the ``base`` the caller gives (``--preset`` on the command line), else the default
preset (:data:`~sswjax.config.presets.DEFAULT_PRESET`, ``accurate``); a slot's mapping without
``"kind"`` changes options of the base's part and one with another kind starts from that part's
defaults. A file that names every stage of the nested form's first version (every file
:func:`save_params` has written) is complete: it reads as written, on the paper's ``Params()``
(stages added since are off, options added since at their defaults), whatever the base. A file
of the old flat names (``{"static": {...}, "dynamic": {...}}``, ``fill_radius``, ...) is
refused in one line that names the converter, ``sswjax params --upgrade OLD.json -o NEW.json``.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping

from sswjax._files import atomic_output, input_file
from sswjax.config.fields import ConfigError
from sswjax.config.params import Params
from sswjax.config.parts import SLOTS
from sswjax.config.presets import DEFAULT_PRESET, PRESETS
from sswjax.config.validate import check_params

__all__ = ["FORMAT", "UPGRADE", "flat_key", "load_params", "params_from_dict", "save_params"]

FORMAT = "sswjax-params/2"
"""The ``"format"`` of the nested JSON form."""

_IGNORED = ("provenance", "comment")

_FIRST_SLOTS = ("preprocess", "cost", "segments", "aggregation", "optimizer", "selection", "checks",
                "fill", "refinement", "coarse")
"""The stages of the nested form's first version: every file :func:`save_params` has written
names them all, so a file that does is complete (the stages added since, ``alignment``,
``band`` and ``smoothing``, are then off)."""

UPGRADE = "sswjax params --upgrade OLD.json -o NEW.json"
"""The command that converts a file of the old flat names."""


def flat_key(data: Mapping) -> str | None:
    """The first key that shows a JSON object in the old flat form (None: none does):
    ``"static"`` / ``"dynamic"``, a stage given a kind's name (the old switches), or another
    top-level key holding a plain value (the nested form's are stages, objects or null)."""
    return next((key for key, value in data.items()
                 if key in ("static", "dynamic") or (key in SLOTS and isinstance(value, str))
                 or (key not in SLOTS and key not in ("format", "preset", *_IGNORED)
                     and not isinstance(value, (Mapping, type(None))))), None)


def _check_base(base) -> None:
    """``base`` of the readers: None or a preset's name."""
    if base is not None and (not isinstance(base, str) or base not in PRESETS):
        raise ValueError(f"unknown preset {base!r}; choose from {', '.join(PRESETS)}")


def params_from_dict(data, *, base: str | None = None) -> Params:
    """Validated ``Params`` of a nested JSON object.

    ``base`` (a preset's name; None: the default preset, ``accurate``) fills what a partial
    object leaves out (the module docstring says which objects are complete).

    Raises ``ConfigError`` (a ``ValueError``) with a one-line message, also for a ``base``
    other than the object's own ``"preset"`` and for an object of the old flat names.
    """
    _check_base(base)
    if not isinstance(data, Mapping):
        raise ConfigError("", f"parameters must be a JSON object, got {type(data).__name__}")
    flat = flat_key(data)
    if flat is not None:
        raise ConfigError(flat, f"parameters in the old flat names ({flat!r}): convert the file "
                          f"with {UPGRADE}")
    unknown = [key for key in data if key not in SLOTS and key not in ("format", "preset")
               and key not in _IGNORED]
    if unknown:
        raise ConfigError(unknown[0], f"unknown parameter {unknown[0]!r}; stages: "
                          f"{', '.join(SLOTS)}")
    if data.get("format", FORMAT) != FORMAT:
        raise ConfigError("format", f"unknown parameter format {data['format']!r}; this version "
                          f"reads {FORMAT!r} (older flat files: {UPGRADE})")
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
    return check_params(params)


def load_params(path: str | os.PathLike, *, base: str | None = None) -> Params:
    """Read parameters from a JSON file written by :func:`save_params` (or by hand).

    A file written by hand may be partial: what it leaves out comes from the preset its
    ``"preset"`` names, else from the preset ``base`` (default: the default preset,
    ``accurate``, what :func:`sswjax.match` runs without parameters). Before ``base`` the
    base was always the paper's method (``Params()``); the files :func:`save_params` writes
    are complete and read the same either way.

    Raises ``ValueError`` with a one-line message for a missing file, invalid JSON, unknown
    keys, wrong types or out-of-range values, an unknown ``base``, a ``base`` other than the
    file's ``"preset"``, and for a file of the old flat names (the message names the converter,
    ``sswjax params --upgrade OLD.json -o NEW.json``).

    Examples
    --------
    >>> import json, tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "p2.json"
    >>> _ = path.write_text(json.dumps({"optimizer": {"p2": 1.3}}))
    >>> load_params(path).alignment is not None, load_params(path, base="fast").coarse.levels
    (True, 1)
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
    flat = flat_key(data) if isinstance(data, Mapping) else None
    if flat is not None:
        raise ConfigError(flat, f"{path}: parameters in the old flat names ({flat!r}): convert "
                          f"the file with sswjax params --upgrade {path} -o NEW.json")
    try:
        return params_from_dict(data, base=base)
    except ConfigError as error:
        raise ConfigError(error.path, f"{path}: {error}") from None


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
