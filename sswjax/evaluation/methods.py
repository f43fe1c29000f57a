"""The catalogue of named methods for evaluation: SSW's ablations, the aggregators of Table 1 as
methods, and other projects' matchers (peers).

Conventions: a method is a callable ``(left, right, ndisp) -> float32 (H, W)`` dense disparity
taking images as read from disk (see :mod:`sswjax.evaluation.runner`).

* A **variant** is a set of changes applied on top of the user's parameters with
  :meth:`sswjax.Params.replace` (:data:`VARIANTS`); every aggregator kind of
  :mod:`sswjax.config.aggregation` is a variant too, named after it (the paper's Table 1:
  BF, GF, iGF, MF, and a plain box), replacing only the aggregation.
* A **peer** is another project's matcher run under our protocol (:data:`PEERS`, optional
  dependencies, :mod:`sswjax.evaluation.peers`).

With shape buckets an SSW variant is a :class:`BucketedSSW`, which
:func:`sswjax.evaluation.runner.evaluate_scenes` runs grouped by bucket and sharded over all JAX
devices.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np

from sswjax.api.batch import iter_match_scenes
from sswjax.api.match import match
from sswjax.config import Params, default_params, kinds
from sswjax.evaluation.peers import bm_disparity, pandora_disparity, sgbm_disparity
from sswjax.runtime.buckets import ShapeBuckets

__all__ = ["PEERS", "VARIANTS", "BucketedSSW", "Peer", "Variant", "check_dependencies",
           "make_method", "method_names", "method_summaries", "submission_name", "variant_changes"]

Method = Callable[[np.ndarray, np.ndarray, int], np.ndarray]


class Variant(NamedTuple):
    """An entry of :data:`VARIANTS`: changes for :meth:`sswjax.Params.replace` and a summary."""

    changes: Mapping[str, Any]
    summary: str


VARIANTS: dict[str, Variant] = {
    "ssw-noseg": Variant({"segments": None}, "SSW without the segment term"),
    "ssw-norefine": Variant({"refinement": None},
                            "SSW without the side-window median refinement"),
    "ssw-nolr": Variant({"checks": None, "fill": None}, "SSW without the left-right check and fill"),
    "ssw-guide": Variant({"aggregation.window_selection": "guide"},
                         "SSW, windows chosen on the left image"),
    "ssw-tad": Variant({"cost.tad_weight": 1.0, "cost.gradient_weight": 0.0,
                        "cost.census_weight": 0.0}, "SSW with the TAD cost alone"),
    "ssw-gm": Variant({"cost.tad_weight": 0.0, "cost.gradient_weight": 1.0,
                       "cost.census_weight": 0.0}, "SSW with the gradient cost alone"),
    "ssw-census": Variant({"cost.tad_weight": 0.0, "cost.gradient_weight": 0.0,
                           "cost.census_weight": 1.0}, "SSW with the census cost alone"),
}
"""Ablations of SSW: method name -> :class:`Variant` (applied on top of the user's parameters)."""


class Peer(NamedTuple):
    """An entry of :data:`PEERS`: another project's matcher, a one-line summary, the modules of
    its optional packages and what installs them (:func:`check_dependencies`)."""

    fn: Callable[..., Any]
    summary: str
    needs: tuple[str, ...] = ()
    install: str = ""


_OPENCV = (("cv2",), "OpenCV: pip install 'sswjax[bench]'")

PEERS: dict[str, Peer] = {
    "bm": Peer(bm_disparity, "OpenCV StereoBM, block 9 on the luma, background fill (extra [bench])",
               *_OPENCV),
    "sgbm": Peer(sgbm_disparity, "OpenCV StereoSGBM 3-way, block 3, background fill (extra [bench])",
                 *_OPENCV),
    "sgbm-hh": Peer(functools.partial(sgbm_disparity, mode="hh"),
                    "OpenCV StereoSGBM HH (8 paths, full-size buffers), block 3, background fill "
                    "(extra [bench])", *_OPENCV),
    "pandora": Peer(pandora_disparity,
                    "CNES Pandora census 5x5 + SGM, background fill (extra [pandora])",
                    ("pandora", "pandora_plugin_libsgm", "xarray"),
                    "CNES Pandora: pip install 'sswjax[pandora]'"),
}
"""Method name -> :class:`Peer`."""


def variant_changes(name: str) -> Mapping[str, Any]:
    """Parameter changes of the SSW method ``name`` (an aggregator kind or a variant).

    An aggregator is ``{"aggregation": kind}``; :func:`make_method` also keeps the window's
    radius where the new kind's means the same and drops superpixels nothing uses then.

    Raises ``KeyError`` for a name that is neither.

    Examples
    --------
    >>> variant_changes("gf"), variant_changes("ssw")
    ({'aggregation': 'gf'}, {})
    """
    if name in kinds("aggregation"):
        return {} if name == "ssw" else {"aggregation": name}
    return VARIANTS[name].changes


def _as_aggregator(variant: Params, base: Params) -> Params:
    """``variant`` (``base`` with another aggregator) as the aggregator methods have always run:
    box and bilateral windows of the radius of a base window of the same meaning (ssw, box, bf),
    and no superpixels where no stage uses them."""
    if variant.aggregation.kind in ("box", "bf") and base.aggregation.kind in ("ssw", "box", "bf"):
        variant = variant.replace(**{"aggregation.radius": base.aggregation.radius})
    users = [part for part in (variant.aggregation, variant.optimizer, variant.fill, variant.band)
             if part is not None and getattr(part, "uses_segments", False)]
    return variant if users else variant.replace(segments=None)


def method_names() -> tuple[str, ...]:
    """Every method ``sswjax evaluate --methods`` accepts: aggregators, variants, peers."""
    return (*kinds("aggregation"), *VARIANTS, *PEERS)


def method_summaries() -> dict[str, str]:
    """Method name -> one-line summary (for the command line's help)."""
    aggregators = {name: cls.summary() for name, cls in kinds("aggregation").items()}
    return {**aggregators, **{name: entry.summary for name, entry in VARIANTS.items()},
            **{name: entry.summary for name, entry in PEERS.items()}}


@dataclasses.dataclass(frozen=True)
class BucketedSSW:
    """An SSW variant on bucketed shapes, a :class:`sswjax.evaluation.runner.BatchedMethod`.

    Called on one pair it is ``sswjax.match(left, right, ndisp, params=params, buckets=buckets)``;
    :meth:`match_many` gives the same maps from :func:`sswjax.api.batch.iter_match_scenes`:
    pairs grouped by bucket, one pair per device per call, sharded over ``devices`` (default:
    all ``jax.devices()``).
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


def check_dependencies(names: Sequence[str]) -> None:
    """Check, before any scene is matched, that the optional packages of the methods ``names``
    import (:attr:`Peer.needs`); names that are not peers pass (unknown ones are
    :func:`make_method`'s to refuse).

    Raises ``ValueError`` (one line: ``method NAME needs WHAT: pip install ...``) for the first
    that does not.

    Examples
    --------
    >>> check_dependencies(["ssw", "gf", "nope"])
    """
    for name in names:
        peer = PEERS.get(name)
        for module in () if peer is None else peer.needs:
            try:
                importlib.import_module(module)
            except ImportError:
                raise ValueError(f"method {name} needs {peer.install}") from None


def make_method(
    name: str, *, params: Params | None = None, buckets: ShapeBuckets | None = None,
    devices=None, estimate_range: bool = False,
) -> Method:
    """The method called ``name`` as ``(left, right, ndisp) -> disparity``.

    Parameters
    ----------
    name : str
        One of :func:`method_names`.
    params : Params, optional
        Base parameters of the SSW variants (default: the ``accurate`` preset,
        :func:`sswjax.config.default_params`); ignored by peers.
    buckets : ShapeBuckets, optional
        Shape bucketing of the SSW variants (see :func:`sswjax.match`); with it they are
        :class:`BucketedSSW` (batched evaluation over ``devices``).
    devices : sequence of jax.Device, optional
        Devices of the batched evaluation (default: all ``jax.devices()``); used only with
        ``buckets``.
    estimate_range : bool
        The SSW variants ignore the scene's ``ndisp`` and search the range
        :func:`sswjax.api.auto_range.estimate_range` estimates from the pair (``sswjax.match``
        with ``ndisp=None``); not with ``buckets``. Peers always get the scene's range.

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
    if name in kinds("aggregation"):
        variant = _as_aggregator(variant, default_params() if params is None else params)
    if estimate_range:
        if buckets is not None:
            raise ValueError("an estimated range is each pair's own: it cannot be batched in "
                             "shape buckets")
        return functools.partial(_estimated_range_match, params=variant)
    if buckets is not None:
        return BucketedSSW(variant, buckets, None if devices is None else tuple(devices))
    return functools.partial(match, params=variant)


def _estimated_range_match(left, right, ndisp: int, *, params: Params):
    """``sswjax.match`` over the range estimated from the pair; ``ndisp`` (the scene's) unused."""
    return match(left, right, None, params=params)


def submission_name(name: str) -> str:
    """MiddEval3 file-name form of a method name: ``"ssw-noseg"`` -> ``"SSWNOSEG"``."""
    return "".join(c for c in name.upper() if c.isalnum())
