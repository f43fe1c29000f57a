"""Disparity ranges ``min_disp .. min_disp + ndisp - 1`` (possibly negative) at the front door.

The jitted graph only searches ``0 .. ndisp - 1``. A range starting at ``M`` is run by moving
the pair into a frame where it starts at 0 (:func:`range_frame`), matching there, and mapping
the result back (:func:`from_range_frame`): the right image is shifted by ``M`` columns,
``right'(x) = right(x - M)``, edge-replicated where ``x - M`` falls outside, so a disparity
``d`` of the pair is ``d - M`` in the frame. Every stage (border rule, left-right check, fill,
disparity chunks, shape buckets, strips) sees an ordinary pair and needs no change.

The graph's border rule (no match where the right column ``x' - d' < 0``) must stay the
rule of the pair (``x - d < 0``):

- ``M < 0``: both images are widened by ``-M`` columns (left padded on the left, right on the
  right, edge-replicated), so column 0 of the right image stays column 0 of the frame and the
  rule is exact; the ``-M`` extra columns are cropped from the result. Without the widening,
  true matches in the first ``-M`` columns of the right image would be excluded.
- ``M > 0``: the frame keeps the width; disparities that point left of the right image
  (``x - d`` in ``[-M, 0)``, pixels without a match) compare with the right image's first
  column, replicated, instead of taking the border cost. Their pixels have no match anyway
  (the band of the validity mask).

Array conventions: images float32 ``(H, W, C)`` as :func:`sswjax.api.checked_pair` gives
them; disparities float32 ``(H, W)`` in pixels.
"""

from __future__ import annotations

import numpy as np

__all__ = ["check_disparity_range", "from_range_frame", "range_frame"]


def check_disparity_range(width: int, ndisp: int, min_disp) -> None:
    """Refuse a ``min_disp`` that is not an integer or a range that no pixel can match in.

    A left pixel ``x`` of an image ``width`` columns wide has a right pixel ``x - d`` inside
    the image only for ``-(width - 1) <= d <= width - 1``; the range ``min_disp .. min_disp +
    ndisp - 1`` must meet that interval.

    Raises
    ------
    ValueError
        With a one-line message.

    Examples
    --------
    >>> check_disparity_range(64, 16, -5)
    >>> check_disparity_range(64, 16, 64)
    Traceback (most recent call last):
    ...
    ValueError: disparity range 64..79 leaves no valid disparity for an image 64 pixels wide: it must meet -63..63
    """
    if isinstance(min_disp, bool) or not isinstance(min_disp, (int, np.integer)):
        raise ValueError(f"min_disp must be an integer, got {min_disp!r}")
    last = int(min_disp) + int(ndisp) - 1
    if min_disp > width - 1 or last < -(width - 1):
        raise ValueError(
            f"disparity range {min_disp}..{last} leaves no valid disparity for an image {width} "
            f"pixels wide: it must meet {-(width - 1)}..{width - 1}")


def range_frame(left: np.ndarray, right: np.ndarray, *, min_disp: int
                ) -> tuple[np.ndarray, np.ndarray]:
    """The pair in the frame where the range ``min_disp ..`` starts at 0.

    Parameters
    ----------
    left, right : numpy.ndarray (H, W, C)
    min_disp : int
        First disparity of the range, ``M``.

    Returns
    -------
    (numpy.ndarray (H, W + P, C), numpy.ndarray (H, W + P, C)), ``P = max(-M, 0)``
        ``left'(x) = left(x - P)`` and ``right'(x) = right(x - P - M)``, indices clipped to the
        image (edge replication). ``M = 0`` returns the inputs themselves.

    Examples
    --------
    >>> row = np.arange(5.0)[None, :, None]
    >>> shifted = range_frame(row, row, min_disp=2)[1]
    >>> shifted[0, :, 0].tolist()
    [0.0, 0.0, 0.0, 1.0, 2.0]
    >>> [image[0, :, 0].tolist() for image in range_frame(row, row, min_disp=-2)]
    [[0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 4.0], [0.0, 1.0, 2.0, 3.0, 4.0, 4.0, 4.0]]
    """
    if min_disp == 0:
        return left, right
    width = left.shape[1]
    pad = max(-int(min_disp), 0)
    columns = np.arange(width + pad)
    return (np.take(left, np.clip(columns - pad, 0, width - 1), axis=1),
            np.take(right, np.clip(columns - pad - min_disp, 0, width - 1), axis=1))


def from_range_frame(disparity: np.ndarray, *, min_disp: int, width: int) -> np.ndarray:
    """A disparity map of :func:`range_frame`'s pair back in the pair's frame.

    Parameters
    ----------
    disparity : numpy.ndarray float32 (H, W + P)
        Disparities ``0 .. ndisp - 1`` of the frame.
    min_disp : int
    width : int
        ``W``, the pair's width.

    Returns
    -------
    numpy.ndarray float32 (H, W)
        ``disparity + min_disp`` without the ``P`` widening columns.

    Examples
    --------
    >>> from_range_frame(np.array([[9.0, 0.0, 1.0]], np.float32), min_disp=-1, width=2).tolist()
    [[-1.0, 0.0]]
    """
    if min_disp == 0:
        return disparity
    pad = max(-int(min_disp), 0)
    return (disparity[:, pad:pad + width] + np.float32(min_disp)).astype(np.float32)
