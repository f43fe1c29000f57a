"""Tests for sswjax.stages.segments: SLIC superpixels and per-segment means.

SLIC quality is compared with scikit-image's SLIC on a real image with two NumPy metrics:

* boundary recall: fraction of ground-truth boundary pixels within 2 px (Chebyshev) of a
  superpixel boundary pixel. Ground truth: strong edges, i.e. pixels whose Sobel gradient
  magnitude of the gray image exceeds its 90th percentile.
* under-segmentation error, the corrected variant of Neubert & Protzel ("Superpixel Benchmark
  and Comparison", Forum Bildverarbeitung 2012), with the Felzenszwalb-Huttenlocher
  segmentation as reference:
  ``UE = (1/N) * sum_G sum_{S : S & G != {}} min(|S & G|, |S - G|)``,
  i.e. every superpixel S overlapping a reference segment G is charged the smaller of its part
  inside G and its part outside G (Achanta et al. 2012 charge the whole |S|, which punishes
  superpixels that only touch G by a few pixels).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import ndimage
from skimage import color as skcolor
from skimage import data, filters, segmentation

from sswjax.stages.segments import segment_mean, slic, slic_grid_shape

N_SEGMENTS = 400


# ----------------------------------------------------------------------------- metric helpers


def boundary_map(labels: np.ndarray) -> np.ndarray:
    """Bool (H, W): pixels with a 4-neighbour of a different label (both sides marked)."""
    boundary = np.zeros(labels.shape, bool)
    vertical = labels[1:] != labels[:-1]
    horizontal = labels[:, 1:] != labels[:, :-1]
    boundary[1:] |= vertical
    boundary[:-1] |= vertical
    boundary[:, 1:] |= horizontal
    boundary[:, :-1] |= horizontal
    return boundary


def boundary_recall(labels: np.ndarray, true_boundary: np.ndarray, *, tolerance: int = 2) -> float:
    """Fraction of ``true_boundary`` pixels within ``tolerance`` px of a boundary of ``labels``."""
    window = np.ones((2 * tolerance + 1, 2 * tolerance + 1), bool)
    near_boundary = ndimage.binary_dilation(boundary_map(labels), structure=window)
    return float(near_boundary[true_boundary].mean())


def undersegmentation_error(labels: np.ndarray, reference: np.ndarray) -> float:
    """Corrected under-segmentation error (Neubert & Protzel 2012), see the module docstring."""
    num_superpixels = int(labels.max()) + 1
    num_reference = int(reference.max()) + 1
    pair_index = reference.ravel().astype(np.int64) * num_superpixels + labels.ravel()
    overlap = np.bincount(pair_index, minlength=num_reference * num_superpixels).reshape(
        num_reference, num_superpixels
    )  # overlap[g, s] = |S_s & G_g|
    superpixel_size = overlap.sum(axis=0)
    charged = np.minimum(overlap, superpixel_size[None, :] - overlap)  # zero where no overlap
    return float(charged.sum() / labels.size)


def mean_spatial_variance(labels: np.ndarray) -> float:
    """Pixel-weighted mean over segments of var(y) + var(x) of the segment's pixels."""
    rows, cols = np.indices(labels.shape)
    flat = labels.ravel()
    count = np.bincount(flat).astype(float)
    total = 0.0
    for coordinate in (rows.ravel(), cols.ravel()):
        mean = np.bincount(flat, coordinate) / np.maximum(count, 1)
        total += np.sum((coordinate - mean[flat]) ** 2)
    return total / labels.size


def test_metric_helpers_on_trivial_cases():
    reference = np.repeat(np.arange(4, dtype=np.int32), 8).reshape(4, 8)  # four horizontal bands
    assert undersegmentation_error(reference, reference) == 0.0
    assert boundary_recall(reference, boundary_map(reference)) == 1.0
    one_segment = np.zeros_like(reference)
    # Each band G (8 px) is covered by the single 32-px superpixel: charged min(8, 24) = 8.
    assert undersegmentation_error(one_segment, reference) == 1.0
    assert boundary_recall(one_segment, boundary_map(reference)) == 0.0


# ----------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def astronaut():
    return (data.astronaut() / 255.0).astype(np.float32)  # (512, 512, 3)


@pytest.fixture(scope="module")
def our_labels(astronaut):
    return np.asarray(slic(jnp.asarray(astronaut), n_segments=N_SEGMENTS, compactness=10.0))


# ----------------------------------------------------------------------------- slic


def test_slic_grid_shape():
    assert slic_grid_shape(512, 512, 400) == (20, 20)
    assert slic_grid_shape(500, 741, 2000) == (37, 54)
    assert slic_grid_shape(10, 1000, 5) == (1, 5)
    assert slic_grid_shape(1000, 10, 5) == (5, 1)
    assert slic_grid_shape(3, 3, 100) == (3, 3)


def test_slic_quality_close_to_skimage(astronaut, our_labels):
    gray = skcolor.rgb2gray(astronaut)
    gradient = filters.sobel(gray)
    strong_edges = gradient > np.percentile(gradient, 90)
    # Object-level reference segmentation (118 segments on this image).
    reference = segmentation.felzenszwalb(astronaut, scale=300, sigma=0.8, min_size=200)

    skimage_labels = segmentation.slic(astronaut, n_segments=N_SEGMENTS, compactness=10, start_label=0)
    # Same algorithm without the connected-components pass, i.e. like ours.
    skimage_unconnected = segmentation.slic(
        astronaut, n_segments=N_SEGMENTS, compactness=10, start_label=0, enforce_connectivity=False
    )

    ours_recall = boundary_recall(our_labels, strong_edges)
    ours_error = undersegmentation_error(our_labels, reference)
    print(f"\nours:                     boundary recall {ours_recall:.3f}, under-segmentation {ours_error:.3f}")
    for name, labels in [("skimage", skimage_labels), ("skimage (no connectivity)", skimage_unconnected)]:
        recall = boundary_recall(labels, strong_edges)
        error = undersegmentation_error(labels, reference)
        print(f"{name + ':':26s} boundary recall {recall:.3f}, under-segmentation {error:.3f}")
        assert ours_recall >= recall - 0.05
        assert ours_error <= error + 0.05


def test_slic_segment_count_and_range(astronaut, our_labels):
    grid_rows, grid_cols = slic_grid_shape(*astronaut.shape[:2], N_SEGMENTS)
    assert our_labels.dtype == np.int32
    assert our_labels.shape == astronaut.shape[:2]
    assert our_labels.min() >= 0 and our_labels.max() < grid_rows * grid_cols
    assert 0.8 * N_SEGMENTS <= len(np.unique(our_labels)) <= 1.2 * N_SEGMENTS


def test_slic_higher_compactness_gives_more_compact_segments(astronaut, our_labels):
    # compactness is traced, so this reuses the compiled function of `our_labels`.
    compact_labels = np.asarray(slic(jnp.asarray(astronaut), n_segments=N_SEGMENTS, compactness=40.0))
    loose_variance = mean_spatial_variance(our_labels)
    compact_variance = mean_spatial_variance(compact_labels)
    assert compact_variance < 0.8 * loose_variance


def test_slic_under_jit_with_traced_compactness(astronaut, our_labels):
    @jax.jit
    def labels_for(image, compactness):
        return slic(image, n_segments=N_SEGMENTS, compactness=compactness)

    labels = labels_for(jnp.asarray(astronaut), jnp.float32(10.0))
    np.testing.assert_array_equal(np.asarray(labels), our_labels)


def test_slic_respects_a_colour_edge_off_the_grid():
    image = np.zeros((60, 90, 3), np.float32)
    image[:, :37] = [0.9, 0.2, 0.1]
    image[:, 37:] = [0.1, 0.3, 0.8]
    labels = np.asarray(slic(jnp.asarray(image), n_segments=24, compactness=10.0))
    left, right = set(np.unique(labels[:, :37])), set(np.unique(labels[:, 37:]))
    assert not left & right


def test_slic_gray_matches_gray_as_rgb(astronaut):
    gray = skcolor.rgb2gray(astronaut[::4, ::4]).astype(np.float32)
    from_gray = np.asarray(slic(jnp.asarray(gray), n_segments=64, compactness=5.0))
    from_rgb = np.asarray(slic(jnp.asarray(np.repeat(gray[..., None], 3, axis=-1)), n_segments=64, compactness=5.0))
    assert from_gray.shape == gray.shape
    assert np.mean(from_gray == from_rgb) > 0.99


@pytest.mark.parametrize(
    ("image", "options", "error"),
    [
        (np.zeros((8, 8, 4), np.float32), {"n_segments": 4}, ValueError),
        (np.zeros((8,), np.float32), {"n_segments": 4}, ValueError),
        (np.zeros((8, 8, 3), np.uint8), {"n_segments": 4}, TypeError),
        (np.zeros((8, 8, 3), np.float32), {"n_segments": 0}, ValueError),
        (np.zeros((8, 8, 3), np.float32), {"n_segments": 4, "compactness": np.ones(2)}, ValueError),
    ],
)
def test_slic_entry_checks(image, options, error):
    with pytest.raises(error):
        slic(image, **options)


# ----------------------------------------------------------------------------- segment_mean


def numpy_segment_mean(values: np.ndarray, labels: np.ndarray) -> np.ndarray:
    result = np.empty_like(values)
    for segment in np.unique(labels):
        inside = labels == segment
        for index in np.ndindex(values.shape[:-2]):
            result[index][inside] = values[index][inside].mean()
    return result


@pytest.fixture(scope="module")
def small_problem():
    rng = np.random.default_rng(1)
    labels = rng.integers(0, 7, size=(9, 11)).astype(np.int32)
    labels[labels == 4] = 5  # leave segment 4 empty
    values = rng.normal(size=(3, 9, 11)).astype(np.float32)
    return values, labels


def test_segment_mean_matches_numpy(small_problem):
    values, labels = small_problem
    ours = np.asarray(segment_mean(jnp.asarray(values), jnp.asarray(labels), num_segments=7))
    assert ours.shape == values.shape and ours.dtype == np.float32
    np.testing.assert_allclose(ours, numpy_segment_mean(values, labels), rtol=1e-5, atol=1e-6)
    ours_2d = np.asarray(segment_mean(jnp.asarray(values[0]), jnp.asarray(labels), num_segments=7))
    np.testing.assert_allclose(ours_2d, ours[0], rtol=1e-6)


def test_segment_mean_gradient(small_problem):
    values, labels = small_problem
    weights = np.random.default_rng(2).normal(size=values.shape).astype(np.float32)

    def weighted_total(v):
        return jnp.sum(jnp.asarray(weights) * segment_mean(v, jnp.asarray(labels), num_segments=7))

    gradient = np.asarray(jax.grad(weighted_total)(jnp.asarray(values)))
    # segment_mean is a symmetric linear map, so the gradient is the segment mean of the weights.
    np.testing.assert_allclose(gradient, numpy_segment_mean(weights, labels), rtol=1e-5, atol=1e-6)
    plain = np.asarray(jax.grad(lambda v: jnp.sum(segment_mean(v, jnp.asarray(labels), num_segments=7)))(values))
    np.testing.assert_allclose(plain, np.ones_like(values), rtol=1e-5)


def test_segment_mean_entry_checks(small_problem):
    values, labels = small_problem
    with pytest.raises(ValueError):
        segment_mean(values, labels[:-1], num_segments=7)
    with pytest.raises(TypeError):
        segment_mean(values, labels.astype(np.float32), num_segments=7)
    with pytest.raises(TypeError):
        segment_mean(values.astype(np.int32), labels, num_segments=7)
    with pytest.raises(ValueError):
        segment_mean(values, labels, num_segments=0)
