"""Configurations of the optimisers between aggregation and selection: semi-global matching.

Array conventions (whole module): ``optimise(cost, guide, labels=, cost_bound=)`` takes the
aggregated volume, float32 ``(D, H, W)`` (lower is better) or as :meth:`storage` stored it,
the left image float32 ``(H, W, C)`` in [0, 1], the superpixels int32 ``(H, W)`` or ``None``,
and the largest cost of a matching pixel (a scalar); it returns a float32 ``(D, H, W)`` volume
or the :class:`~sswjax.stages.sgm.PathSums` that the selection reads plane by plane.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from sswjax.config.fields import ConfigError, Softplus, is_set, option, stage_config
from sswjax.config.parts import Part, register
from sswjax.stages.quantisation import SGM_DTYPES, PathSums, Quantisation, quantisation
from sswjax.stages.cross_scale import half_resolution_semi_global
from sswjax.stages.sgm import PATH_COUNTS, semi_global_sums, vertical_shifts

__all__ = ["HalfResolutionSemiGlobal", "Optimizer", "SemiGlobal"]


class Optimizer(Part):
    """Base of the optimisers.

    ``uses_segments``: whether it reads the superpixels; ``subpixel_on_input``: whether the
    sub-pixel parabola fits the aggregated cost it was given rather than its output (whose
    interpolated coarse term would bias it).
    """

    uses_segments = False
    subpixel_on_input = False
    searches_bands = False
    carries_paths = False

    def optimise(self, cost, guide, *, labels, cost_bound, starts=None,
                 seeds=None) -> PathSums | jax.Array:
        """The optimised volume (module docstring); with ``starts`` (int32 (H, W)) ``cost`` is
        a band volume (:mod:`sswjax.stages.bands`), for the optimisers that
        ``searches_bands``; with ``seeds`` (:class:`~sswjax.stages.paths.Seeds`) the paths
        along the rows come from the neighbouring windows, for those that ``carries_paths``
        (their states for the neighbours in the result's ``carried``)."""
        raise NotImplementedError

    def storage(self, cost_bound) -> Quantisation | None:
        """How :meth:`optimise` takes the aggregated cost (None: float32), which the graph
        applies block by block as it builds the volume."""
        return None


@stage_config
class _Penalties(Optimizer):
    """The options every semi-global optimiser shares."""

    paths: int = option(8, static=True, choices=PATH_COUNTS,
                        help="paths: horizontal and vertical, and with 8 the diagonals")
    dtype: str = option("int16", static=True, choices=SGM_DTYPES, differentiable="float32",
                        help="what the paths run on: the cost quantised to 'int16' (as OpenCV's "
                             "SGBM), stored in 'uint8' levels, or 'float32' (exact, "
                             "differentiable)")
    p1: float = option(0.05, low=0, search=Softplus(0.0),
                       help="penalty of a disparity change of one, in cost units")
    p2: float = option(0.4, low=0, search=Softplus(0.0),
                       help="penalty of a larger change, in cost units")
    sigma: float = option(0.05, above=0, search=Softplus(1e-3),
                          help="guide intensity change that halves P2")

    def _quantisation(self, cost_bound) -> dict:
        """``cost_bound`` and ``cost_levels`` of the semi-global functions for :attr:`dtype`."""
        return {"cost_bound": None if self.dtype == "float32" else cost_bound,
                "cost_levels": 255 if self.dtype == "uint8" else None}


@register("optimizer", "sgm")
class SemiGlobal(_Penalties):
    """Semi-global optimisation of the aggregated cost, 4 or 8 paths, guide-adaptive P2, reduced
    across superpixels (Hirschmuller 2008)."""

    segment_factor: float = option(1.0, low=0, high=1,
                                   help="factor of both penalties across superpixel boundaries "
                                        "(with segments)")

    uses_segments = True
    searches_bands = True
    carries_paths = True

    def validate(self, params) -> None:
        """The segment factor acts only with superpixels."""
        if params.segments is None and is_set(self, "segment_factor"):
            raise ConfigError("optimizer.segment_factor", "parameter optimizer.segment_factor "
                              "acts only with superpixels (segments is None)")

    def optimise(self, cost, guide, *, labels, cost_bound, starts=None, seeds=None):
        """:func:`~sswjax.stages.sgm.semi_global_sums` (PathSums), over bands with
        ``starts``, carried in and out with ``seeds``."""
        return semi_global_sums(cost, guide, p1=self.p1, p2=self.p2, sigma=self.sigma,
                                paths=self.paths, labels=labels,
                                segment_factor=self.segment_factor, starts=starts,
                                seeds=seeds, **self._quantisation(cost_bound))

    def seed_lines(self, cost_bound) -> tuple[int, object]:
        """How many :class:`~sswjax.stages.paths.Seeds` lines each direction carries, and
        their dtype (that of the sums)."""
        dtype = jnp.float32 if self._quantisation(cost_bound)["cost_bound"] is None else jnp.int16
        return len(vertical_shifts(self.paths)), dtype

    def storage(self, cost_bound):
        """The :func:`~sswjax.stages.sgm.quantisation` of the paths (None for float32)."""
        options = self._quantisation(cost_bound)
        if options["cost_bound"] is None:
            return None
        return quantisation(paths=self.paths, p1=self.p1, p2=self.p2, **options)


@register("optimizer", "sgm-half")
class HalfResolutionSemiGlobal(_Penalties):
    """Semi-global optimisation of the volume halved in space and disparity, doubled back onto
    the aggregated cost (an eighth of the paths' work)."""

    detail_weight: float = option(1.0, low=0, help="weight of the full-resolution aggregated "
                                  "cost added to the doubled half-resolution paths")

    subpixel_on_input = True

    def optimise(self, cost, guide, *, labels, cost_bound, starts=None, seeds=None):
        """:func:`~sswjax.stages.cross_scale.half_resolution_semi_global` (float32 volume)."""
        return half_resolution_semi_global(cost, guide, p1=self.p1, p2=self.p2,
                                           sigma=self.sigma, paths=self.paths,
                                           detail_weight=self.detail_weight,
                                           **self._quantisation(cost_bound))
