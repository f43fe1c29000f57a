"""Validation of a configuration, derived from the options' declarations.

:func:`check_params` checks each option against its :class:`~sswjax.config.fields.Option`
(type, bounds, choices, oddness; traced values finite in float32, the dtype the graph computes
in), then each part's own rules against the whole configuration (``Part.validate``), then the
rules between slots. Every failure is a :class:`~sswjax.config.fields.ConfigError` (a
``ValueError``) with a one-line message naming the option by its dotted path.
"""

from __future__ import annotations

from sswjax.config.fields import ConfigError, check_value, option_fields
from sswjax.config.params import Params
from sswjax.config.parts import SLOTS, kinds

__all__ = ["check_params"]


def check_params(params) -> Params:
    """Validate a ``Params`` value given to the Python API; return it unchanged.

    Traced values (inside ``jax.jit`` or ``jax.grad``) are not inspected.

    Raises
    ------
    TypeError
        If ``params`` is not a ``Params``.
    ConfigError
        On the first bad option or combination, with a one-line message naming it.
    """
    if not isinstance(params, Params):
        raise TypeError(f"params must be a sswjax.Params (see sswjax.preset and "
                        f"sswjax.load_params), got {type(params).__name__}")
    for slot, config in params.stages():
        if config is None:
            if not SLOTS[slot].optional:
                raise ConfigError(slot, f"stage {slot} cannot be None")
            continue
        if kinds(slot).get(getattr(config, "kind", None)) is not type(config):
            raise ConfigError(slot, f"stage {slot} takes one of the kinds "
                              f"{', '.join(kinds(slot))}, got {type(config).__name__}")
        for name, spec in option_fields(config):
            check_value(f"{slot}.{name}", spec, getattr(config, name))
    for _, config in params.stages():
        if config is not None:
            config.validate(params)
    if params.checks is None and params.fill is not None:
        raise ConfigError("fill", f"stage fill ({params.fill.kind!r}) fills what the checks "
                          "reject: with checks None, set fill to None too")
    if params.checks is not None and params.fill is None:
        raise ConfigError("fill", "stage fill is None, but the checks reject pixels: choose a "
                          f"fill ({', '.join(kinds('fill'))})")
    return params
