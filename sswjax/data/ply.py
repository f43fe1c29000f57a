"""Point clouds as binary PLY files (MeshLab, CloudCompare, Open3D read them).

Array conventions: ``xyz`` floating ``(N, 3)`` in the calibration's unit, ``rgb`` uint8 ``(N, 3)``
(:func:`sswjax.api.geometry.point_cloud` gives both).
"""

from __future__ import annotations

import os

import numpy as np

from sswjax._checks import check_floating, check_rank
from sswjax._files import output_file

__all__ = ["write_ply"]


def write_ply(path: str | os.PathLike, xyz, rgb, *, atomic: bool = True) -> None:
    """Atomically write a binary little-endian PLY point cloud (MeshLab, CloudCompare, Open3D).

    One ``vertex`` element with ``float x, y, z`` and ``uchar red, green, blue``.

    Parameters
    ----------
    path : str or os.PathLike
    xyz : array_like floating (N, 3)
    rgb : array_like uint8 (N, 3)
    atomic : bool
        False: write ``path`` itself (a temporary file already).

    Raises
    ------
    ValueError, TypeError
        On bad shapes or dtypes.
    InputError
        If the file cannot be written.

    Examples
    --------
    >>> write_ply("cloud.ply", np.zeros((1, 3), np.float32), np.zeros((1, 3), np.uint8))  # doctest: +SKIP
    """
    xyz, rgb = np.asarray(xyz), np.asarray(rgb)
    check_rank("xyz", xyz, 2)
    check_floating("xyz", xyz)
    if xyz.shape[1] != 3 or rgb.shape != xyz.shape:
        raise ValueError(f"xyz and rgb must both be (N, 3), got {xyz.shape} and {rgb.shape}")
    if rgb.dtype != np.uint8:
        raise TypeError(f"rgb must be uint8, got {rgb.dtype}")
    vertices = np.empty(len(xyz), [(c, "<f4") for c in "xyz"] +
                        [(c, "u1") for c in ("red", "green", "blue")])
    for i, c in enumerate("xyz"):
        vertices[c] = xyz[:, i]
    for i, c in enumerate(("red", "green", "blue")):
        vertices[c] = rgb[:, i]
    header = "\n".join(["ply", "format binary_little_endian 1.0", "comment written by sswjax",
                        f"element vertex {len(xyz)}", "property float x", "property float y",
                        "property float z", "property uchar red", "property uchar green",
                        "property uchar blue", "end_header"]) + "\n"
    with output_file(path, atomic=atomic) as tmp, open(tmp, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(vertices.tobytes())
