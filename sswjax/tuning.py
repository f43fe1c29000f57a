"""Differentiable objective for the gradient-based parameter search (optax).

The search runs the *same* functions as inference: :func:`sswjax.pipeline.aggregated_cost`
(cost, SLIC, segment-side-window aggregation), then the optimiser of ``Params.optimizer`` if
any (``"sgm"``: :func:`sswjax.stages.sgm.semi_global` through the registry, in float32, see
:data:`DIFFERENTIABLE_STATIC`), then :func:`sswjax.stages.selection.soft_argmin` in place of the
winner-takes-all. The loss is a smooth L1 (Huber, delta 1 px) against the ground truth over
valid non-occluded pixels.

Search spaces: ``searched`` (a tuple of ``DynamicParams`` fields; :data:`SEARCHED` for the
paper's pipeline, :data:`SGM_SEARCHED` for the semi-global one) picks the raw keys
(:func:`raw_keys`); the other fields stay at their ``base`` values. Reparametrisation (``raw``
is a dict of unconstrained float32 scalars):

* ``tad_weight, gradient_weight, census_weight``: a softmax simplex of three logits, so
  ``a + b + c = 1`` (the hand-set sum). WTA is invariant to the overall scale of the cost but
  soft-argmin is not; fixing the sum and learning a separate ``temperature`` keeps the two apart.
* ``tad_truncation``: sigmoid into ``TRUNCATION_RANGES["tad_truncation"]``;
  ``gradient_truncation`` likewise.
* ``segment_weight``, ``sgm_p1``, ``sgm_p2``, ``sgm_sigma``: floor + softplus
  (:data:`SOFTPLUS_FLOORS`; sigma's floor keeps its division finite). Near its small starting
  values softplus is about exp, so Adam's steps on the raw value are relative steps.
* ``temperature`` of the soft-argmin: softplus (plus a floor). It is a search-only quantity, not
  a :class:`~sswjax.params.Params` field.

Not searched by gradient (no useful gradient on the soft path): ``slic_compactness`` (enters only
the SLIC assignment argmin) and ``lr_tolerance`` (the left-right check is not on the soft path).
They are kept at the values of the initial ``Params`` (or can be put in an outer grid), as are all
static fields (radii, census window, superpixel count, iterations).

Optimiser: :func:`make_optimizer` is Adam wrapped in ``optax.multi_transform``; the raw keys
listed as frozen are labelled ``"frozen"`` and get ``optax.set_to_zero()`` (a zero update, no Adam
moments), so freezing is part of the optimiser and :func:`make_update_step` knows nothing of it.

Devices: :func:`make_update_step` splits each crop batch over a 1-D mesh of all JAX devices
(``jax.sharding``; padded with zero-weight crops to a multiple of the device count) with the
parameters and optimizer state replicated, so one step uses every CPU device, GPU or TPU core
and gives the one-device result.

Array conventions: images float32 ``(H, W, C)`` in [0, 1]; ground truth float32 ``(H, W)`` in
pixels, non-finite = unknown; ``valid`` bool ``(H, W)`` (non-occluded with known ground truth).
"""

from __future__ import annotations

import functools
import pickle

import jax
import jax.numpy as jnp
import numpy as np
import optax
from jax.sharding import NamedSharding, PartitionSpec

from sswjax.batching import BATCH_AXIS, device_mesh, pad_batch
from sswjax.params import DynamicParams, Params, StaticParams
from sswjax.pipeline import aggregated_cost, superpixels
from sswjax.registry import OPTIMIZERS
from sswjax.stages.selection import soft_argmin
from sswjax.stages.sgm import as_volume

WEIGHTS = ("tad_weight", "gradient_weight", "census_weight")
TRUNCATION_RANGES = {"tad_truncation": (0.002, 0.3), "gradient_truncation": (0.005, 1.0)}
SOFTPLUS_FLOORS = {"segment_weight": 0.0, "sgm_p1": 0.0, "sgm_p2": 0.0, "sgm_sigma": 1e-3}
"""Fields searched through ``floor + softplus(raw)``: >= their floor (``sgm_sigma`` divides)."""
SEARCHED = WEIGHTS + tuple(TRUNCATION_RANGES) + ("segment_weight",)
"""Dynamic fields searched by gradient for the paper's pipeline (the default ``searched``)."""
SGM_SEARCHED = tuple(TRUNCATION_RANGES) + ("sgm_p1", "sgm_p2", "sgm_sigma")
"""Dynamic fields searched through the semi-global optimiser (``optimizer="sgm"``): the penalties
and the cost truncations; the cost weights stay fixed (searching them overfits, tuning/README)."""
FIXED = ("slic_compactness", "lr_tolerance")
"""Dynamic fields with no useful gradient on the soft path: held fixed."""
RAW_KEYS = ("weight_logits", "tad_truncation", "gradient_truncation", "segment_weight",
            "temperature")
"""Raw keys of the default (paper) search space."""
ALL_RAW_KEYS = RAW_KEYS + ("sgm_p1", "sgm_p2", "sgm_sigma")
"""Every raw key a search space can have (what ``freeze`` may name)."""
MIN_TEMPERATURE = 1e-4
HUBER_DELTA = 1.0


def _softplus_inverse(y):
    y = np.asarray(y, np.float64)
    return np.where(y > 20, y, np.log(np.expm1(np.maximum(y, 1e-12))))


def _logit(p):
    p = np.clip(np.asarray(p, np.float64), 1e-6, 1 - 1e-6)
    return np.log(p) - np.log1p(-p)


def raw_keys(searched) -> tuple[str, ...]:
    """The raw keys of the search space of the dynamic fields ``searched``.

    The three cost weights are searched together (one ``"weight_logits"`` key) or not at all;
    ``"temperature"`` (the soft-argmin's) is always there.

    >>> raw_keys(SGM_SEARCHED)
    ('tad_truncation', 'gradient_truncation', 'sgm_p1', 'sgm_p2', 'sgm_sigma', 'temperature')
    """
    searched = tuple(searched)
    weights = [k for k in searched if k in WEIGHTS]
    if weights and len(weights) != len(WEIGHTS):
        raise ValueError(f"the cost weights are searched all together or not at all, got {weights}")
    unknown = [k for k in searched
               if k not in WEIGHTS and k not in TRUNCATION_RANGES and k not in SOFTPLUS_FLOORS]
    if unknown:
        raise ValueError(f"no reparametrisation for {unknown}; searchable: "
                         f"{WEIGHTS + tuple(TRUNCATION_RANGES) + tuple(SOFTPLUS_FLOORS)}")
    return (("weight_logits",) if weights else ()) + tuple(
        k for k in searched if k not in WEIGHTS) + ("temperature",)


def to_unconstrained(dynamic: DynamicParams, *, temperature: float = 0.02,
                     searched=SEARCHED) -> dict:
    """Raw (unconstrained) search variables of the fields ``searched`` of ``dynamic``, and of a
    soft-argmin temperature.

    Reparametrisation: the weights (if searched) a softmax simplex, normalised to sum to 1 (WTA
    does not change) with centred logits; the truncations a sigmoid into
    :data:`TRUNCATION_RANGES`; ``segment_weight`` and the SGM penalties ``floor + softplus``
    (:data:`SOFTPLUS_FLOORS`). The keys are :func:`raw_keys` of ``searched``; the others stay
    at their ``base`` values in :func:`from_unconstrained`.

    Examples
    --------
    >>> raw = to_unconstrained(DynamicParams(sgm_p2=0.8), searched=SGM_SEARCHED)
    >>> round(float(from_unconstrained(raw)[0].sgm_p2), 4)
    0.8
    """
    raw = {}
    for key in raw_keys(searched):
        if key == "weight_logits":
            weights = np.array([float(getattr(dynamic, k)) for k in WEIGHTS], np.float64)
            if weights.sum() <= 0:
                raise ValueError("tad, gradient and census weights must not all be zero")
            logits = np.log(np.maximum(weights / weights.sum(), 1e-6))
            raw[key] = jnp.asarray(logits - logits.mean(), jnp.float32)
        elif key in TRUNCATION_RANGES:
            low, high = TRUNCATION_RANGES[key]
            raw[key] = jnp.asarray(_logit((float(getattr(dynamic, key)) - low) / (high - low)),
                                   jnp.float32)
        elif key in SOFTPLUS_FLOORS:
            value = float(getattr(dynamic, key)) - SOFTPLUS_FLOORS[key]
            raw[key] = jnp.asarray(_softplus_inverse(value), jnp.float32)
    raw["temperature"] = jnp.asarray(_softplus_inverse(temperature - MIN_TEMPERATURE), jnp.float32)
    return raw


def from_unconstrained(raw: dict, *, base: DynamicParams = DynamicParams()
                       ) -> tuple[DynamicParams, jax.Array]:
    """Constrained ``DynamicParams`` (fields not in ``raw`` taken from ``base``) and the
    temperature; the inverse of :func:`to_unconstrained` for any search space."""
    values = {}
    for key, value in raw.items():
        if key == "weight_logits":
            weights = jax.nn.softmax(value)
            values.update(zip(WEIGHTS, (weights[0], weights[1], weights[2])))
        elif key in TRUNCATION_RANGES:
            low, high = TRUNCATION_RANGES[key]
            values[key] = low + (high - low) * jax.nn.sigmoid(value)
        elif key in SOFTPLUS_FLOORS:
            values[key] = SOFTPLUS_FLOORS[key] + jax.nn.softplus(value)
        elif key != "temperature":
            raise ValueError(f"unknown raw key {key!r}; expected some of {ALL_RAW_KEYS}")
    temperature = MIN_TEMPERATURE + jax.nn.softplus(raw["temperature"])
    return base._replace(**values), temperature


def searched_fields(raw: dict) -> tuple[str, ...]:
    """The dynamic fields a raw dict sets (the inverse of :func:`raw_keys`)."""
    return tuple(f for k in raw if k != "temperature"
                 for f in (WEIGHTS if k == "weight_logits" else (k,)))


def raw_to_params(raw: dict, base: Params) -> Params:
    """``base`` with its searched dynamic fields replaced by those of ``raw`` (plain floats)."""
    dynamic, _ = from_unconstrained(raw, base=base.dynamic)
    return base.replace(**{k: float(getattr(dynamic, k)) for k in searched_fields(raw)})


def valid_mask(ground_truth, nonocc, *, ndisp) -> jax.Array:
    """Pixels the loss uses: known ground truth, non-occluded, inside the disparity range and
    whose match ``x - gt`` falls inside the image (crop)."""
    gt = jnp.asarray(ground_truth)
    columns = jnp.arange(gt.shape[1])[None, :]
    finite = jnp.isfinite(gt)
    safe = jnp.where(finite, gt, 0.0)
    return finite & nonocc & (safe >= 0) & (safe <= ndisp - 1) & (columns - safe >= 0)


DIFFERENTIABLE_STATIC = {"sgm_dtype": "float32"}
"""Static switches whose inference value is not differentiable, and the value the search runs
with (the int16 paths of :func:`sswjax.stages.sgm.semi_global` round: zero gradients). A field
that ``StaticParams`` does not have is skipped."""


def differentiable_static(static: StaticParams) -> StaticParams:
    """``static`` with :data:`DIFFERENTIABLE_STATIC` applied (what :func:`soft_disparity` runs).

    >>> differentiable_static(StaticParams()) == StaticParams()._replace(
    ...     **{k: v for k, v in DIFFERENTIABLE_STATIC.items() if k in StaticParams._fields})
    True
    """
    return static._replace(**{k: v for k, v in DIFFERENTIABLE_STATIC.items()
                              if k in static._fields})


OUT_OF_RANGE_COST = 1e4
"""Cost of the padded disparities ``>= scene_ndisp``: high but finite, as the pipeline's (the
optimiser's recursion turns +inf into NaN)."""


def soft_disparity(raw, left, right, *, static: StaticParams, ndisp: int, base: DynamicParams,
                   scene_ndisp=None) -> jax.Array:
    """Soft-argmin disparity ``(H, W)`` of the inference volume with the parameters of ``raw``.

    The volume is that of the pipeline before its winner-takes-all: the aggregated cost
    (:func:`sswjax.pipeline.aggregated_cost`), then, when ``static.optimizer`` is not
    ``"none"``, the optimiser of :data:`sswjax.registry.OPTIMIZERS` (e.g. ``"sgm"``:
    :func:`sswjax.stages.sgm.semi_global`, differentiable in its penalties), as
    ``sswjax.pipeline`` applies it.

    ``scene_ndisp`` (traced scalar, optional) masks disparities ``>= scene_ndisp`` so that a
    common, padded ``ndisp`` gives each scene its own range (the cost of every slice is computed
    and aggregated independently, so the kept slices are those of the scene's own ``ndisp``;
    as in the pipeline, the optimiser sees them at :data:`OUT_OF_RANGE_COST`). The static
    switches of :data:`DIFFERENTIABLE_STATIC` are set to their differentiable values.

    Parameters
    ----------
    raw : dict of float32 arrays
        Search variables (:func:`to_unconstrained`).
    left, right : float32 (H, W, C), C in {1, 3}, values in [0, 1]
    static : StaticParams
    ndisp : int
        Disparities of the volume (static).
    base : DynamicParams
        Values of the fields ``raw`` does not set.
    scene_ndisp : int32 scalar, optional

    Returns
    -------
    float32 (H, W), in [0, ndisp - 1].
    """
    dynamic, temperature = from_unconstrained(raw, base=base)
    params = Params(dynamic=dynamic, static=differentiable_static(static))
    cost = aggregated_cost(left, right, params, ndisp=ndisp)
    d = jnp.arange(ndisp)[:, None, None]
    if scene_ndisp is not None:
        cost = jnp.where(d < scene_ndisp, cost, OUT_OF_RANGE_COST)
    optimizer = OPTIMIZERS[static.optimizer]
    if optimizer.fn is not None:
        labels, num_segments = superpixels(left, params)
        cost = as_volume(optimizer.fn(cost, left, labels=labels if num_segments else None,
                                      params=params))
        if scene_ndisp is not None:
            cost = jnp.where(d < scene_ndisp, cost, OUT_OF_RANGE_COST)
    return soft_argmin(cost, temperature=temperature)


def smooth_l1(error, *, delta: float = HUBER_DELTA):
    """Huber loss of an error (quadratic below ``delta`` pixels, linear above)."""
    a = jnp.abs(error)
    return jnp.where(a < delta, 0.5 * a * a / delta, a - 0.5 * delta)


def loss(raw, left, right, ground_truth, valid, *, static: StaticParams, ndisp: int,
         base: DynamicParams = DynamicParams(), scene_ndisp=None):
    """Mean smooth-L1 of the soft-argmin disparity over ``valid`` pixels of one crop.

    Returns ``(loss, count)``; the temperature is part of ``raw``.
    """
    disparity = soft_disparity(raw, left, right, static=static, ndisp=ndisp, base=base,
                               scene_ndisp=scene_ndisp)
    gt = jnp.where(valid, ground_truth, 0.0)
    per_pixel = jnp.where(valid, smooth_l1(disparity - gt), 0.0)
    count = valid.sum()
    return per_pixel.sum() / jnp.maximum(count, 1), count


def batch_loss(raw, lefts, rights, gts, valids, scene_ndisps, *, static, ndisp, base):
    """Pixel-weighted mean loss over a batch of crops (``jax.vmap``), and the pixel count."""
    per_crop, counts = jax.vmap(
        lambda l, r, g, v, n: loss(raw, l, r, g, v, static=static, ndisp=ndisp, base=base,
                                   scene_ndisp=n)
    )(lefts, rights, gts, valids, scene_ndisps)
    total = jnp.maximum(counts.sum(), 1)
    return (per_crop * counts).sum() / total


def shard_crops(batch, mesh):
    """A crop batch on ``mesh`` (:func:`sswjax.batching.device_mesh`), split on its batch axis.

    A batch whose size is not a multiple of the device count is padded with copies of its last
    crop whose ``valid`` mask is all False: they have a zero pixel count, so they change neither
    :func:`batch_loss` nor its gradient.

    Parameters
    ----------
    batch : (lefts, rights, gts, valids, scene_ndisps)
        float32 (B, H, W, C), float32 (B, H, W, C), float32 (B, H, W), bool (B, H, W), int32 (B,).
    mesh : jax.sharding.Mesh
        1-D, axis ``"batch"``.

    Returns
    -------
    tuple of jax.Array, the same five with B rounded up to a multiple of ``mesh.size``.
    """
    size = len(batch[0])
    lefts, rights, gts, valids, scene_ndisps = pad_batch(batch, mesh.size)
    valids = valids.copy()
    valids[size:] = False
    sharding = NamedSharding(mesh, PartitionSpec(BATCH_AXIS))
    return jax.device_put((lefts, rights, gts, valids, scene_ndisps), sharding)


def freeze_labels(frozen):
    """optax labels of a ``raw`` dict: ``"frozen"`` for the keys in ``frozen``, else ``"train"``.

    Returns a function of ``raw`` (as ``optax.multi_transform`` takes it). Raises ``ValueError``
    for a key not in :data:`ALL_RAW_KEYS`.
    """
    frozen = tuple(frozen)
    unknown = sorted(set(frozen) - set(ALL_RAW_KEYS))
    if unknown:
        raise ValueError(f"unknown raw keys {unknown}; expected some of {ALL_RAW_KEYS}")
    return lambda raw: {k: "frozen" if k in frozen else "train" for k in raw}


def make_optimizer(learning_rate: float, *, frozen=()) -> optax.GradientTransformation:
    """Adam on the raw keys not in ``frozen``; the keys in ``frozen`` do not move.

    ``optax.multi_transform`` routes the leaves labelled by :func:`freeze_labels`: ``"train"``
    to ``optax.adam(learning_rate)``, ``"frozen"`` to ``optax.set_to_zero()``. Adam is elementwise,
    so the trained leaves follow exactly the path they would with a zero gradient on the frozen
    ones (which gives Adam a zero update). The state holds Adam moments for the trained leaves
    only; its structure depends on ``frozen`` (see :func:`load_checkpoint`).
    """
    return optax.multi_transform(
        {"train": optax.adam(learning_rate), "frozen": optax.set_to_zero()},
        freeze_labels(frozen),
    )


def make_update_step(optimizer, *, static: StaticParams, ndisp: int, base: DynamicParams,
                     devices=None):
    """``(raw, opt_state, batch) -> (raw, opt_state, loss)``: one jitted optax step, sharded.

    ``batch`` = ``(lefts, rights, gts, valids, scene_ndisps)`` (see :func:`shard_crops`) is
    split over a 1-D mesh of ``devices`` (default: all ``jax.devices()``) on its batch axis, any
    size (padded with zero-weight crops to a multiple of the device count; a multiple wastes
    nothing); ``raw`` and ``opt_state`` are replicated, so ``jit`` partitions the vmapped loss
    and its gradient over the devices and all-reduces the sums. The returned ``raw`` and
    ``opt_state`` are replicated. Every key of ``raw`` gets its gradient; to hold some fixed,
    build ``optimizer`` with :func:`make_optimizer` (``frozen=...``)."""
    mesh = device_mesh(devices=devices)
    replicated = NamedSharding(mesh, PartitionSpec())

    def objective(raw, batch):
        return batch_loss(raw, *batch, static=static, ndisp=ndisp, base=base)

    @functools.partial(jax.jit, out_shardings=replicated)
    def sharded_step(raw, opt_state, batch):
        value, grads = jax.value_and_grad(objective)(raw, batch)
        updates, opt_state = optimizer.update(grads, opt_state, raw)
        return optax.apply_updates(raw, updates), opt_state, value

    def update_step(raw, opt_state, batch):
        raw, opt_state = jax.device_put((raw, opt_state), replicated)
        return sharded_step(raw, opt_state, shard_crops(batch, mesh))

    return update_step


# --- folds and crops -----------------------------------------------------------------------


def dataset_folds(names) -> list[tuple[str, list[str]]]:
    """Leave-one-dataset-out folds: ``[(held_out, [the others]), ...]``, one per data set.

    The search of each fold sees crops of the other sets only; its held-out set is then scored
    with the full pipeline (``tuning/search.py --folds datasets``).

    Parameters
    ----------
    names : sequence of str
        At least two distinct data set names.

    Returns
    -------
    list of (str, list of str), in the order of ``names``.

    Examples
    --------
    >>> dataset_folds(["MiddEval3", "KITTI2012", "Middlebury2001"])[1]
    ('KITTI2012', ['MiddEval3', 'Middlebury2001'])
    """
    names = list(names)
    if len(names) < 2 or len(set(names)) != len(names):
        raise ValueError(f"need at least two distinct data sets, got {names}")
    return [(held, [n for n in names if n != held]) for held in names]




MAX_CROP_TRIES = 50
"""Draws of a crop position before :func:`random_crops` takes the last one drawn."""


def _crop_valid(scene, sl, width: int) -> np.ndarray:
    """The loss's pixels of a crop: known ground truth, non-occluded (all known pixels when the
    scene has no mask), inside the scene's range, match inside the crop."""
    gt = scene.ground_truth[sl]
    finite = np.isfinite(gt)
    safe = np.where(finite, gt, 0.0)
    columns = np.arange(width)[None, :]
    nonocc = True if scene.mask is None else scene.mask[sl] == 255
    return finite & nonocc & (safe <= scene.ndisp - 1) & (columns - safe >= 0)


def random_crops(scenes, rng: np.random.Generator, *, batch: int, height: int, width: int,
                 min_valid: float = 0.0):
    """A batch of fixed-size random crops ``(lefts, rights, gts, valids, scene_ndisps)``.

    ``scenes`` are :class:`~sswjax.data.datasets.StereoScene` with float32 images of one
    channel count (see :func:`prepare_scene`). Crops are drawn uniformly over scenes, then
    positions. ``min_valid`` > 0 (for sparse ground truth such as KITTI's) redraws the position
    until at least that share of the crop's pixels are valid (at most :data:`MAX_CROP_TRIES`
    draws); 0 draws once, as before it existed (the same random stream).

    Returns
    -------
    float32 (B, h, w, C), float32 (B, h, w, C), float32 (B, h, w) (unknown = 0),
    bool (B, h, w), int32 (B,)

    Examples
    --------
    >>> from sswjax.data.datasets import StereoScene
    >>> image = np.zeros((30, 60, 1), np.float32)
    >>> gt = np.full((30, 60), np.nan, np.float32); gt[20:] = 2.0    # known at the bottom only
    >>> scene = StereoScene("s", image, image, 8, gt, None, None)
    >>> crops = random_crops([scene], np.random.default_rng(0), batch=4, height=10, width=20,
    ...                      min_valid=0.5)
    >>> bool(crops[3].mean(axis=(1, 2)).min() >= 0.5)
    True
    """
    out = [[], [], [], [], []]
    for _ in range(batch):
        s = scenes[rng.integers(len(scenes))]
        h, w = s.left.shape[:2]
        for _ in range(MAX_CROP_TRIES if min_valid > 0 else 1):
            y = int(rng.integers(0, h - height + 1))
            x = int(rng.integers(0, w - width + 1))
            sl = (slice(y, y + height), slice(x, x + width))
            valid = _crop_valid(s, sl, width)
            if valid.mean() >= min_valid:
                break
        out[0].append(s.left[sl])
        out[1].append(s.right[sl])
        out[2].append(np.where(np.isfinite(s.ground_truth[sl]), s.ground_truth[sl], 0.0).astype(np.float32))
        out[3].append(valid)
        out[4].append(s.ndisp)
    return tuple(np.stack(a) for a in out[:4]) + (np.asarray(out[4], np.int32),)


def prepare_scene(scene, *, channels: int | None = None):
    """A scene with float32 ``[0, 1]`` images, as the pipeline takes them.

    ``channels=3`` repeats a gray pair into three equal channels, so that gray and colour
    scenes share a compiled step: every stage of the cost and of the optimiser reads the
    channel mean or the BT.601 luma, which are the gray value again (up to rounding).
    """
    from sswjax.api import prepare_pair

    left, right = prepare_pair(scene.left, scene.right)
    if channels is not None and left.shape[-1] != channels:
        if (left.shape[-1], channels) != (1, 3):
            raise ValueError(f"cannot turn {left.shape[-1]} channels into {channels}")
        left, right = np.repeat(left, 3, axis=-1), np.repeat(right, 3, axis=-1)
    return scene._replace(left=left, right=right)


def crop_segments(n_segments: int, crop_area: int, image_area: float) -> int:
    """Superpixel count giving a crop the superpixel size of the full image."""
    if n_segments == 0:
        return 0
    return max(1, int(round(n_segments * crop_area / image_area)))


# --- checkpoints ---------------------------------------------------------------------------


def save_checkpoint(path, *, raw, opt_state, step: int, rng: np.random.Generator, extra=None):
    """Pickle raw params, optimizer state, step and RNG state (atomically)."""
    from sswjax.data.io import atomic_output

    state = {
        "raw": jax.tree_util.tree_map(np.asarray, raw),
        "opt_state": jax.tree_util.tree_map(np.asarray, opt_state),
        "step": int(step),
        "rng": rng.bit_generator.state,
        "extra": extra or {},
    }
    with atomic_output(path) as tmp, open(tmp, "wb") as handle:
        pickle.dump(state, handle)


def load_checkpoint(path, *, opt_state_like):
    """Inverse of :func:`save_checkpoint`: ``(raw, opt_state, step, rng, extra)``.

    ``opt_state_like`` (e.g. ``optimizer.init(raw)``) gives the pytree structure to restore; a
    checkpoint whose optimizer state has another structure (another ``frozen`` set of
    :func:`make_optimizer`, or written before the optimizer was a ``multi_transform``) raises
    ``ValueError``.
    """
    with open(path, "rb") as handle:
        state = pickle.load(handle)
    raw = {k: jnp.asarray(v) for k, v in state["raw"].items()}
    leaves, stored = jax.tree_util.tree_flatten(state["opt_state"])
    expected = jax.tree_util.tree_structure(opt_state_like)
    if stored != expected:
        raise ValueError(f"{path}: its optimizer state does not match this optimizer (written "
                         "with another frozen set, or before make_optimizer)")
    opt_state = jax.tree_util.tree_unflatten(expected, [jnp.asarray(x) for x in leaves])
    rng = np.random.default_rng()
    rng.bit_generator.state = state["rng"]
    return raw, opt_state, state["step"], rng, state["extra"]


__all__ = [
    "ALL_RAW_KEYS", "DIFFERENTIABLE_STATIC", "FIXED", "OUT_OF_RANGE_COST", "RAW_KEYS",
    "SEARCHED", "SGM_SEARCHED", "SOFTPLUS_FLOORS", "TRUNCATION_RANGES", "batch_loss",
    "crop_segments", "dataset_folds", "differentiable_static", "freeze_labels",
    "from_unconstrained", "load_checkpoint", "loss", "make_optimizer", "make_update_step",
    "prepare_scene", "random_crops", "raw_keys", "raw_to_params", "save_checkpoint",
    "searched_fields", "shard_crops", "smooth_l1", "soft_disparity", "to_unconstrained",
    "valid_mask",
]
