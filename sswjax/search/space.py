"""The search space: which traced options the optax search moves, and through what transform.

Nothing here is a table of parameters: every traced option that the search may move declares
its transform where it is declared (``Option.search`` in :mod:`sswjax.config`), and every
static option whose inference value has no gradient declares the value the search runs with
(``Option.differentiable``, e.g. the semi-global ``dtype`` -> ``"float32"``: the int16 paths
round the cost, so their gradients are zero). This module reads that metadata.

Names: an option is named by its dotted path, ``"<slot>.<option>"`` (``"cost.tad_truncation"``,
``"optimizer.p2"``); ``searched`` is a tuple of such paths. The search variables (``raw``, a
dict of unconstrained float32 arrays) are keyed by *raw keys*: an option's path, except that
the options of one :class:`~sswjax.config.fields.Simplex` group share one vector of logits
keyed ``"<slot>.<group>"`` (the cost weights: ``"cost.weight_logits"``), plus
:data:`TEMPERATURE`, the soft-argmin's temperature (search-only, not a ``Params`` option).

Transforms (``raw`` -> value):

* ``Simplex(group)``: ``softmax(logits)``, so the group sums to 1. WTA is invariant to the
  overall scale of the cost but soft-argmin is not; fixing the sum and learning a separate
  temperature keeps the two apart. :func:`to_unconstrained` normalises the values to sum 1
  and centres the logits.
* ``Sigmoid(low, high)``: ``low + (high - low) * sigmoid(raw)``.
* ``Softplus(floor)``: ``floor + softplus(raw)``. Near small values softplus is about exp, so
  Adam's steps on the raw value are relative steps.
* the temperature: ``MIN_TEMPERATURE + softplus(raw)``.

Traced options without a transform (e.g. ``segments.compactness``, which enters only SLIC's
assignment argmin, and ``checks.tolerance``, whose check is not on the soft path) and every
static option stay at their ``base`` values.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from sswjax.config import Params
from sswjax.config.fields import Sigmoid, Simplex, Softplus, option_fields
from sswjax.config.parts import SLOTS, kinds

__all__ = ["MIN_TEMPERATURE", "SEARCHED", "SGM_SEARCHED", "TEMPERATURE", "all_raw_keys",
           "differentiable", "from_unconstrained", "raw_keys", "raw_to_params", "searchable",
           "searched_fields", "to_unconstrained", "value_of"]

SEARCHED = ("cost.tad_weight", "cost.gradient_weight", "cost.census_weight",
            "cost.tad_truncation", "cost.gradient_truncation", "aggregation.segment_weight")
"""The options searched for the paper's pipeline (the default ``searched``)."""
SGM_SEARCHED = ("cost.tad_truncation", "cost.gradient_truncation", "optimizer.p1",
                "optimizer.p2", "optimizer.sigma")
"""The options searched through the semi-global optimiser: the cost truncations and the
penalties; the cost weights stay fixed (searching them overfits, tuning/README)."""
TEMPERATURE = "temperature"
"""The raw key of the soft-argmin's temperature."""
MIN_TEMPERATURE = 1e-4
"""The temperature's floor."""


def _softplus_inverse(y):
    y = np.asarray(y, np.float64)
    return np.where(y > 20, y, np.log(np.expm1(np.maximum(y, 1e-12))))


def _logit(p):
    p = np.clip(np.asarray(p, np.float64), 1e-6, 1 - 1e-6)
    return np.log(p) - np.log1p(-p)


def _split(path: str) -> tuple[str, str]:
    slot, _, name = path.partition(".")
    if slot not in SLOTS or not name:
        raise ValueError(f"{path!r} is not an option path \"<slot>.<option>\"; slots: "
                         f"{', '.join(SLOTS)}")
    return slot, name


def _group(cls, group: str) -> tuple[str, ...]:
    """The options of ``cls`` (a configuration class) in the simplex ``group``, in order."""
    return tuple(name for name, spec in option_fields(cls)
                 if isinstance(spec.search, Simplex) and spec.search.group == group)


def _declared(path: str, config=None):
    """The search transform of the option at ``path``: that of ``config``'s class (the part in
    the slot), else the one every registered part of the slot that has the option declares;
    and the classes it was read from."""
    slot, name = _split(path)
    classes = [type(config)] if config is not None else list(kinds(slot).values())
    found = {cls: dict(option_fields(cls))[name].search for cls in classes
             if name in dict(option_fields(cls))}
    transforms = set(found.values()) - {None}
    if not transforms:
        raise ValueError(f"no reparametrisation for {path!r}: it is not a searchable option "
                         f"(searchable: {', '.join(_every_searchable())})")
    if len(transforms) > 1:
        raise ValueError(f"{path!r}: the parts of slot {slot} declare different search "
                         "transforms; search it with parameters that choose the part")
    return transforms.pop(), [cls for cls, t in found.items() if t is not None]


def _raw_key(path: str) -> str:
    transform, _ = _declared(path)
    return f"{path.partition('.')[0]}.{transform.group}" if isinstance(transform, Simplex) \
        else path


def _every_searchable() -> tuple[str, ...]:
    return tuple(dict.fromkeys(f"{slot}.{name}" for slot in SLOTS for cls in kinds(slot).values()
                               for name, spec in option_fields(cls) if spec.search is not None))


def all_raw_keys() -> tuple[str, ...]:
    """Every raw key a search space of the registered parts can have (what ``frozen`` may name).

    >>> "cost.weight_logits" in all_raw_keys() and "optimizer.p2" in all_raw_keys()
    True
    """
    return tuple(dict.fromkeys(_raw_key(path) for path in _every_searchable())) + (TEMPERATURE,)


def searchable(params: Params) -> tuple[str, ...]:
    """The paths of the options of ``params``' parts that declare a search transform.

    >>> searchable(Params()) == SEARCHED
    True
    """
    return tuple(f"{slot}.{name}" for slot, config in params.stages() if config is not None
                 for name, spec in option_fields(config) if spec.search is not None)


def raw_keys(searched) -> tuple[str, ...]:
    """The raw keys of the search space of the options ``searched`` (dotted paths).

    The options of a simplex group are searched all together (one key, where the first of them
    is listed) or not at all; :data:`TEMPERATURE` is always there.

    >>> raw_keys(SEARCHED)  # doctest: +NORMALIZE_WHITESPACE
    ('cost.weight_logits', 'cost.tad_truncation', 'cost.gradient_truncation',
     'aggregation.segment_weight', 'temperature')
    """
    searched = tuple(searched)
    keys = {}
    for path in searched:
        transform, classes = _declared(path)
        if isinstance(transform, Simplex):
            slot = path.partition(".")[0]
            members = {f"{slot}.{name}" for cls in classes for name in _group(cls, transform.group)}
            given = sorted(members & set(searched))
            if given != sorted(members):
                raise ValueError(f"the options {', '.join(sorted(members))} are searched all "
                                 f"together or not at all, got {', '.join(given)}")
        keys.setdefault(_raw_key(path), None)
    return tuple(keys) + (TEMPERATURE,)


def value_of(params: Params, path: str):
    """The value of the option at ``path`` in ``params``.

    >>> value_of(Params(), "aggregation.radius")
    4
    """
    slot, name = _split(path)
    config = getattr(params, slot)
    if config is None:
        raise ValueError(f"{path}: stage {slot} is None")
    if name not in dict(option_fields(config)):
        raise ValueError(f"{path}: {slot} {config.kind!r} has no option {name!r}")
    return getattr(config, name)


def to_unconstrained(params: Params, *, temperature: float = 0.02, searched=SEARCHED) -> dict:
    """The raw (unconstrained) search variables of the options ``searched`` of ``params``, and
    of a soft-argmin temperature: a dict of float32 arrays keyed by :func:`raw_keys`.

    The inverse of :func:`from_unconstrained` (module docstring); the simplex values are
    normalised to sum to 1 (WTA does not change) and their logits centred.

    Examples
    --------
    >>> from sswjax.config import preset
    >>> base = preset("accurate").replace(**{"optimizer.p2": 0.8})
    >>> raw = to_unconstrained(base, searched=SGM_SEARCHED)
    >>> round(float(from_unconstrained(raw, base=base)[0].optimizer.p2), 4)
    0.8
    """
    raw = {}
    for key in raw_keys(searched):
        if key == TEMPERATURE:
            continue
        slot, name = _split(key)
        config = getattr(params, slot)
        if config is None:
            raise ValueError(f"{key}: stage {slot} is None in these parameters")
        members = _group(type(config), name)
        if members:
            values = np.array([float(getattr(config, m)) for m in members], np.float64)
            if values.sum() <= 0:
                raise ValueError(f"{key}: the options {', '.join(members)} must not all be zero")
            logits = np.log(np.maximum(values / values.sum(), 1e-6))
            raw[key] = jnp.asarray(logits - logits.mean(), jnp.float32)
            continue
        transform, _ = _declared(key, config)
        value = float(value_of(params, key))
        if isinstance(transform, Sigmoid):
            value = _logit((value - transform.low) / (transform.high - transform.low))
        else:
            value = _softplus_inverse(value - transform.floor)
        raw[key] = jnp.asarray(value, jnp.float32)
    raw[TEMPERATURE] = jnp.asarray(_softplus_inverse(temperature - MIN_TEMPERATURE), jnp.float32)
    return raw


def _constrained(raw: dict, base: Params) -> dict:
    """Option path -> constrained value (a JAX scalar) of every option ``raw`` sets."""
    values = {}
    for key, value in raw.items():
        if key == TEMPERATURE:
            continue
        slot, name = _split(key)
        config = getattr(base, slot)
        if config is None:
            raise ValueError(f"raw key {key!r}: stage {slot} is None in the base parameters")
        members = _group(type(config), name)
        if members:
            weights = jax.nn.softmax(value)
            values.update({f"{slot}.{m}": weights[i] for i, m in enumerate(members)})
            continue
        transform, _ = _declared(key, config)
        if isinstance(transform, Sigmoid):
            values[key] = transform.low + (transform.high - transform.low) * jax.nn.sigmoid(value)
        elif isinstance(transform, Softplus):
            values[key] = transform.floor + jax.nn.softplus(value)
        else:
            raise ValueError(f"raw key {key!r} names one option of the simplex group "
                             f"{slot}.{transform.group}")
    return values


def from_unconstrained(raw: dict, *, base: Params) -> tuple[Params, jax.Array]:
    """``base`` with the options ``raw`` sets (constrained), and the temperature (a float32
    scalar); the inverse of :func:`to_unconstrained` for any search space. Traceable."""
    params = base.replace(**_constrained(raw, base))
    return params, MIN_TEMPERATURE + jax.nn.softplus(raw[TEMPERATURE])


def searched_fields(raw: dict) -> tuple[str, ...]:
    """The option paths a raw dict sets (the inverse of :func:`raw_keys`).

    >>> searched_fields(dict.fromkeys(raw_keys(SEARCHED))) == SEARCHED
    True
    """
    paths = []
    for key in raw:
        if key == TEMPERATURE:
            continue
        slot, name = _split(key)
        members = tuple(dict.fromkeys(m for cls in kinds(slot).values() for m in _group(cls, name)))
        if not members:
            _declared(key)
        paths += [f"{slot}.{m}" for m in members] or [key]
    return tuple(paths)


def raw_to_params(raw: dict, base: Params) -> Params:
    """``base`` with the options ``raw`` sets replaced by their values (plain floats)."""
    return base.replace(**{path: float(value) for path, value in _constrained(raw, base).items()})


def differentiable(params: Params) -> Params:
    """``params`` with every static option that declares ``differentiable`` set to that value
    (what the search runs: e.g. the semi-global paths in float32).

    >>> from sswjax.config import preset
    >>> preset("accurate").optimizer.dtype, differentiable(preset("accurate")).optimizer.dtype
    ('uint8', 'float32')
    """
    changes = {}
    for slot, config in params.stages():
        if config is None:
            continue
        options = {name: spec.differentiable for name, spec in option_fields(config)
                   if spec.static and spec.differentiable is not None}
        if options:
            changes[slot] = dataclasses.replace(config, **options)
    return params.replace(**changes) if changes else params
