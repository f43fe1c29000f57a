"""Configuration of the vertical alignment: the residual vertical offset of the rectification,
measured on a first, coarser pass and taken out of the right image before the method runs.

The graph (:mod:`sswjax.graph.alignment`) reads these options; the stage functions are those of
:mod:`sswjax.stages.alignment`.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from sswjax.config.fields import option
from sswjax.config.fill import BackgroundFill
from sswjax.config.parts import Part, register
from sswjax.config.checks import LeftRightCheck
from sswjax.stages.alignment import (affine_offsets, fit_offsets, grid_offsets, shift_rows,
                                     tile_offsets)

__all__ = ["FIRST_PASS_CHECKS", "MODELS", "VerticalAlignment"]

FIRST_PASS_CHECKS = ("method", "left-right", "none")
"""The choices of :attr:`VerticalAlignment.checks`."""

MODELS = ("plane", "grid")
"""The choices of :attr:`VerticalAlignment.model`."""


@register("alignment", "vertical")
class VerticalAlignment(Part):
    """The right image's rows moved onto the left's: an offset affine in the image coordinates
    (and, with :attr:`model` 'grid', each tile's own departure from it), measured on the
    matching cost at a first pass's map (the method on the pair halved ``levels`` times), tile
    by tile over a few candidate offsets; then the method runs on the aligned pair."""

    levels: int = option(1, static=True, low=1, high=3, help="the first pass and the measure "
                         "run on the pair halved this many times")
    candidates: int = option(7, static=True, low=3, high=15, odd=True, help="vertical offsets "
                             "tried per tile, centred on 0")
    # 0.4 px (a span of +-1.2 px): chosen by the held-out rule, on bad 2.0 and over 2.0, 1.0
    # and 0.5, among spans of +-0.6 to +-1.33 px (docs/notes/alignment.md, "The candidates' span").
    step: float = option(0.4, above=0, help="full-resolution pixels between the candidate "
                         "offsets")
    # 3 (with the 'grid' model): chosen by the held-out rule, on bad 2.0 and over 2.0, 1.0 and
    # 0.5, among 2 to 8 tiles a side with the plane and 3 to 6 with the grid (docs/notes/alignment.md,
    # "The tiles' own offsets").
    tiles: int = option(3, static=True, low=2, high=16, help="the offsets are measured on a "
                        "grid of tiles x tiles tiles")
    # 256 (16 x 16 at the measured level): a tile of fewer valid pixels does not count. On
    # white noise, which the first pass cannot match at its halved level, tiles of 72 pixels
    # (a 48 x 96 pair) gave spurious offsets of up to a pixel at the corners; from 384 pixels
    # on, 99.7 % of the map stayed within 0.1 px (docs/notes/alignment.md, "Limits").
    min_pixels: int = option(256, static=True, low=1, help="valid pixels a tile needs to count, "
                             "at the measured level")

    # 'none': every pixel's cost counts, the mismatched ones' too (their cost hardly varies
    # with the offset): chosen by the held-out rule, on bad 2.0 and over 2.0, 1.0 and 0.5,
    # against the method's checks and the left-right check alone (docs/notes/alignment.md, "The
    # first pass's checks").
    checks: str = option("none", static=True, choices=FIRST_PASS_CHECKS,
                         help="the pixels of the first pass whose cost counts: 'method' those "
                              "the method's checks keep, 'left-right' those its left-right "
                              "check keeps, 'none' all")

    # 'grid': chosen with the tiles (KITTI at bad 2.0 6.52 -> 5.89 with 3 x 3 tiles; its
    # rectification bends the rows, more than a plane follows).
    model: str = option("grid", static=True, choices=MODELS,
                        help="the offset of every pixel: 'plane' the affine plane through the "
                             "tiles, 'grid' that plane plus each measured tile's own departure "
                             "from it, bilinear between the tiles' centres")

    def first_pass(self, params):
        """The parameters of the first pass, run on the pair halved ``levels`` times: the
        method of ``params`` over its whole volume, without this stage, coarse-to-fine, the
        band, the median and the smoothing, its checks as :attr:`checks` says (the pixels they
        reject do not count, so they are filled by the cheapest fill)."""
        checks = params.checks
        if checks is not None and self.checks != "method":
            checks = LeftRightCheck(tolerance=checks.tolerance) \
                if self.checks == "left-right" else None
        return params.replace(alignment=None, coarse=None, band=None, smoothing=None,
                              refinement=None, checks=checks,
                              fill=BackgroundFill(median_radius=0))

    def measurable(self, shape) -> bool:
        """Whether a pair of ``shape`` (its static ``(H, W)``, a bucket's padding included) can
        have a tile of ``min_pixels`` at the measured level. When no tile can, the offset is
        0 whatever the images, so the graph leaves the stage out (the same map, without the
        first pass to compile). A bound from above: the pair halved ``levels`` times (sizes
        rounded up), and the largest tile that any own size within it can give (the last of
        ``tiles`` takes ``size // tiles`` plus the remainder, at most ``tiles - 1``)."""
        largest = 1
        for size in shape:
            for _ in range(self.levels):
                size = (size + 1) // 2
            largest *= min(size, size // self.tiles + self.tiles - 1)
        return largest >= self.min_pixels

    def offsets(self, scale: int = 1) -> jax.Array:
        """The candidate offsets in pixels of a level ``scale`` times coarser than the pair:
        float32 (candidates,)."""
        half = (self.candidates - 1) / 2
        return (jnp.arange(self.candidates, dtype=jnp.float32) - half) * self.step / scale

    def coefficients(self, costs: jax.Array, valid: jax.Array, *, scale: int = 1,
                     size=None) -> jax.Array:
        """The model's coefficients, in the pair's pixels, from the candidates' costs (float32
        (K, H, W), at :meth:`offsets` ``(scale)``) where ``valid`` (bool (H, W)): float32 (3,)
        for the plane's ``(c0, c1, c2)``; for 'grid' float32 (3 + tiles * tiles,), the plane's
        then each tile's own offset less the plane's at its centre, row of tiles by row (0
        where the tile was not measured). The normalised coordinates are those of every level,
        so the coefficients scale as the offsets do. ``size``: the pair's own (H, W) at that
        level within padding (int32 (2,))."""
        tiles = tile_offsets(costs, valid, step=self.step / scale, tiles=self.tiles,
                             min_pixels=self.min_pixels, size=size)
        plane = fit_offsets(tiles)
        if self.model == "plane":
            return plane * scale
        u, v, offset, weight = (tiles[:, k] for k in range(4))
        residuals = jnp.where(weight > 0, offset - (plane[0] + plane[1] * u + plane[2] * v), 0.0)
        return jnp.concatenate([plane, residuals]) * scale

    def offset_map(self, coefficients: jax.Array, shape: tuple[int, int], *,
                   size=None) -> jax.Array:
        """Every pixel's offset from :meth:`coefficients`, within the candidates' span (what
        was measured; a plane through the tiles can reach beyond it at the corners): float32
        (H, W) for ``shape`` ``(H, W)``. ``size``: the pair's own (H, W) within padding."""
        span = (self.candidates - 1) / 2 * self.step
        offsets = affine_offsets(coefficients[:3], shape, size=size)
        if self.model == "grid":
            offsets = offsets + grid_offsets(coefficients[3:].reshape(self.tiles, self.tiles),
                                             shape, size=size)
        return jnp.clip(offsets, -span, span)

    def apply(self, right: jax.Array, coefficients: jax.Array, *, size=None) -> jax.Array:
        """``right`` (float32 (H, W, C)) with its rows moved by :meth:`offset_map`: float32
        (H, W, C). ``size``: the pair's own (H, W) within padding."""
        return shift_rows(right, self.offset_map(coefficients, right.shape[:2], size=size))
