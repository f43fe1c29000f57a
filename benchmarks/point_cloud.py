"""Render a PLY point cloud of ``sswjax match --ply`` as a 3-D scatter coloured by the image.

The cloud is read with `plyfile <https://github.com/dranjan/python-plyfile>`_ (an independent
PLY reader, so the picture also checks the file), a random subsample is drawn in the camera
frame of the left view with "up" pointing up (``-y``) and depth going away from the viewer,
and the picture is written as PNG. The cloud of docs/command-line.md is made by::

    M=../shared/data/MiddEval3/trainingQ/Motorcycle
    sswjax match $M/im0.png $M/im1.png --ndisp 70 --preset accurate --calib $M/calib.txt \\
        -o /tmp/disp0.pfm --ply /tmp/motorcycle.ply
    python benchmarks/point_cloud.py /tmp/motorcycle.ply \\
        -o benchmarks/results/point_cloud_motorcycle.png

Needs the ``bench`` extras (matplotlib, plyfile).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def read_cloud(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """float ``xyz (N, 3)`` and uint8 ``rgb (N, 3)`` of a PLY file's vertices."""
    from plyfile import PlyData

    vertex = PlyData.read(str(path))["vertex"]
    xyz = np.stack([vertex[c] for c in "xyz"], axis=-1).astype(np.float64)
    rgb = np.stack([vertex[c] for c in ("red", "green", "blue")], axis=-1).astype(np.uint8)
    return xyz, rgb


def render(xyz: np.ndarray, rgb: np.ndarray, out: Path, *, points: int, seed: int,
           title: str, unit: str) -> None:
    """Scatter a random subsample of ``points`` points (depth clipped to its 1-99 % range)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    low, high = np.percentile(xyz[:, 2], [1, 99])
    keep = np.flatnonzero((xyz[:, 2] >= low) & (xyz[:, 2] <= high))
    rng = np.random.default_rng(seed)
    pick = rng.choice(keep, size=min(points, keep.size), replace=False)
    x, y, z = xyz[pick].T
    figure = plt.figure(figsize=(9, 7), dpi=110)
    axes = figure.add_subplot(projection="3d")
    # Matplotlib's vertical axis is its third: plot (x, depth, up).
    axes.scatter(x, z, -y, c=rgb[pick] / 255.0, s=1.0, linewidths=0, depthshade=False)
    axes.set_xlabel(f"x (right, {unit})")
    axes.set_ylabel(f"z (depth, {unit})")
    axes.set_zlabel(f"-y (up, {unit})")
    axes.set_box_aspect((np.ptp(x), np.ptp(z), np.ptp(y)))
    axes.view_init(elev=18, azim=-68)
    axes.set_title(title)
    figure.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(out)
    plt.close(figure)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("ply", type=Path, help="point cloud written by sswjax match --ply")
    parser.add_argument("-o", "--output", type=Path,
                        default=Path("benchmarks/results/point_cloud_motorcycle.png"))
    parser.add_argument("--points", type=int, default=120_000, help="points drawn (subsample)")
    parser.add_argument("--unit", default="mm", help="the calibration's baseline unit (mm)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--title", default="Motorcycle (MiddEval3 trainingQ), preset accurate")
    args = parser.parse_args()
    xyz, rgb = read_cloud(args.ply)
    render(xyz, rgb, args.output, points=args.points, seed=args.seed, title=args.title,
           unit=args.unit)
    print(f"{len(xyz)} points, depth {np.percentile(xyz[:, 2], 1):.0f} .. "
          f"{np.percentile(xyz[:, 2], 99):.0f} (1-99 %); wrote {args.output}")


if __name__ == "__main__":
    main()
