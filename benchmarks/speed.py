"""Speed of SSW on MiddEval3 pairs against OpenCV StereoSGBM (3-way), measured in one run.

For every scene: first-call time (compilation + one run), warm end-to-end time (median over
repeats), per-stage warm times (cost, superpixels, aggregation, selection + refinement, each
jitted alone), throughput in million disparity evaluations per second (W * H * ndisp / s) and
OpenCV SGBM's time on the same pair, SSW and SGBM runs alternating so that machine noise hits
both. Writes Markdown and CSV; prints the Markdown.

    python benchmarks/speed.py [--data DIR] [--scenes Teddy Piano] [--repeats 3] [-o benchmarks/results]
"""

from __future__ import annotations

import argparse
import csv
import resource
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import sswjax
from sswjax.aggregation import aggregate_cost
from sswjax.cost import cost_volume
from sswjax.datasets import find_data_root, load_middeval3
from sswjax.peers import sgbm_disparity
from sswjax.pipeline import prepare_pair, select_and_refine, ssw_disparity, superpixels


def _timed(fn, *args):
    start = time.perf_counter()
    jax.block_until_ready(fn(*args))
    return time.perf_counter() - start


def stage_functions(params: sswjax.Params, ndisp: int):
    """Each pipeline stage jitted alone: name -> (function, how to build its inputs)."""
    d, s = params.dynamic, params.static

    def cost(left, right):
        return cost_volume(left, right, ndisp=ndisp, tad_weight=d.tad_weight,
                           gradient_weight=d.gradient_weight, census_weight=d.census_weight,
                           tad_truncation=d.tad_truncation, gradient_truncation=d.gradient_truncation,
                           census_height=s.census_height, census_width=s.census_width)

    def segments(left):
        return superpixels(left, params)[0]

    def aggregation(volume, left, labels, num_segments):
        return aggregate_cost(volume, left, radius=s.aggregation_radius,
                              iterations=s.aggregation_iterations,
                              window_selection=s.window_selection, labels=labels,
                              num_segments=num_segments, segment_weight=d.segment_weight)

    return jax.jit(cost), jax.jit(segments), jax.jit(aggregation, static_argnums=3), jax.jit(
        lambda volume: select_and_refine(volume, params))


def bench_scene(scene, params, repeats):
    left, right = map(jnp.asarray, prepare_pair(scene.left, scene.right))
    ndisp = scene.ndisp
    full = lambda: ssw_disparity(left, right, params, ndisp=ndisp)  # noqa: E731
    first = _timed(full)
    ssw_times, sgbm_times = [], []
    sgbm_disparity(scene.left, scene.right, ndisp)  # warm OpenCV's allocations too
    for _ in range(repeats):
        ssw_times.append(_timed(full))
        sgbm_times.append(_timed(lambda: sgbm_disparity(scene.left, scene.right, ndisp)))
    cost, segments, aggregation, refine = stage_functions(params, ndisp)
    volume = cost(left, right)
    labels = segments(left)
    num_segments = superpixels(left, params)[1]
    aggregated = aggregation(volume, left, labels, num_segments)
    refine(aggregated)
    stages = {
        "cost": np.median([_timed(cost, left, right) for _ in range(repeats)]),
        "superpixels": np.median([_timed(segments, left) for _ in range(repeats)]),
        "aggregation": np.median(
            [_timed(aggregation, volume, left, labels, num_segments) for _ in range(repeats)]),
        "selection+refinement": np.median([_timed(refine, aggregated) for _ in range(repeats)]),
    }
    warm = float(np.median(ssw_times))
    sgbm = float(np.median(sgbm_times))
    height, width = scene.left.shape[:2]
    return {
        "scene": scene.name,
        "size": f"{width}x{height}x{ndisp}",
        "first_call_s": first,
        "warm_s": warm,
        "sgbm_s": sgbm,
        "ratio": warm / sgbm,
        "mde_per_s": width * height * ndisp / warm / 1e6,
        **{f"{k}_s": float(v) for k, v in stages.items()},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path)
    parser.add_argument("--scenes", nargs="+")
    parser.add_argument("--params", type=Path)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results"))
    args = parser.parse_args()
    params = sswjax.Params() if args.params is None else sswjax.load_params(args.params)
    scenes = load_middeval3(find_data_root(args.data), scenes=args.scenes)
    rows = []
    for scene in scenes:
        rows.append(bench_scene(scene, params, args.repeats))
        print(f"{scene.name}: warm {rows[-1]['warm_s']:.3f} s, sgbm {rows[-1]['sgbm_s']:.3f} s", flush=True)
    keys = list(rows[0])
    median = {k: float(np.median([r[k] for r in rows])) for k in keys if k not in ("scene", "size")}
    rss_gb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
    lines = [
        f"SSW vs OpenCV StereoSGBM 3-way, {len(rows)} pairs, median of {args.repeats} warm runs "
        f"each; jax {jax.__version__}, {jax.devices()[0].platform}; peak RSS {rss_gb:.2f} GB",
        "",
        "| scene | W x H x D | first call s | SSW warm s | SGBM s | SSW / SGBM | Mde/s | cost s "
        "| superpixels s | aggregation s | selection+refinement s |",
        "|---" * 11 + "|",
    ]
    for r in rows + [{"scene": "**median**", "size": "", **median}]:
        lines.append(
            f"| {r['scene']} | {r['size']} | {r['first_call_s']:.2f} | {r['warm_s']:.3f} | "
            f"{r['sgbm_s']:.3f} | {r['ratio']:.1f} | {r['mde_per_s']:.0f} | {r['cost_s']:.3f} | "
            f"{r['superpixels_s']:.3f} | {r['aggregation_s']:.3f} | {r['selection+refinement_s']:.3f} |"
        )
    table = "\n".join(lines)
    print(table)
    args.output.mkdir(parents=True, exist_ok=True)
    (args.output / "speed.md").write_text(table + "\n")
    with open(args.output / "speed.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=keys)
        writer.writeheader()
        writer.writerows(rows)


if __name__ == "__main__":
    main()
