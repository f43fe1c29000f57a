"""Configuration of the matching cost (Eq. 1-5).

Array conventions (whole module): images float32 ``(H, W, C)``, C in {1, 3}, values in
[0, 1]; cost slices float32 ``(D, H, W)``, lower is better.
"""

from __future__ import annotations

import jax

from sswjax.config.fields import ConfigError, Sigmoid, Simplex, option
from sswjax.config.parts import Part, register
from sswjax.stages.bands import band_cost
from sswjax.stages.cost import MatchingFeatures, matching_cost, matching_cost_at, matching_features

__all__ = ["MatchingCost"]


@register("cost", "tad-gradient-census")
class MatchingCost(Part):
    """TAD + Sobel gradient + census, each normalised to [0, 1] and weighted (Eq. 1-5).

    The defaults are ``tuning/params/tuned.json``'s: the truncations found by the optax search,
    the weights set by hand (written as the shortest decimals of the float32 values the graph
    computes with).
    """

    census_height: int = option(7, static=True, low=1, high=15, odd=True,
                                help="census window height (Eq. 4)")
    census_width: int = option(9, static=True, low=1, high=15, odd=True,
                               help="census window width (Eq. 4)")
    tad_weight: float = option(0.05, low=0, search=Simplex("weight_logits"),
                               help="alpha of Eq. 5: weight of the truncated colour difference")
    gradient_weight: float = option(0.15, low=0, search=Simplex("weight_logits"),
                                    help="beta of Eq. 5: weight of the gradient difference")
    census_weight: float = option(0.8, low=0, search=Simplex("weight_logits"),
                                  help="gamma of Eq. 5: weight of the census Hamming distance")
    tad_truncation: float = option(0.042218186, above=0, search=Sigmoid(0.002, 0.3),
                                   help="tau of Eq. 2 on the channel-mean absolute difference")
    gradient_truncation: float = option(0.015484431, above=0,
                                        search=Sigmoid(0.005, 1.0),
                                        help="truncation of the gradient-magnitude difference "
                                             "(Eq. 3)")

    def validate(self, params) -> None:
        """A census window needs a neighbour; the weights must be able to produce a cost."""
        if self.census_height == 1 and self.census_width == 1:
            raise ConfigError("cost.census_height", "parameters cost.census_height and "
                              "cost.census_width: a 1 x 1 census window compares no neighbour")
        weights = [self.tad_weight, self.gradient_weight, self.census_weight]
        if all(not isinstance(w, jax.core.Tracer) for w in weights) \
                and sum(abs(float(w)) for w in weights) == 0:
            raise ConfigError("cost.census_weight", "parameters cost.tad_weight, "
                              "gradient_weight and census_weight are all 0: no pixel has a cost")

    def _terms(self) -> dict:
        return dict(tad_weight=self.tad_weight, gradient_weight=self.gradient_weight,
                    census_weight=self.census_weight, tad_truncation=self.tad_truncation,
                    gradient_truncation=self.gradient_truncation)

    def features(self, left: jax.Array, right: jax.Array) -> MatchingFeatures:
        """The per-image terms of the cost (:func:`~sswjax.stages.cost.matching_features`)."""
        return matching_features(left, right, census_height=self.census_height,
                                 census_width=self.census_width)

    def slices(self, features: MatchingFeatures, first, count: int) -> jax.Array:
        """Cost slices of disparities ``first .. first + count - 1``: float32 (count, H, W)."""
        return matching_cost(features, first, count, **self._terms())

    def band(self, features: MatchingFeatures, starts: jax.Array, width: int) -> jax.Array:
        """Cost over each pixel's band of ``width`` disparities from ``starts`` (int32 (H, W)):
        float32 (width, H, W) (:func:`~sswjax.stages.bands.band_cost`)."""
        return band_cost(features, starts, width=width, **self._terms())

    def at(self, features: MatchingFeatures, disparity: jax.Array) -> jax.Array:
        """The cost of each pixel at its own disparity (int32 (H, W)): float32 (H, W)."""
        return matching_cost_at(features, disparity, **self._terms())

    def bound(self):
        """The largest cost of a matching pixel: the weights' sum (each term is in [0, 1])."""
        return abs(self.tad_weight) + abs(self.gradient_weight) + abs(self.census_weight)
