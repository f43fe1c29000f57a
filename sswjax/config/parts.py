"""The stages of the method as slots, and the registry of the parts that can fill each slot.

:data:`SLOTS` lists the stages in the order the data flows through them; each is a field of
:class:`sswjax.config.Params`. A slot holds one configuration, an instance of a class
registered for it with :func:`register` (its *kind*: ``"vote"`` for the vote fill), or ``None``
when the slot is optional and the stage is off. Interchangeable slots (several kinds) name the
kind in JSON and on the command line; the others have one class.

A part owns its defaults, its options (declared with :func:`sswjax.config.fields.option`), its
checks against the rest of the configuration (``validate``) and the call of its stage
functions. Adding one is one stage module, one configuration class and its ``@register``
line; validation, JSON, ``--set``, ``sswjax params`` and the graph then know it.
"""

from __future__ import annotations

from typing import NamedTuple

from sswjax.config.fields import stage_config

__all__ = ["SLOTS", "Part", "Slot", "kinds", "register", "unregister"]


class Slot(NamedTuple):
    """A stage of the pipeline: a field of ``Params``.

    Attributes
    ----------
    name : str
        The field's name, e.g. ``"fill"``.
    summary : str
        One line for help.
    optional : bool
        Whether ``None`` (the stage off) is allowed.
    interchangeable : bool
        Whether several kinds may fill it (JSON then names the ``"kind"``).
    """

    name: str
    summary: str
    optional: bool
    interchangeable: bool


SLOTS: dict[str, Slot] = {slot.name: slot for slot in (
    Slot("alignment", "the right image's rows moved onto the left's (the rectification's "
         "residual vertical offset, measured on a first pass)", True, False),
    Slot("preprocess", "what the matching cost sees of the images", True, True),
    Slot("cost", "the matching cost of each pixel and disparity (Eq. 1-5)", False, False),
    Slot("segments", "the superpixels the segment-aware stages share (Eq. 6)", True, False),
    Slot("aggregation", "the aggregation of the cost volume (Eq. 7)", False, True),
    Slot("optimizer", "the optimisation of the aggregated volume before the selection", True,
         True),
    Slot("selection", "the winner-takes-all and its sub-pixel fit (Eq. 8)", False, False),
    Slot("checks", "the tests that reject a pixel's disparity (Eq. 9)", True, False),
    Slot("fill", "how the rejected pixels are filled (Eq. 9)", True, True),
    Slot("refinement", "the median over the disparity map", True, False),
    Slot("coarse", "the method on the pair halved, the map doubled back", True, False),
    Slot("band", "a full-resolution search of a few disparities around the map before it",
         True, False),
    Slot("smoothing", "edge-aware smoothing of the finished map, at full resolution", True,
         False),
)}
"""Slot name -> :class:`Slot`, in pipeline order."""

_KINDS: dict[str, dict[str, type]] = {name: {} for name in SLOTS}


class Part:
    """Base of every configuration class: its slot and kind, set by :func:`register`.

    ``validate(params)`` checks the part against the whole configuration (rules across
    stages) and raises :class:`sswjax.config.validate.ConfigError`; the default accepts.
    """

    slot: str = ""
    kind: str = ""

    def validate(self, params) -> None:
        """Rules between this part and the rest of ``params`` (none by default)."""

    @classmethod
    def summary(cls) -> str:
        """The first paragraph of the class's docstring, on one line."""
        paragraph = (cls.__doc__ or cls.__name__).strip().split("\n\n")[0]
        return " ".join(line.strip() for line in paragraph.splitlines())


def register(slot: str, kind: str):
    """Class decorator: make a :class:`Part` subclass a stage configuration
    (:func:`~sswjax.config.fields.stage_config`) and the part ``kind`` of ``slot``.

    Raises ``ValueError`` for an unknown slot or a kind already taken.
    """
    if slot not in SLOTS:
        raise ValueError(f"unknown slot {slot!r}; slots: {', '.join(SLOTS)}")

    def wrap(cls):
        if kind in _KINDS[slot]:
            raise ValueError(f"{slot} kind {kind!r} is already registered")
        if not issubclass(cls, Part):
            raise TypeError(f"{cls.__name__} must derive from sswjax.config.parts.Part")
        cls = stage_config(cls)
        cls.slot, cls.kind = slot, kind
        _KINDS[slot][kind] = cls
        return cls

    return wrap


def unregister(slot: str, kind: str) -> None:
    """Remove a registered kind (for tests that register a toy part)."""
    del _KINDS[slot][kind]


def kinds(slot: str) -> dict[str, type]:
    """Kind name -> class of the parts registered for ``slot`` (a copy, registration order)."""
    if slot not in SLOTS:
        raise ValueError(f"unknown slot {slot!r}; slots: {', '.join(SLOTS)}")
    return dict(_KINDS[slot])
