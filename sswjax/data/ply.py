"""Point clouds as binary PLY files (MeshLab, CloudCompare, Open3D read them) or NumPy ``.npz``.

Array conventions: ``xyz`` floating ``(N, 3)`` in the calibration's unit, ``rgb`` uint8 ``(N, 3)``
(:func:`sswjax.api.geometry.point_cloud` gives both). :func:`write_cloud` writes either format
by the file's extension (:data:`CLOUD_SUFFIXES`); the ``.npz`` holds ``xyz`` float32 and
``rgb`` uint8 (``np.load(path)["xyz"]``).
"""

from __future__ import annotations

import os

import numpy as np

from sswjax._checks import check_floating, check_rank
from sswjax._files import output_file

__all__ = ["CLOUD_SUFFIXES", "write_cloud", "write_npz_cloud", "write_ply"]

CLOUD_SUFFIXES = (".ply", ".npz")
"""The file name endings :func:`write_cloud` writes (any case)."""


def _checked(xyz, rgb) -> tuple[np.ndarray, np.ndarray]:
    xyz, rgb = np.asarray(xyz), np.asarray(rgb)
    check_rank("xyz", xyz, 2)
    check_floating("xyz", xyz)
    if xyz.shape[1] != 3 or rgb.shape != xyz.shape:
        raise ValueError(f"xyz and rgb must both be (N, 3), got {xyz.shape} and {rgb.shape}")
    if rgb.dtype != np.uint8:
        raise TypeError(f"rgb must be uint8, got {rgb.dtype}")
    return xyz, rgb


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
    xyz, rgb = _checked(xyz, rgb)
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


def write_npz_cloud(path: str | os.PathLike, xyz, rgb, *, atomic: bool = True) -> None:
    """Atomically write a point cloud as NumPy ``.npz``: ``xyz`` float32 ``(N, 3)`` and ``rgb``
    uint8 ``(N, 3)`` (``atomic=False``: write ``path`` itself, whatever its name ends in).

    Examples
    --------
    >>> write_npz_cloud("cloud.npz", np.zeros((1, 3)), np.zeros((1, 3), np.uint8))  # doctest: +SKIP
    >>> np.load("cloud.npz")["xyz"].dtype                                         # doctest: +SKIP
    dtype('float32')
    """
    xyz, rgb = _checked(xyz, rgb)
    with output_file(path, atomic=atomic) as tmp, open(tmp, "wb") as f:
        np.savez(f, xyz=xyz.astype(np.float32), rgb=rgb)  # a file object: no ".npz" added


def write_cloud(path: str | os.PathLike, xyz, rgb, *, suffix: str | None = None,
                atomic: bool = True) -> None:
    """Write a point cloud in the format of ``suffix`` (default: ``path``'s), one of
    :data:`CLOUD_SUFFIXES`: :func:`write_ply` or :func:`write_npz_cloud`.

    Raises
    ------
    ValueError
        On another ending, or as the writers.
    """
    suffix = (suffix if suffix is not None else os.path.splitext(os.fspath(path))[1]).lower()
    if suffix not in CLOUD_SUFFIXES:
        raise ValueError(f"a point cloud is written as {' or '.join(CLOUD_SUFFIXES)}, not "
                         f"{suffix or 'a file without extension'!r}")
    writer = write_ply if suffix == ".ply" else write_npz_cloud
    writer(path, xyz, rgb, atomic=atomic)
