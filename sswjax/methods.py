"""Named stereo methods for evaluation: SSW, its ablations, the baseline aggregators and peers.

Conventions: a method is a callable ``(left, right, ndisp) -> float32 (H, W)`` dense disparity
taking images as read from disk (see :mod:`sswjax.evaluation`). SSW variants are the pipeline
with some parameters changed (:data:`SSW_VARIANTS`); the baselines replace only the aggregation
step (Table 1 of the paper: BF, GF, iGF, MF); peers are other projects' matchers
(:mod:`sswjax.peers`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from sswjax.params import Params
from sswjax.peers import pandora_disparity, sgbm_disparity
from sswjax.pipeline import ShapeBuckets, match

SSW_VARIANTS: dict[str, dict] = {
    "ssw": {},
    "bf": {"aggregation": "bf"},
    "gf": {"aggregation": "gf"},
    "igf": {"aggregation": "igf"},
    "mf": {"aggregation": "mf"},
    "box": {"aggregation": "box"},
    "ssw-noseg": {"n_segments": 0},
    "ssw-norefine": {"refine_radius": 0},
    "ssw-nolr": {"lr_check": False},
    "ssw-guide": {"window_selection": "guide"},
    "ssw-tad": {"tad_weight": 1.0, "gradient_weight": 0.0, "census_weight": 0.0},
    "ssw-gm": {"tad_weight": 0.0, "gradient_weight": 1.0, "census_weight": 0.0},
    "ssw-census": {"tad_weight": 0.0, "gradient_weight": 0.0, "census_weight": 1.0},
}
"""Method name -> parameter changes applied on top of the user's parameters."""

PEERS: dict[str, Callable[[np.ndarray, np.ndarray, int], np.ndarray]] = {
    "sgbm": sgbm_disparity,
    "pandora": pandora_disparity,
}
"""Method name -> another project's matcher under our protocol (optional dependencies)."""

METHOD_NAMES = tuple(SSW_VARIANTS) + tuple(PEERS)

Method = Callable[[np.ndarray, np.ndarray, int], np.ndarray]


def make_method(
    name: str, params: Params | None = None, *, buckets: ShapeBuckets | None = None
) -> Method:
    """The method called ``name`` as ``(left, right, ndisp) -> disparity``.

    Parameters
    ----------
    name : str
        One of :data:`METHOD_NAMES`.
    params : Params, optional
        Base parameters of the SSW variants (default ``Params()``); ignored by peers.
    buckets : ShapeBuckets, optional
        Shape bucketing of the SSW variants (see :func:`sswjax.match`).

    Examples
    --------
    >>> method = make_method("gf")
    >>> sorted(METHOD_NAMES)[:3]
    ['bf', 'box', 'gf']
    """
    if name in PEERS:
        return PEERS[name]
    if name not in SSW_VARIANTS:
        raise ValueError(f"unknown method {name!r}; choose from {', '.join(METHOD_NAMES)}")
    variant = (Params() if params is None else params).replace(**SSW_VARIANTS[name])

    def run(left, right, ndisp):
        return match(left, right, ndisp, variant, buckets=buckets)

    return run


def submission_name(name: str) -> str:
    """MiddEval3 file-name form of a method name: ``"ssw-noseg"`` -> ``"SSWNOSEG"``."""
    return "".join(c for c in name.upper() if c.isalnum())
