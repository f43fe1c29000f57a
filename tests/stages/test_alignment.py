"""The vertical alignment's stage functions (``sswjax.stages.alignment``) against loop
references and least squares."""

import jax.numpy as jnp
import numpy as np
import pytest

from sswjax.stages.alignment import (affine_offsets, fit_offsets, grid_offsets, shift_rows,
                                     tile_offsets)


def _shift_reference(image: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Pixel by pixel: the two rows around ``y + offset`` (clamped to the image), linear."""
    height, width, channels = image.shape
    out = np.zeros(image.shape, np.float64)
    for y in range(height):
        for x in range(width):
            row = min(max(y + offsets[y, x], 0.0), height - 1.0)
            top = int(np.floor(row))
            bottom = min(top + 1, height - 1)
            weight = row - top
            out[y, x] = (1 - weight) * image[top, x] + weight * image[bottom, x]
    return out


@pytest.mark.parametrize("shape,scale", [((7, 5, 3), 0.4), ((9, 4, 1), 3.0), ((6, 8, 3), 0.05)])
def test_shift_rows_matches_the_loop_reference(shape, scale):
    rng = np.random.default_rng(shape[0] * 10 + shape[1])
    image = rng.random(shape).astype(np.float32)
    # Offsets of both signs, some beyond the first and last rows.
    offsets = (rng.normal(0, scale, shape[:2])).astype(np.float32)
    got = np.asarray(shift_rows(jnp.asarray(image), jnp.asarray(offsets)))
    np.testing.assert_allclose(got, _shift_reference(image, offsets), atol=1e-6)


def test_shift_rows_by_zero_is_the_image():
    image = np.random.default_rng(0).random((5, 6, 3)).astype(np.float32)
    got = np.asarray(shift_rows(jnp.asarray(image), jnp.zeros((5, 6))))
    np.testing.assert_array_equal(got, image)


def test_affine_offsets_matches_the_loop_reference():
    coefficients = np.array([0.3, -0.5, 1.2], np.float32)
    height, width = 5, 8
    got = np.asarray(affine_offsets(jnp.asarray(coefficients), (height, width)))
    for y in range(height):
        for x in range(width):
            u, v = (x - (width - 1) / 2) / width, (y - (height - 1) / 2) / height
            assert got[y, x] == pytest.approx(coefficients @ [1.0, u, v], abs=1e-6)


def _grid_reference(residuals, height, width, own_height, own_width):
    """Pixel by pixel: the four tiles whose centres ``(i + 1/2) own / tiles`` surround the
    pixel's, bilinear; the edge tiles' values beyond the outer centres."""
    tiles = residuals.shape[0]
    out = np.zeros((height, width))
    for y in range(height):
        for x in range(width):
            at_row = min(max((y + 0.5) / own_height * tiles - 0.5, 0.0), tiles - 1.0)
            at_col = min(max((x + 0.5) / own_width * tiles - 0.5, 0.0), tiles - 1.0)
            i, j = int(at_row), int(at_col)
            i2, j2 = min(i + 1, tiles - 1), min(j + 1, tiles - 1)
            a, b = at_row - i, at_col - j
            out[y, x] = ((1 - a) * ((1 - b) * residuals[i, j] + b * residuals[i, j2])
                         + a * ((1 - b) * residuals[i2, j] + b * residuals[i2, j2]))
    return out


@pytest.mark.parametrize("tiles,shape,size", [(3, (9, 14), None), (4, (12, 11), (10, 7)),
                                              (2, (5, 6), None)])
def test_grid_offsets_matches_the_loop_reference(tiles, shape, size):
    residuals = np.random.default_rng(tiles).normal(0, 0.5, (tiles, tiles)).astype(np.float32)
    got = np.asarray(grid_offsets(jnp.asarray(residuals), shape,
                                  size=None if size is None else jnp.asarray(size)))
    own = shape if size is None else size
    np.testing.assert_allclose(got, _grid_reference(residuals, *shape, *own), atol=1e-6)


def _tiles_reference(costs, valid, step, tiles, min_pixels):
    """Tile by tile: the mean of each candidate's cost over the tile's valid pixels, the
    parabola through the lowest and its neighbours."""
    count, height, width = costs.shape
    rows = [min(y // (height // tiles), tiles - 1) for y in range(height)]
    cols = [min(x // (width // tiles), tiles - 1) for x in range(width)]
    out = []
    for i in range(tiles):
        for j in range(tiles):
            ys = [y for y in range(height) if rows[y] == i]
            xs = [x for x in range(width) if cols[x] == j]
            cells = [(y, x) for y in ys for x in xs if valid[y, x]]
            means = [np.mean([costs[k, y, x] for y, x in cells]) if cells else 0.0
                     for k in range(count)]
            best = int(np.argmin(means))
            u = (np.mean(xs) - (width - 1) / 2) / width
            v = (np.mean(ys) - (height - 1) / 2) / height
            if best in (0, count - 1) or len(cells) < min_pixels:
                out.append((u, v, None, 0.0))
                continue
            a, b, c = means[best - 1], means[best], means[best + 1]
            curvature = a - 2 * b + c
            if curvature <= 0:
                out.append((u, v, None, 0.0))
                continue
            offset = (best - (count - 1) / 2 + 0.5 * (a - c) / curvature) * step
            out.append((u, v, offset, curvature * len(cells)))
    return out


@pytest.mark.parametrize("shape,tiles,min_pixels", [((5, 13, 11), 2, 1), ((7, 17, 9), 3, 5),
                                                     ((3, 8, 8), 4, 2)])
def test_tile_offsets_matches_the_loop_reference(shape, tiles, min_pixels):
    rng = np.random.default_rng(sum(shape) + tiles)
    count = shape[0]
    # A bowl per pixel around a random centre, with noise: most tiles have an interior
    # minimum, some (the centre beyond the candidates) do not.
    centre = rng.uniform(-1.2, 1.2, shape[1:]) * (count - 1) / 2
    k = np.arange(count)[:, None, None] - (count - 1) / 2
    costs = ((k - centre) ** 2 + rng.normal(0, 0.3, shape)).astype(np.float32)
    valid = rng.random(shape[1:]) < 0.8
    got = np.asarray(tile_offsets(jnp.asarray(costs), jnp.asarray(valid), step=0.25, tiles=tiles,
                                  min_pixels=min_pixels))
    expected = _tiles_reference(costs, valid, 0.25, tiles, min_pixels)
    assert got.shape == (tiles * tiles, 4)
    for row, (u, v, offset, weight) in zip(got, expected):
        assert row[0] == pytest.approx(u, abs=1e-6) and row[1] == pytest.approx(v, abs=1e-6)
        assert row[3] == pytest.approx(weight, rel=1e-4, abs=1e-5)
        if offset is not None:
            assert row[2] == pytest.approx(offset, abs=1e-4)


def test_fit_offsets_matches_weighted_least_squares():
    rng = np.random.default_rng(3)
    tiles = np.stack([rng.uniform(-0.5, 0.5, 16), rng.uniform(-0.5, 0.5, 16),
                      rng.normal(0, 0.3, 16), rng.uniform(0, 2, 16)], axis=1).astype(np.float32)
    tiles[[2, 7], 3] = 0.0  # tiles without weight do not count
    design = np.stack([np.ones(16), tiles[:, 0], tiles[:, 1]], axis=1)
    root = np.sqrt(tiles[:, 3])
    expected = np.linalg.lstsq(design * root[:, None], tiles[:, 2] * root, rcond=None)[0]
    np.testing.assert_allclose(np.asarray(fit_offsets(jnp.asarray(tiles))), expected, atol=1e-4)


def test_fit_offsets_falls_back_to_the_mean_then_to_zero():
    one_line = np.array([[0.1, 0.0, 0.2, 1.0], [0.3, 0.0, 0.4, 1.0], [-0.2, 0.0, 0.3, 2.0]],
                        np.float32)  # every tile on v = 0: the plane is not determined
    np.testing.assert_allclose(np.asarray(fit_offsets(jnp.asarray(one_line))),
                               [(0.2 + 0.4 + 0.6) / 4, 0.0, 0.0], atol=1e-6)
    nothing = one_line.copy()
    nothing[:, 3] = 0.0
    np.testing.assert_array_equal(np.asarray(fit_offsets(jnp.asarray(nothing))), [0.0, 0.0, 0.0])
