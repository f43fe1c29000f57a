"""The gated joint bilateral mean of a disparity map against a per-pixel loop reference."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sswjax.stages.smoothing import (gated_bilateral_line_mean, gated_bilateral_mean,
                                     gated_bilateral_smoothing)


def _reference(disparity: np.ndarray, guide: np.ndarray, radius: int, gate: float,
               scale: float, axis=None, tilted=False) -> np.ndarray:
    """The definition written pixel by pixel, the window clamped to the image (edge
    replication): the square, or the line along ``axis``; ``tilted``, the gate measured from
    the slope through the pixel along each axis of the window."""
    height, width = disparity.shape
    out = np.zeros_like(disparity, dtype=np.float64)
    rows = [0] if axis == 1 else range(-radius, radius + 1)
    cols = [0] if axis == 0 else range(-radius, radius + 1)

    def at(y, x):
        return disparity[min(max(y, 0), height - 1), min(max(x, 0), width - 1)]

    def slope(y, x, sy, sx):   # along (sy, sx): from the window's ends, 0 across an edge
        ahead = at(y + radius * sy, x + radius * sx) - at(y, x)
        behind = at(y, x) - at(y - radius * sy, x - radius * sx)
        if abs(ahead - behind) >= gate or abs(ahead + behind) > 2 * radius:
            return 0.0
        return (ahead + behind) / (2 * radius)

    for y in range(height):
        for x in range(width):
            total = weights = 0.0
            tilt_y = slope(y, x, 1, 0) if tilted and axis != 1 else 0.0
            tilt_x = slope(y, x, 0, 1) if tilted and axis != 0 else 0.0
            for dy in rows:
                for dx in cols:
                    qy, qx = min(max(y + dy, 0), height - 1), min(max(x + dx, 0), width - 1)
                    expected = disparity[y, x] + dy * tilt_y + dx * tilt_x
                    if abs(disparity[qy, qx] - expected) >= gate:
                        continue
                    weight = np.exp(-np.abs(guide[qy, qx] - guide[y, x]).sum() / scale)
                    total += weight * disparity[qy, qx]
                    weights += weight
            out[y, x] = total / weights
    return out


@pytest.mark.parametrize("shape,radius,gate,scale", [((9, 11, 3), 1, 1.0, 0.1),
                                                     ((7, 6, 1), 2, 0.6, 0.05),
                                                     ((5, 13, 3), 3, 2.5, 1.0)])
def test_matches_the_loop_reference(shape, radius, gate, scale):
    rng = np.random.default_rng(sum(shape) + radius)
    guide = rng.random(shape).astype(np.float32)
    # Two surfaces (a ramp and a plateau) with noise: some neighbours pass the gate, some not.
    disparity = np.where(np.arange(shape[1]) < shape[1] // 2, np.arange(shape[1]) * 0.4, 9.0)
    disparity = (disparity + rng.normal(0, 0.5, shape[:2])).astype(np.float32)
    got = gated_bilateral_mean(jnp.asarray(disparity), jnp.asarray(guide), radius=radius,
                               gate=gate, colour_scale=scale)
    np.testing.assert_allclose(np.asarray(got), _reference(disparity, guide, radius, gate, scale),
                               rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("axis", [0, 1])
@pytest.mark.parametrize("shape,radius,gate,scale", [((9, 11, 3), 1, 1.0, 0.1),
                                                     ((6, 7, 1), 3, 2.5, 1.0)])
def test_the_line_mean_matches_the_loop_reference(shape, radius, gate, scale, axis):
    rng = np.random.default_rng(sum(shape) + radius + axis)
    guide = rng.random(shape).astype(np.float32)
    disparity = (np.where(np.arange(shape[1]) < shape[1] // 2, 2.0, 5.0)
                 + rng.normal(0, 0.6, shape[:2])).astype(np.float32)
    got = gated_bilateral_line_mean(jnp.asarray(disparity), jnp.asarray(guide), radius=radius,
                                    gate=gate, colour_scale=scale, axis=axis)
    np.testing.assert_allclose(np.asarray(got),
                               _reference(disparity, guide, radius, gate, scale, axis),
                               rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("separable", [False, True])
def test_the_passes_match_the_loop_reference_applied_in_turn(separable):
    """Two passes (of the square, or of a row then a column each) under one jit: the loop
    reference applied pass after pass."""
    rng = np.random.default_rng(5)
    guide = rng.random((8, 12, 3)).astype(np.float32)
    disparity = (np.where(np.arange(12) < 6, 3.0, 7.0)
                 + rng.normal(0, 0.7, (8, 12))).astype(np.float32)
    smooth = jax.jit(lambda d, g: gated_bilateral_smoothing(
        d, g, radius=2, gate=1.5, colour_scale=0.2, iterations=2, separable=separable))
    got = np.asarray(smooth(jnp.asarray(disparity), jnp.asarray(guide)))
    expected = disparity.astype(np.float64)
    for _ in range(2):
        for axis in ((1, 0) if separable else (None,)):
            expected = _reference(expected, guide, 2, 1.5, 0.2, axis)
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-5)


def _slanted(shape, rng):
    """A steep ramp (1.4 px per row, 0.5 per column) beside a plateau, with noise: the far
    neighbours of the ramp fail an untilted gate of 1.5 and pass a tilted one."""
    height, width = shape[:2]
    ramp = 1.4 * np.arange(height)[:, None] + 0.5 * np.arange(width)[None]
    disparity = np.where(np.arange(width)[None] < width // 2, ramp, 30.0)
    return (disparity + rng.normal(0, 0.3, (height, width))).astype(np.float32)


@pytest.mark.parametrize("axis", [None, 0, 1])
@pytest.mark.parametrize("shape,radius,gate,scale", [((9, 12, 3), 2, 1.5, 0.2),
                                                     ((8, 10, 1), 3, 1.0, 1.0)])
def test_the_tilted_gate_matches_the_loop_reference(shape, radius, gate, scale, axis):
    rng = np.random.default_rng(sum(shape) + radius)
    guide = rng.random(shape).astype(np.float32)
    disparity = _slanted(shape, rng)
    options = dict(radius=radius, gate=gate, colour_scale=scale, tilted=True)
    if axis is None:
        got = gated_bilateral_mean(jnp.asarray(disparity), jnp.asarray(guide), **options)
    else:
        got = gated_bilateral_line_mean(jnp.asarray(disparity), jnp.asarray(guide), axis=axis,
                                        **options)
    expected = _reference(disparity, guide, radius, gate, scale, axis, tilted=True)
    np.testing.assert_allclose(np.asarray(got), expected, rtol=1e-5, atol=1e-5)
    # The tilt changes the result on the ramp (by far more than the tolerance above): the
    # test is not the untilted filter's.
    assert np.abs(expected - _reference(disparity, guide, radius, gate, scale, axis)).max() > 1e-3


@pytest.mark.parametrize("separable", [False, True])
def test_tilted_passes_match_the_loop_reference_applied_in_turn(separable):
    rng = np.random.default_rng(7)
    guide = rng.random((9, 12, 3)).astype(np.float32)
    disparity = _slanted((9, 12), rng)
    smooth = jax.jit(lambda d, g: gated_bilateral_smoothing(
        d, g, radius=2, gate=1.5, colour_scale=0.2, iterations=2, separable=separable,
        tilted=True))
    got = np.asarray(smooth(jnp.asarray(disparity), jnp.asarray(guide)))
    expected = disparity.astype(np.float64)
    for _ in range(2):
        for axis in ((1, 0) if separable else (None,)):
            expected = _reference(expected, guide, 2, 1.5, 0.2, axis, tilted=True)
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-5)


def test_a_tilted_gate_keeps_a_steep_plane_and_a_depth_edge():
    """A plane steeper than the gate per pixel is left as it is (untilted, the gate cuts it
    into uneven windows), and a step stays a step."""
    guide = jnp.zeros((8, 12, 1))
    plane = (1.5 * jnp.arange(8)[:, None] + 0.2 * jnp.arange(12)[None]).astype(jnp.float32)
    out = gated_bilateral_mean(plane, guide, radius=2, gate=1.0, colour_scale=0.1, tilted=True)
    np.testing.assert_allclose(np.asarray(out)[2:-2, 2:-2], np.asarray(plane)[2:-2, 2:-2],
                               atol=1e-4)
    step = jnp.where(jnp.arange(12) < 6, 2.0, 8.0)[None].repeat(8, 0)
    for axis in (0, 1):
        out = gated_bilateral_line_mean(step, guide, radius=2, gate=1.0, colour_scale=0.1,
                                        axis=axis, tilted=True)
        np.testing.assert_array_equal(np.asarray(out), np.asarray(step))


def test_the_line_mean_refuses_another_axis():
    with pytest.raises(ValueError, match="axis"):
        gated_bilateral_line_mean(jnp.zeros((4, 5)), jnp.zeros((4, 5, 1)), radius=1, gate=1.0,
                                  colour_scale=0.1, axis=2)


def test_keeps_depth_edges_and_planes():
    """A step larger than the gate stays a step, and a plane (no step) is left as it is."""
    guide = jnp.zeros((6, 10, 1))
    step = jnp.where(jnp.arange(10) < 5, 2.0, 8.0)[None].repeat(6, 0)
    out = gated_bilateral_mean(step, guide, radius=2, gate=1.0, colour_scale=0.1)
    np.testing.assert_array_equal(np.asarray(out), np.asarray(step))
    plane = (0.3 * jnp.arange(10)[None] + 0.1 * jnp.arange(6)[:, None]).astype(jnp.float32)
    out = gated_bilateral_mean(plane, guide, radius=1, gate=1.0, colour_scale=0.1)
    np.testing.assert_allclose(np.asarray(out)[1:-1, 1:-1], np.asarray(plane)[1:-1, 1:-1],
                               atol=1e-5)


def test_refuses_a_guide_of_another_size():
    with pytest.raises(ValueError, match="guide"):
        gated_bilateral_mean(jnp.zeros((4, 5)), jnp.zeros((4, 6, 3)), radius=1, gate=1.0,
                             colour_scale=0.1)
