"""``sswjax match`` options for the confidence and the validity of a map.

``--confidence CONF.pfm`` writes the confidence (float32 in [0, 1], higher = more reliable),
``--validity VALID.png`` the validity bits as an 8-bit gray PNG (0 = valid; bit 0 = failed the
left-right check and filled, bit 1 = left band ``x - d < 0``, bit 2 = confidence below
``--low-confidence``, bit 3 = outside the rectified view (``--rectify``), bit 4 = no cost minimum
stands out (a textureless or saturated region); :mod:`sswjax.stages.confidence`), and ``--invalid-as-inf`` writes the
``-o`` map (and ``--png``) with ``inf`` wherever a validity bit is set, the MiddEval3
convention for pixels without an estimate. ``--confidence`` is written by its extension
(``.pfm``, ``.npy``, ``.tif``, ``.tiff``). Every output is checked before the run and written
with the others, all or nothing (:func:`confidence_writers`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import imageio.v3 as iio
import numpy as np

from sswjax.cli.common import Writer
from sswjax.data.io import write_float_map
from sswjax.stages.confidence import DEFAULT_THRESHOLD

__all__ = ["add_confidence_options", "confidence_writers", "invalid_as_inf", "wants_confidence",
           "write_validity"]


def _threshold(text: str) -> float:
    """``--low-confidence`` value: a number in [0, 1]."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number in [0, 1], got {text!r}") from None
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"expected a number in [0, 1], got {text!r}")
    return value


def add_confidence_options(parser: argparse.ArgumentParser) -> None:
    """Add ``--confidence``, ``--validity``, ``--invalid-as-inf`` and ``--low-confidence``."""
    parser.add_argument("--confidence", type=Path, metavar="CONF.pfm",
                        help="also write the confidence of each pixel (float32 in [0, 1], "
                             "higher = more reliable) as .pfm, .npy, .tif or .tiff")
    parser.add_argument("--validity", type=Path, metavar="VALID.png",
                        help="also write the validity bits (8-bit PNG, 0 = valid; 1: failed the "
                             "left-right check and filled, 2: left band x - d < 0, 4: low "
                             "confidence, 8: outside the rectified view, 16: ambiguous, no "
                             "cost minimum stands out)")
    parser.add_argument("--invalid-as-inf", action="store_true",
                        help="write inf into -o (and --png) wherever a validity bit is set "
                             "(the MiddEval3 convention) instead of the filled values")
    parser.add_argument("--low-confidence", type=_threshold, default=DEFAULT_THRESHOLD,
                        metavar="T", help="confidence below T sets validity bit 2 "
                                          f"(default {DEFAULT_THRESHOLD}; 0 never)")


def wants_confidence(args) -> bool:
    """Whether ``args`` asks for any output of :func:`sswjax.match_with_confidence`."""
    return (getattr(args, "confidence", None) is not None
            or getattr(args, "validity", None) is not None
            or getattr(args, "invalid_as_inf", False))


def invalid_as_inf(disparity: np.ndarray, validity: np.ndarray) -> np.ndarray:
    """The map with ``inf`` where any validity bit is set.

    Parameters
    ----------
    disparity : float32 (H, W)
    validity : uint8 (H, W)

    Returns
    -------
    float32 (H, W), a new array

    Examples
    --------
    >>> invalid_as_inf(np.array([[1.0, 2.0]], np.float32), np.array([[0, 4]], np.uint8)).tolist()
    [[1.0, inf]]
    """
    return np.where(validity == 0, disparity, np.float32(np.inf)).astype(np.float32)


def write_validity(path: Path, validity: np.ndarray) -> None:
    """Write uint8 ``(H, W)`` validity bits to ``path`` (a temporary file) as an 8-bit gray PNG."""
    iio.imwrite(path, np.asarray(validity, np.uint8), extension=".png")


def confidence_writers(matched, *, confidence: Path | None, validity: Path | None
                       ) -> dict[Path, Writer]:
    """The writers of the confidence (by its extension) and the validity PNG asked for, for
    :func:`sswjax._files.atomic_outputs`.

    Parameters
    ----------
    matched : sswjax.api.match.Matched
        confidence float32 (H, W), validity uint8 (H, W).
    confidence, validity : pathlib.Path or None
    """
    writers: dict[Path, Writer] = {}
    if confidence is not None:
        writers[confidence] = lambda tmp: write_float_map(tmp, matched.confidence,
                                                          suffix=confidence.suffix, atomic=False)
    if validity is not None:
        writers[validity] = lambda tmp: write_validity(tmp, matched.validity)
    return writers
