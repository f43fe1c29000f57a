"""How a stage declares its options: static or traced, bounds, choices and search transform.

Every option of a stage configuration is a dataclass field made by :func:`option`. Its
:class:`Option` metadata is the one place that says

* whether it is **static** (pytree metadata: it fixes shapes or the graph, changing it
  recompiles) or **traced** (a pytree leaf: ``jit`` traces it, ``grad`` differentiates it, the
  optax search moves it; always a float);
* its type, bounds (inclusive ``low`` / ``high``, or ``above`` for a strict lower bound),
  choices, and oddness;
* for traced options, the transform the search maps an unconstrained variable through
  (:class:`Sigmoid`, :class:`Softplus`, :class:`Simplex`); for static ones, the value the
  search must run with when the inference value has no gradient (``differentiable``);
* one line of help.

Validation (:mod:`sswjax.config.validate`), JSON (:mod:`sswjax.config.serialize`), the command
line's help and the search's tables (:mod:`sswjax.search.space`) all read this metadata:
nothing repeats it in a table of its own. :func:`stage_config` turns a class into a frozen
dataclass registered as a JAX pytree with exactly that static / traced split.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Iterator
from typing import Any, NamedTuple

import jax
import numpy as np

__all__ = ["ConfigError", "Option", "Sigmoid", "Simplex", "Softplus", "Transform", "as_float",
           "check_value",
           "default_of", "is_config", "is_set", "nested_fields",
           "option", "option_fields", "stage_config"]


class ConfigError(ValueError):
    """A configuration that cannot run, with a one-line message; ``path`` is the dotted name of
    the option (or stage) at fault, e.g. ``"fill.band_fit"``."""

    def __init__(self, path: str, message: str):
        super().__init__(message)
        self.path = path


class Sigmoid(NamedTuple):
    """Search transform ``value = low + (high - low) * sigmoid(raw)``: stays in (low, high)."""

    low: float
    high: float


class Softplus(NamedTuple):
    """Search transform ``value = floor + softplus(raw)``: stays above ``floor``."""

    floor: float = 0.0


class Simplex(NamedTuple):
    """Search transform shared by the options of one ``group`` of a configuration: one vector
    of logits, ``values = softmax(raw)`` (they sum to 1; searched all together or not at all)."""

    group: str


Transform = Sigmoid | Softplus | Simplex


@dataclasses.dataclass(frozen=True)
class Option:
    """The declaration of one option (the metadata of its dataclass field).

    Attributes
    ----------
    static : bool
        True: pytree metadata (recompiles on change); False: a traced float leaf.
    kind : type
        ``int``, ``bool`` or ``str`` for static options, ``float`` for traced ones.
    help : str
        One line: what it does, in the stage's units.
    low, high : float or None
        Inclusive bounds.
    above : float or None
        Strict lower bound (``value > above``).
    choices : tuple
        The allowed values (static ``str`` or ``int`` options).
    odd : bool
        The value must be odd (window sizes centred on a pixel).
    search : Transform or None
        Traced options the optax search may move, and how (:mod:`sswjax.search.space`).
    differentiable : Any
        Static options: the value the search runs with instead (None: the option's own value).
    grid : float or None
        Options without a gradient that the search tries on a grid instead: the step of the
        values tried either side of the current one (:mod:`sswjax.search.grid`).
    """

    static: bool
    kind: type
    help: str
    low: float | None = None
    high: float | None = None
    above: float | None = None
    choices: tuple = ()
    odd: bool = False
    search: Transform | None = None
    differentiable: Any = None
    grid: float | None = None

    def describe(self) -> str:
        """The allowed values in words, for help and error messages: ``"an odd integer in
        [3, 15]"``, ``"one of 'int16', 'uint8'"``, ``"a number > 0"``."""
        if self.choices:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.kind is bool:
            return "true or false"
        noun = {int: "integer", float: "number", str: "string"}[self.kind]
        noun = f"an odd {noun}" if self.odd else f"an {noun}" if noun == "integer" else f"a {noun}"
        if self.low is not None and self.high is not None:
            return f"{noun} in [{_number(self.low)}, {_number(self.high)}]"
        if self.above is not None and self.high is not None:
            return f"{noun} in ({_number(self.above)}, {_number(self.high)}]"
        if self.above is not None:
            return f"{noun} > {_number(self.above)}"
        if self.low is not None:
            return f"{noun} >= {_number(self.low)}"
        return noun


def _number(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else str(value)


def option(default, *, help: str, static: bool = False, low=None, high=None, above=None,
           choices=(), odd: bool = False, search: Transform | None = None,
           differentiable=None, grid: float | None = None) -> Any:
    """A dataclass field declaring one option (see :class:`Option`).

    The option's type is that of ``default`` for a static option (``int``, ``bool``, ``str``);
    a traced option is a float.

    Examples
    --------
    >>> @stage_config
    ... class Example:
    ...     radius: int = option(4, static=True, low=1, high=50, help="window radius")
    ...     weight: float = option(0.5, low=0, help="weight of the term")
    >>> Example().radius, option_fields(Example)[1][1].static
    (4, False)
    """
    if static:
        kind = type(default)
        if kind not in (int, bool, str):
            raise TypeError(f"a static option is an int, bool or str, got {default!r}")
    else:
        kind = float
        if isinstance(default, bool) or not isinstance(default, (int, float)):
            raise TypeError(f"a traced option is a number, got {default!r}")
        if differentiable is not None:
            raise TypeError("differentiable= is for static options")
    if search is not None and static:
        raise TypeError("a static option has no search transform (it has no gradient)")
    if grid is not None and (search is not None or not grid > 0 or kind in (bool, str)):
        raise TypeError("grid= is a positive step, for numeric options without a search "
                        "transform")
    spec = Option(static, kind, help, low, high, above, tuple(choices), odd, search,
                  differentiable, grid)
    return dataclasses.field(default=default, metadata={"option": spec})


def stage_config(cls):
    """Make ``cls`` a frozen dataclass and a JAX pytree: static options are its metadata, traced
    options and nested configurations its children.

    A field made by :func:`option` is an option; any other field holds a nested configuration
    (or ``None``) and is a pytree child. The class gains ``replace(**changes)``.
    """
    cls = dataclasses.dataclass(frozen=True)(cls)
    meta, data = [], []
    for field in dataclasses.fields(cls):
        spec = field.metadata.get("option")
        (meta if spec is not None and spec.static else data).append(field.name)
    jax.tree_util.register_dataclass(cls, data_fields=data, meta_fields=meta)
    if "replace" not in cls.__dict__:
        cls.replace = lambda self, **changes: dataclasses.replace(self, **changes)
    return cls


def is_config(value) -> bool:
    """Whether ``value`` is an instance of a class made by :func:`stage_config`."""
    return dataclasses.is_dataclass(value) and not isinstance(value, type) \
        and hasattr(type(value), "__dataclass_fields__")


def option_fields(cls) -> list[tuple[str, Option]]:
    """``(name, Option)`` of every option of a configuration class (or instance), in order."""
    return [(f.name, f.metadata["option"]) for f in dataclasses.fields(cls)
            if "option" in f.metadata]


def nested_fields(cls) -> Iterator[str]:
    """Names of the fields of a configuration that hold nested configurations."""
    return (f.name for f in dataclasses.fields(cls) if "option" not in f.metadata)


def default_of(cls, name: str):
    """The default value of field ``name`` of a configuration class (or instance)."""
    return {f.name: f.default for f in dataclasses.fields(cls)}[name]


def is_set(config, name: str) -> bool:
    """Whether option ``name`` of ``config`` differs from its default (a traced option in
    float32, the graph's dtype; a traced value, whose value is unknown, counts as not set): how
    a rule tells an option someone chose from one left alone."""
    value = getattr(config, name)
    if isinstance(value, jax.core.Tracer):
        return False
    if not dict(option_fields(config))[name].static:  # as the graph sees it: float32
        return bool(np.float32(value) != np.float32(default_of(config, name)))
    return value != default_of(config, name)


def as_float(spec: Option, value):
    """A Python integer given to a traced option as a float (every other value as it is), so
    that the pytree's leaves keep one dtype however a value was written.

    >>> as_float(Option(False, float, ""), 2), as_float(Option(True, int, ""), 2)
    (2.0, 2)
    """
    if not spec.static and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    return value


def check_value(path: str, spec: Option, value):
    """Check one option's value; return it with its canonical Python type (traced options as
    ``float``; a traced JAX value is returned as it is, unchecked).

    Examples
    --------
    >>> check_value("fill.median_radius", Option(True, int, "", low=0, high=15), 3)
    3
    >>> check_value("cost.tad_weight", Option(False, float, "", low=0), 1e39)
    Traceback (most recent call last):
    ...
    sswjax.config.fields.ConfigError: parameter cost.tad_weight must be finite in float32 (the graph's dtype), got 1e+39
    """
    if spec.static:
        return _check_static(path, spec, value)
    if isinstance(value, jax.core.Tracer):
        return value
    if not isinstance(value, (bool, int, float)) and hasattr(value, "shape"):
        if tuple(value.shape) != ():
            raise ConfigError(path, f"parameter {path} must be a scalar, got shape "
                              f"{tuple(value.shape)}")
        if getattr(getattr(value, "dtype", None), "kind", "") not in ("i", "u", "f"):
            raise ConfigError(path, f"parameter {path} must be a number, got {value!r}")
        value = float(value)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(path, f"parameter {path} must be {spec.describe()}, got {value!r}")
    value = float(value)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        single = float(np.float32(value))
    if not math.isfinite(single):
        raise ConfigError(path, f"parameter {path} must be finite in float32 (the graph's "
                          f"dtype), got {value!r}")
    if not _in_bounds(spec, value):
        raise ConfigError(path, f"parameter {path} must be {spec.describe()}, got {value!r}")
    return value


def _in_bounds(spec: Option, value) -> bool:
    return not ((spec.low is not None and value < spec.low)
                or (spec.high is not None and value > spec.high)
                or (spec.above is not None and value <= spec.above))


def _check_static(path: str, spec: Option, value):
    if spec.kind is bool:
        ok = isinstance(value, bool)
    elif spec.kind is int:
        ok = isinstance(value, int) and not isinstance(value, bool) and _in_bounds(spec, value)
        ok = ok and not (spec.odd and value % 2 == 0)
    else:
        ok = isinstance(value, str)
    if ok and spec.choices:
        ok = value in spec.choices
    if not ok:
        raise ConfigError(path, f"parameter {path} must be {spec.describe()}, got {value!r}")
    return value
