"""The residual vertical offset of a rectified pair: measured on the matching cost, taken out of
the right image.

Not in the paper, which assumes rows that correspond exactly. Real rectifications leave a small
vertical disparity: MiddEval3 ships its pairs with the calibration's own errors on purpose
(Scharstein et al., "High-resolution stereo datasets with subpixel-accurate ground truth",
GCPR 2014, Section 4: "imperfect rectification", its ``dyavg`` up to 0.3 px at quarter
resolution), KITTI's rectification is not exact either. A window cost compares the wrong rows by
that offset; most of it shows below two pixels (Playtable against PlaytableP, the same scene
rectified perfectly: bad 0.5 30.2 against 16.4 % for ``accurate``).

The offset is modelled as affine in the image coordinates (a vertical shift, a rotation's
column term, a scale's row term): ``dy(y, x) = c0 + c1 u + c2 v`` with ``u = (x - (W - 1) / 2)
/ W`` and ``v = (y - (H - 1) / 2) / H``. It is measured where a first map says the pixels match:
the cost of Eq. (5) of each pixel at its (rounded) disparity, with the two images moved apart by
each of a few candidate offsets, is averaged over each tile of a grid; a parabola through the
lowest mean and its neighbours gives the tile's offset, weighted by its curvature times its
pixels; a weighted least-squares plane through the tiles gives the coefficients. Each tile's
own departure from the plane can be kept too, bilinear between the tiles' centres
(:func:`grid_offsets`): a calibration's leftover lens distortion bends the rows.

Array conventions (whole module): images float32 ``(H, W, C)``; offsets float32 ``(H, W)`` in
pixels, positive when the right image's matching row is below the left's (``right(y + dy, x -
d)`` matches ``left(y, x)``); candidate costs float32 ``(K, H, W)``; coefficients float32 ``(3,)``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from sswjax._checks import check_positive_int, check_rank

__all__ = ["affine_offsets", "fit_offsets", "grid_offsets", "shift_rows", "tile_offsets"]


def affine_offsets(coefficients: jax.Array, shape: tuple[int, int], *, size=None) -> jax.Array:
    """The offset of every pixel from the model's coefficients.

    Parameters
    ----------
    coefficients : float32 (3,)
        ``(c0, c1, c2)`` of ``dy = c0 + c1 u + c2 v`` (module docstring).
    shape : (int, int)
        ``(H, W)``.
    size : int32 (2,), optional
        The image's own height and width within padding to ``shape`` (traced values are fine):
        ``u`` and ``v`` are centred and divided by them. Default ``shape``.

    Returns
    -------
    float32 (H, W)

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> dy = affine_offsets(jnp.array([0.5, 0.0, 1.0]), (3, 4))
    >>> [round(float(v), 4) for v in dy[:, 0]]
    [0.1667, 0.5, 0.8333]
    """
    check_rank("coefficients", coefficients, 1)
    height, width = shape
    own_height, own_width = (height, width) if size is None else (size[0], size[1])
    u = (jnp.arange(width, dtype=jnp.float32) - (own_width - 1) / 2) / own_width
    v = (jnp.arange(height, dtype=jnp.float32) - (own_height - 1) / 2) / own_height
    return coefficients[0] + coefficients[1] * u[None, :] + coefficients[2] * v[:, None]


def grid_offsets(residuals: jax.Array, shape: tuple[int, int], *, size=None) -> jax.Array:
    """Each pixel's share of the tiles' own offsets: bilinear between the tiles' centres, the
    nearest edge tiles' beyond them (the tile grid of :func:`tile_offsets`, its centres taken at
    ``(i + 1/2) own / tiles``; the last tile's remainder, under ``tiles`` pixels at the measured
    level, is left out).

    Parameters
    ----------
    residuals : float32 (tiles, tiles)
        Per tile (row of tiles, column of tiles), its offset less the plane's at its centre.
    shape : (int, int)
        ``(H, W)``.
    size : int32 (2,), optional
        The image's own height and width within padding to ``shape`` (traced values are fine).
        Default ``shape``.

    Returns
    -------
    float32 (H, W)

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> dy = grid_offsets(jnp.array([[0.0, 1.0], [0.0, 1.0]]), (2, 8))
    >>> [round(float(v), 3) for v in dy[0]]
    [0.0, 0.0, 0.125, 0.375, 0.625, 0.875, 1.0, 1.0]
    """
    check_rank("residuals", residuals, 2)
    tiles = residuals.shape[0]
    if residuals.shape != (tiles, tiles):
        raise ValueError(f"residuals must be square, got {residuals.shape}")
    height, width = shape
    own_height, own_width = (height, width) if size is None else (size[0], size[1])

    def axis(count, own):  # the two tiles around each row (or column), and the second's weight
        at = jnp.clip((jnp.arange(count, dtype=jnp.float32) + 0.5) / own * tiles - 0.5, 0,
                      tiles - 1)
        first = jnp.floor(at).astype(jnp.int32)
        return first, jnp.minimum(first + 1, tiles - 1), at - first

    top, bottom, down = axis(height, own_height)
    left, right, across = axis(width, own_width)

    def across_rows(row):  # float32 (H, W): the residuals of tile row ``row[y]``, across
        return residuals[row][:, left] * (1 - across) + residuals[row][:, right] * across

    return (across_rows(top) * (1 - down)[:, None]
            + across_rows(bottom) * down[:, None]).astype(jnp.float32)


def shift_rows(image: jax.Array, offsets: jax.Array) -> jax.Array:
    """``image`` read at ``(y + offsets[y, x], x)``: linear between the two rows, the first and
    last rows repeated beyond the image.

    Parameters
    ----------
    image : float32 (H, W, C)
    offsets : float32 (H, W), pixels

    Returns
    -------
    float32 (H, W, C); where every offset is 0, ``image`` itself (the weight of the second row
    is 0).

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> column = jnp.arange(4.0).reshape(4, 1, 1)
    >>> [float(v) for v in shift_rows(column, jnp.full((4, 1), 0.25))[:, 0, 0]]
    [0.25, 1.25, 2.25, 3.0]
    """
    check_rank("image", image, 3)
    check_rank("offsets", offsets, 2)
    if offsets.shape != image.shape[:2]:
        raise ValueError(f"offsets must have shape {image.shape[:2]}, got {offsets.shape}")
    height, width = offsets.shape
    rows = jnp.clip(jnp.arange(height, dtype=jnp.float32)[:, None] + offsets, 0, height - 1)
    top = jnp.floor(rows)
    weight = (rows - top)[..., None]
    top = top.astype(jnp.int32)
    bottom = jnp.minimum(top + 1, height - 1)
    columns = jnp.arange(width)[None, :]
    flat = image.reshape(height * width, image.shape[-1])

    def read(row):
        return jnp.take(flat, (row * width + columns).reshape(-1), axis=0).reshape(image.shape)

    return (1 - weight) * read(top) + weight * read(bottom)


def tile_offsets(costs: jax.Array, valid: jax.Array, *, step, tiles: int,
                 min_pixels: int = 64, size=None) -> jax.Array:
    """Each tile's offset: the parabola through the lowest mean candidate cost and its
    neighbours.

    Parameters
    ----------
    costs : float32 (K, H, W), K >= 3
        The cost of each pixel at its disparity with the right image moved by candidate ``k``,
        the candidates ``(k - (K - 1) / 2) * step`` pixels.
    valid : bool (H, W)
        The pixels whose cost counts.
    step : float scalar, > 0
        Pixels between candidates.
    tiles : int
        The grid has ``tiles x tiles`` tiles (the last row and column of tiles take the
        remainder of the image).
    min_pixels : int
        A tile with fewer valid pixels has weight 0.
    size : int32 (2,), optional
        The image's own height and width within padding (traced values are fine): the grid
        covers them (``valid`` must be False beyond), the coordinates are theirs. Default the
        costs' ``(H, W)``.

    Returns
    -------
    float32 (tiles * tiles, 4): per tile ``(u, v, offset, weight)``, ``u, v`` its centre in the
    coordinates of :func:`affine_offsets`; the weight is 0 where the lowest mean is the first or
    last candidate (the offset lies outside the candidates) or the parabola does not open
    upwards.

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> k = jnp.arange(5.0)[:, None, None] - 2
    >>> costs = jnp.broadcast_to((k * 0.2 - 0.1) ** 2, (5, 8, 8))
    >>> out = tile_offsets(costs, jnp.ones((8, 8), bool), step=0.2, tiles=2, min_pixels=1)
    >>> [round(float(o), 4) for o in out[:, 2]]
    [0.1, 0.1, 0.1, 0.1]
    """
    check_rank("costs", costs, 3)
    check_positive_int("tiles", tiles)
    count, height, width = costs.shape
    if count < 3:
        raise ValueError(f"tile_offsets needs at least 3 candidates, got {count}")
    if valid.shape != (height, width):
        raise ValueError(f"valid must have shape {(height, width)}, got {valid.shape}")
    own_height, own_width = (height, width) if size is None else (size[0], size[1])
    # Tile index of each row and column: tiles of H // tiles rows, the last one the remainder.
    row_tile = jnp.minimum(jnp.arange(height) // jnp.maximum(own_height // tiles, 1), tiles - 1)
    col_tile = jnp.minimum(jnp.arange(width) // jnp.maximum(own_width // tiles, 1), tiles - 1)
    label = (row_tile[:, None] * tiles + col_tile[None, :]).reshape(-1)
    weight = valid.reshape(-1).astype(jnp.float32)
    pixels = jax.ops.segment_sum(weight, label, num_segments=tiles * tiles)
    sums = jax.vmap(lambda c: jax.ops.segment_sum(c.reshape(-1) * weight, label,
                                                  num_segments=tiles * tiles))(costs)
    means = sums / jnp.maximum(pixels, 1.0)  # (K, T)
    best = jnp.clip(jnp.argmin(means, axis=0), 1, count - 2)
    lower, centre, upper = (jnp.take_along_axis(means, (best + k)[None], axis=0)[0]
                            for k in (-1, 0, 1))
    curvature = lower - 2 * centre + upper
    interior = (jnp.argmin(means, axis=0) == best) & (curvature > 0)
    vertex = 0.5 * (lower - upper) / jnp.where(curvature > 0, curvature, 1.0)
    offset = (best - (count - 1) / 2 + vertex) * step
    tile_weight = jnp.where(interior & (pixels >= min_pixels), curvature * pixels, 0.0)
    # The centre of each tile in the coordinates of affine_offsets.
    def centres(tile, count, own):  # the mean coordinate of each tile's rows (or columns)
        inside = (jnp.arange(count) < own).astype(jnp.float32)
        total = jax.ops.segment_sum(jnp.arange(count) * inside, tile, num_segments=tiles)
        return total / jnp.maximum(jax.ops.segment_sum(inside, tile, num_segments=tiles), 1)

    u = (centres(col_tile, width, own_width) - (own_width - 1) / 2) / own_width
    v = (centres(row_tile, height, own_height) - (own_height - 1) / 2) / own_height
    u = u[None, :].repeat(tiles, 0).reshape(-1)
    v = v[:, None].repeat(tiles, 1).reshape(-1)
    return jnp.stack([u, v, offset, tile_weight], axis=1).astype(jnp.float32)


def fit_offsets(tiles: jax.Array, *, min_tiles: int = 3) -> jax.Array:
    """The weighted least-squares plane ``offset = c0 + c1 u + c2 v`` through the tiles.

    Solved from its 3 x 3 normal equations by the adjugate (no LAPACK call in the graph). With
    fewer than ``min_tiles`` weighted tiles, or tiles on one line, only the mean offset
    ``(c0, 0, 0)``; with none, zeros.

    Parameters
    ----------
    tiles : float32 (T, 4)
        ``(u, v, offset, weight)`` per tile (:func:`tile_offsets`).
    min_tiles : int

    Returns
    -------
    float32 (3,)

    Examples
    --------
    >>> import jax.numpy as jnp
    >>> u, v = jnp.meshgrid(jnp.linspace(-0.4, 0.4, 3), jnp.linspace(-0.4, 0.4, 3))
    >>> u, v = u.reshape(-1), v.reshape(-1)
    >>> t = jnp.stack([u, v, 0.1 + 0.2 * u - 0.3 * v, jnp.ones(9)], axis=1)
    >>> [round(float(c), 4) for c in fit_offsets(t)]
    [0.1, 0.2, -0.3]
    """
    check_rank("tiles", tiles, 2)
    u, v, offset, weight = (tiles[:, k] for k in range(4))
    design = jnp.stack([jnp.ones_like(u), u, v], axis=1)  # (T, 3)
    normal = (design * weight[:, None]).T @ design
    rhs = (design * weight[:, None]).T @ offset
    a, b, c = normal[0], normal[1], normal[2]
    adjugate = jnp.stack([jnp.cross(b, c), jnp.cross(c, a), jnp.cross(a, b)], axis=1)
    determinant = jnp.dot(a, jnp.cross(b, c))
    total = jnp.sum(weight)
    mean = jnp.sum(weight * offset) / jnp.where(total > 0, total, 1.0)
    # Conditioned when the determinant is not negligible against the weights' scale cubed.
    planar = (jnp.sum(weight > 0) >= min_tiles) & (jnp.abs(determinant) > 1e-6 * total ** 3)
    plane = adjugate @ rhs / jnp.where(planar, determinant, 1.0)
    fallback = jnp.stack([jnp.where(total > 0, mean, 0.0), 0.0, 0.0])
    return jnp.where(planar, plane, fallback).astype(jnp.float32)
