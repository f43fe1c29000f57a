"""The refusal of a call that would not fit in memory: raised before any work by
:mod:`sswjax.runtime.memory`'s guard, caught by the command line and the cluster's tasks."""

from __future__ import annotations

from sswjax.runtime.plan import ExecutionPlan

__all__ = ["MemoryEstimateError"]


class MemoryEstimateError(MemoryError):
    """The estimated peak memory of a call exceeds what is available (or the caller's limit).

    Raised before any work, with a one-line message in the API's terms. The fields let a
    caller say it in its own (the command line names its options).

    Attributes
    ----------
    estimate, limit : int
        Bytes: the estimate of the call as asked, and the bound it exceeds.
    bound : str
        Which bound: ``"the limit"`` (the caller's) or ``"the available memory"``.
    shape : (int, int, int)
        The pair's width, height and ndisp, as estimated.
    strips : ExecutionPlan or None
        The strips or tiles that would fit (:func:`plan_for_memory`'s choice), with their
        estimate in :attr:`strips_estimate`; None when even the smallest do not.
    """

    def __init__(self, message: str, *, estimate: int, limit: int, bound: str = "the limit",
                 shape=(0, 0, 0), strips: ExecutionPlan | None = None,
                 strips_estimate: int | None = None):
        super().__init__(message)
        self.estimate = estimate
        self.limit = limit
        self.bound = bound
        self.shape = shape
        self.strips = strips
        self.strips_estimate = strips_estimate
