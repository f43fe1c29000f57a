"""The fit of a coarse-to-fine map again on the full-resolution cost (``coarse.refit_radius``):
a grid of its window on the three data sets, and the held-out choice among them.

The refit reads the doubled map and the pair, and the smoothing follows it, so the preset's
maps without either are computed once per scene (``sswjax.match`` at exact shapes) and every
grid point applies the graph's own refit (:func:`sswjax.graph.coarse.refit_on_cost`) and then
the preset's smoothing to them: the graph's maps with that refit (``tests/test_coarse_to_fine.py``
checks it). Rows are written in ``benchmarks/smoothing.py``'s CSV format (bad 2.0, 1.0, 0.5 and
the average error), with both held-out rules of ``benchmarks/held_out.py``.

    python benchmarks/refit.py [--preset fast] [--data ../shared/data] [--radii 0 1 2 3 4]
        [-o benchmarks/results/refit/PRESET]
"""

from __future__ import annotations

import argparse
import functools
import sys
from pathlib import Path

import jax
import jax.numpy as jnp

import sswjax
from sswjax.graph.coarse import refit_on_cost
from sswjax.runtime.compilation import enable_compilation_cache

from _report import write_report  # benchmarks/, on the path when run as a script
from smoothing import _table, grid_rows, write_held_out


@functools.partial(jax.jit, static_argnums=(4,))
def _refit_and_smooth(params, disparity, left, right, ndisp):
    """The graph's last two steps on a map without them: the refit (when the preset's
    ``coarse.refit_radius`` > 0), then the smoothing (when it has one)."""
    if params.coarse.refit_radius > 0:
        disparity = refit_on_cost(left, right, params, disparity, limit=ndisp)
    if params.smoothing is not None:
        disparity = params.smoothing.smooth(disparity, left, ndisp)
    return disparity


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="fast", help="a coarse-to-fine preset")
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2]
                        / "shared" / "data")
    parser.add_argument("--radii", type=int, nargs="+", default=[0, 1, 2, 3, 4],
                        help="coarse.refit_radius values, 0 for none")
    parser.add_argument("-o", "--output", type=Path,
                        help="default benchmarks/results/refit/PRESET")
    args = parser.parse_args(argv)
    args.output = args.output or Path("benchmarks/results/refit") / args.preset
    preset = sswjax.preset(args.preset)
    if preset.coarse is None:
        parser.error(f"preset {args.preset} does not run coarse-to-fine")
    enable_compilation_cache()  # as the command line does: a second run compiles nothing
    bare = preset.replace(**{"coarse.refit_radius": 0}, smoothing=None)
    grid = {radius: preset.replace(**{"coarse.refit_radius": radius}) for radius in args.radii}
    rows = grid_rows(args.data, bare, {
        f"{args.preset} refit_radius {radius}":
            functools.partial(_refit_and_smooth, params) for radius, params in grid.items()})
    write_report(args.output, "refit", _table(rows), rows, list(rows[0]))
    write_held_out(args.output, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
