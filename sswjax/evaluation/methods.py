"""Named stereo methods for evaluation: SSW, its ablations, the baseline aggregators and peers.

Conventions: a method is a callable ``(left, right, ndisp) -> float32 (H, W)`` dense disparity
taking images as read from disk (see :mod:`sswjax.evaluation.runner`). SSW variants are the pipeline
with some parameters changed (:data:`SSW_VARIANTS`); the baselines replace only the aggregation
step (Table 1 of the paper: BF, GF, iGF, MF); peers are other projects' matchers
(:mod:`sswjax.evaluation.peers`). With shape buckets an SSW variant is a :class:`BucketedSSW`, which
:func:`sswjax.evaluation.evaluate_scenes` runs grouped by bucket and sharded over all JAX devices.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator, Sequence

import numpy as np

from sswjax.api import ShapeBuckets, match
from sswjax.batching import iter_match_scenes
from sswjax.params import Params, default_params
from sswjax.registry import PEERS, method_names, variant_changes

Method = Callable[[np.ndarray, np.ndarray, int], np.ndarray]


@dataclasses.dataclass(frozen=True)
class BucketedSSW:
    """An SSW variant on bucketed shapes, a :class:`sswjax.evaluation.BatchedMethod`.

    Called on one pair it is ``sswjax.match(left, right, ndisp, params=params, buckets=buckets)``;
    :meth:`match_many` gives the same maps from
    :func:`sswjax.batching.iter_match_scenes`: pairs grouped by bucket, one pair per device
    per call, sharded over ``devices`` (default: all ``jax.devices()``).
    """

    params: Params
    buckets: ShapeBuckets
    devices: tuple | None = None

    def __call__(self, left, right, ndisp: int) -> np.ndarray:
        """float32 (H, W) disparity of one pair."""
        return match(left, right, ndisp, params=self.params, buckets=self.buckets)

    def match_many(
        self, pairs: Sequence[tuple[np.ndarray, np.ndarray]], ndisps: Sequence[int]
    ) -> Iterator[tuple[int, np.ndarray, float]]:
        """``(index, float32 (H, W) disparity, seconds)`` per pair, a step's pairs at a time;
        ``seconds`` is the step's wall time divided by its number of pairs."""
        return iter_match_scenes(pairs, ndisps, params=self.params, buckets=self.buckets,
                                 devices=self.devices)


def make_method(
    name: str, *, params: Params | None = None, buckets: ShapeBuckets | None = None,
    devices=None,
) -> Method:
    """The method called ``name`` as ``(left, right, ndisp) -> disparity``.

    Parameters
    ----------
    name : str
        One of :func:`sswjax.registry.method_names`.
    params : Params, optional
        Base parameters of the SSW variants (default: the ``accurate`` preset,
        :func:`sswjax.params.default_params`); ignored by peers.
    buckets : ShapeBuckets, optional
        Shape bucketing of the SSW variants (see :func:`sswjax.match`); with it they are
        :class:`BucketedSSW` (batched evaluation over ``devices``).
    devices : sequence of jax.Device, optional
        Devices of the batched evaluation (default: all ``jax.devices()``); used only with
        ``buckets``.

    Examples
    --------
    >>> method = make_method("gf")
    >>> sorted(method_names())[:4]
    ['bf', 'bm', 'box', 'gf']
    """
    if name in PEERS:
        return PEERS[name].fn
    if name not in method_names():
        raise ValueError(f"unknown method {name!r}; choose from {', '.join(method_names())}")
    variant = (default_params() if params is None else params).replace(**variant_changes(name))
    if buckets is not None:
        return BucketedSSW(variant, buckets, None if devices is None else tuple(devices))

    def run(left, right, ndisp):
        return match(left, right, ndisp, params=variant)

    return run


def submission_name(name: str) -> str:
    """MiddEval3 file-name form of a method name: ``"ssw-noseg"`` -> ``"SSWNOSEG"``."""
    return "".join(c for c in name.upper() if c.isalnum())
