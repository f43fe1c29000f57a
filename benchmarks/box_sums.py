"""Side-window sums on XLA CPU: shifted slices versus running sums, by radius.

Times ``select_side_window_mean`` (the aggregation's inner step) on a cost volume of the size of
a large trainingQ scene, for both ``method="slices"`` and ``method="cumsum"``. Prints a Markdown
table of warm medians.

    python benchmarks/box_sums.py [--shape 70 497 741] [--radii 2 4 6 9] [--repeats 5]
"""

from __future__ import annotations

import argparse
import functools
import time

import jax
import jax.numpy as jnp
import numpy as np

from sswjax.stages.filters import SUM_METHODS, select_side_window_mean


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shape", type=int, nargs=3, default=(70, 497, 741), metavar=("D", "H", "W"))
    parser.add_argument("--radii", type=int, nargs="+", default=(2, 4, 6, 9))
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    key = jax.random.PRNGKey(0)
    volume = jax.random.uniform(key, tuple(args.shape), jnp.float32)
    index = jax.random.randint(key, tuple(args.shape[1:]), 0, 8)
    print(f"volume {tuple(args.shape)}, median of {args.repeats} warm runs, seconds")
    print("| radius | " + " | ".join(SUM_METHODS) + " |")
    print("|---" * (len(SUM_METHODS) + 1) + "|")
    for radius in args.radii:
        cells = []
        for method in SUM_METHODS:
            fn = jax.jit(functools.partial(select_side_window_mean, radius=radius, method=method))
            fn(volume, index).block_until_ready()
            times = []
            for _ in range(args.repeats):
                start = time.perf_counter()
                fn(volume, index).block_until_ready()
                times.append(time.perf_counter() - start)
            cells.append(f"{np.median(times):.3f}")
        print(f"| {radius} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
