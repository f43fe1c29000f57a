"""The names of the stages in the compiled graph.

Each stage of the graph runs under ``jax.named_scope(stage.value)``, so a profiler trace
attributes every operation to one of them (``benchmarks/speed.py``).
"""

from __future__ import annotations

import enum

import jax

__all__ = ["Stage", "scope"]


class Stage(enum.Enum):
    """A named scope of the compiled graph, in the order the data flows through them."""

    ALIGNMENT = "alignment"
    COST = "cost"
    SUPERPIXELS = "superpixels"
    AGGREGATION = "aggregation"
    OPTIMIZATION = "optimization"
    SELECTION = "selection"
    REFINEMENT = "refinement"
    UPSAMPLING = "upsampling"
    REFIT = "refit"
    BAND = "band"
    SMOOTHING = "smoothing"


def scope(stage: Stage):
    """``jax.named_scope`` of ``stage``: ``with scope(Stage.COST): ...``."""
    return jax.named_scope(stage.value)
