"""How a search runs: its steps, batches, crops, objective, validation and restarts.

:class:`SearchSettings` is the search's own configuration, apart from the pipeline's
(:class:`sswjax.config.Params`, which the search moves): it is what ``sswjax search`` takes
as options, what a run folder records in ``settings.json``, and what ``--resume`` compares.
"""

from __future__ import annotations

import dataclasses

from sswjax.search.surrogates import SURROGATES

__all__ = ["DEFAULT_SURROGATE_OF_SEARCH", "SearchSettings"]

DEFAULT_SURROGATE_OF_SEARCH = "soft_bad2"
"""The objective ``sswjax search`` uses: the surrogate whose crop values ranked the parameter
points most like whole-image bad 2.0 and 1.0 (``surrogates.py``, a concluded benchmark:
``docs/notes/benchmarks-concluded.md``; ``docs/parameter-search.md``: Spearman's rho +0.93
with bad 2.0 and +0.89 with bad 1.0 pooled over the three shared sets, against +0.50 / +0.28
for the smooth L1 of the soft-argmin that the search used before), at the start temperature,
which the search therefore holds (``frozen`` has ``"temperature"``)."""


@dataclasses.dataclass(frozen=True)
class SearchSettings:
    """The search loop's settings (all plain values, so they round-trip through JSON).

    Attributes
    ----------
    steps : int
        Adam steps per start at most (early stopping may end a start sooner).
    batch : int
        Crops per step.
    crop_height, crop_context : int
        A crop is ``crop_height`` rows by ``padded ndisp + crop_context`` columns, so every
        pixel of its right-hand ``crop_context`` columns has its whole range inside the crop
        and the semi-global paths run over at least that many pixels.
    lr : float
        Adam's learning rate on the unconstrained variables.
    ema : float
        Decay of the moving average of the iterates that is validated and returned.
    temperature : float or None
        Initial soft-argmin temperature; None = 0.02 times the optimiser's paths (its volume
        sums them), or 0.02 without an optimiser.
    surrogate : str
        The loss, a name of :data:`sswjax.search.surrogates.SURROGATES`.
    val_every : int
        Steps between validations on whole images.
    val_images : int
        Whole training images validated on (spread over the data sets).
    patience : int
        Validations without improvement after which a start stops.
    restarts : int
        Starts: the base parameters, then ``restarts - 1`` random points around them (each
        searched option scaled by ``exp(U(-restart_spread, restart_spread))``).
    restart_spread : float
    min_valid : float
        Share of a crop's pixels that must have ground truth (crops are redrawn until they do).
    ndisp_step : int
        Scenes' disparity counts are rounded up to multiples of this; one compiled step per
        multiple.
    max_ndisp : int
        Scenes with a larger range are not searched on (their crops would not fit).
    seed : int
    frozen : tuple of str
        Raw keys held at their start (:func:`sswjax.search.make_optimizer`); by default the
        temperature, at which the surrogate's agreement with the metric was measured.
    checkpoint_every : int
    grid : bool
        After the continuous search, one pass of the grid over the options without a gradient
        (:mod:`sswjax.search.grid`), validated on the same whole images.
    """

    steps: int = 60
    batch: int = 8
    crop_height: int = 96
    crop_context: int = 128
    lr: float = 0.05
    ema: float = 0.8
    temperature: float | None = None
    surrogate: str = DEFAULT_SURROGATE_OF_SEARCH
    val_every: int = 10
    val_images: int = 8
    patience: int = 2
    restarts: int = 2
    restart_spread: float = 0.4
    min_valid: float = 0.1
    ndisp_step: int = 32
    max_ndisp: int = 256
    seed: int = 0
    frozen: tuple = ("temperature",)
    checkpoint_every: int = 10
    grid: bool = True

    def __post_init__(self):
        positive = ("steps", "batch", "crop_height", "crop_context", "val_every", "val_images",
                    "patience", "restarts", "ndisp_step", "max_ndisp", "checkpoint_every")
        for name in positive:
            value = getattr(self, name)
            if not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be a positive integer, got {value!r}")
        if not self.lr > 0:
            raise ValueError(f"lr must be positive, got {self.lr}")
        if not 0 <= self.ema < 1:
            raise ValueError(f"ema must be in [0, 1), got {self.ema}")
        if not 0 <= self.min_valid < 1:
            raise ValueError(f"min_valid must be in [0, 1), got {self.min_valid}")
        if self.temperature is not None and not self.temperature > 0:
            raise ValueError(f"temperature must be positive, got {self.temperature}")
        if self.restart_spread < 0:
            raise ValueError(f"restart_spread must be >= 0, got {self.restart_spread}")
        if self.surrogate not in SURROGATES:
            raise ValueError(f"unknown surrogate {self.surrogate!r}; known: "
                             f"{', '.join(SURROGATES)}")
        object.__setattr__(self, "frozen", tuple(self.frozen))

    def to_dict(self) -> dict:
        """The settings as a JSON-ready dict (``frozen`` as a list)."""
        out = dataclasses.asdict(self)
        out["frozen"] = list(self.frozen)
        return out

    @classmethod
    def from_dict(cls, data: dict) -> SearchSettings:
        """The inverse of :meth:`to_dict`; unknown keys raise ``ValueError``."""
        unknown = sorted(set(data) - {f.name for f in dataclasses.fields(cls)})
        if unknown:
            raise ValueError(f"unknown search settings {unknown}")
        return cls(**data)
