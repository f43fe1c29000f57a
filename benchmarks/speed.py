"""Speed of SSW on MiddEval3 pairs against OpenCV StereoSGBM (3-way), measured in one run.

For every scene: first-call time (compilation + one run), warm end-to-end time (median over
repeats), per-stage warm times of the real compiled graph (cost, superpixels, aggregation,
selection, refinement: a profiler trace attributes every XLA operation to its stage), throughput in million disparity evaluations per second (W * H * ndisp / s) and
OpenCV SGBM's time on the same pair, SSW and SGBM runs alternating so that machine noise hits
both. Writes Markdown and CSV; prints the Markdown.

    python benchmarks/speed.py [--data DIR] [--scenes Teddy Piano] [--repeats 5] [-o benchmarks/results]
"""

from __future__ import annotations

import argparse
import gzip
import json
import re
import resource
import tempfile
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import sswjax
from sswjax.api.images import prepare_pair
from sswjax.data.layouts import find_data_root, load_scenes
from sswjax.evaluation.peers import sgbm_disparity
from sswjax.graph import Stage, ssw_disparity

from _report import write_report  # benchmarks/, on the path when run as a script

STAGES = tuple(stage.value for stage in Stage)


def _timed(fn, *args):
    start = time.perf_counter()
    jax.block_until_ready(fn(*args))
    return time.perf_counter() - start


def _op_names(compiled_text: str) -> dict[str, str]:
    """Instruction name -> ``op_name`` metadata (named scopes included) of a compiled graph."""
    names = {}
    for line in compiled_text.splitlines():
        match = re.match(r'\s*(?:ROOT )?%(\S+) = .*?op_name="([^"]*)"', line)
        if match:
            names[match.group(1)] = match.group(2)
    return names


def stage_profile(left, right, params, ndisp) -> dict[str, float]:
    """Seconds spent in each stage of one warm ``ssw_disparity`` call, from a profiler trace.

    Every executed XLA operation (thunk) is attributed to the stage whose ``jax.named_scope``
    (:class:`sswjax.graph.Stage`) its ``op_name`` carries; loop containers are skipped so time is
    not counted twice. Operations may overlap on the two cores, so stages can add up to more
    than the wall time; the profiler also adds some overhead.
    """
    names = _op_names(ssw_disparity.lower(left, right, params, ndisp=ndisp).compile().as_text())
    with tempfile.TemporaryDirectory() as directory:
        with jax.profiler.trace(directory):
            jax.block_until_ready(ssw_disparity(left, right, params, ndisp=ndisp))
        (trace,) = Path(directory).rglob("*.trace.json.gz")
        events = json.loads(gzip.decompress(trace.read_bytes()))["traceEvents"]
    seconds = dict.fromkeys(STAGES, 0.0)
    for event in events:
        op = names.get(event.get("name"))
        if event.get("ph") != "X" or op is None or event["name"].startswith("while"):
            continue
        # The outermost stage scope wins: the band's cost, paths and fill count as the band.
        found = [(f"{op}/".find(f"/{s}/"), s) for s in STAGES if f"/{s}/" in f"{op}/"]
        if found:
            stage = min(found)[1]
            seconds[stage] += event["dur"] / 1e6
    return seconds


def bench_scene(scene, params, repeats, pandora=False):
    left, right = map(jnp.asarray, prepare_pair(scene.left, scene.right))
    ndisp = scene.ndisp
    full = lambda: ssw_disparity(left, right, params, ndisp=ndisp)  # noqa: E731
    first = _timed(full)
    ssw_times, sgbm_times = [], []
    sgbm_disparity(scene.left, scene.right, ndisp)  # warm OpenCV's allocations too
    for _ in range(repeats):
        ssw_times.append(_timed(full))
        sgbm_times.append(_timed(lambda: sgbm_disparity(scene.left, scene.right, ndisp)))
    stages = stage_profile(left, right, params, ndisp)
    if pandora:  # one run: it takes seconds per pair, far above the machine's noise
        from sswjax.evaluation.peers import pandora_disparity

        pandora_s = _timed(lambda: pandora_disparity(scene.left, scene.right, ndisp))
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
        **({"pandora_s": pandora_s, "pandora_ratio": pandora_s / warm} if pandora else {}),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path,
                        help="MiddEval3 (or its split folder), or the folder holding it as "
                             "the other benchmarks take it (../shared/data)")
    parser.add_argument("--scenes", nargs="+")
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--params", type=Path, help="parameters JSON (default: Params())")
    group.add_argument("--preset", choices=list(sswjax.PRESETS), help="a named preset")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--pandora", action="store_true",
                        help="also time CNES Pandora (census + SGM; pip install 'sswjax[pandora]')")
    parser.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results"))
    args = parser.parse_args()
    params = sswjax.Params() if args.params is None else sswjax.load_params(args.params)
    params = sswjax.preset(args.preset) if args.preset else params
    root = find_data_root(data=args.data)
    if (root / "MiddEval3").is_dir():  # the data sets' folder, as front.py and band.py take it
        root = root / "MiddEval3"
    scenes = load_scenes(root, scenes=args.scenes)
    rows = []
    if args.pandora:  # its first call imports and registers plugins: keep that out of the timings
        from sswjax.evaluation.peers import pandora_disparity

        pandora_disparity(scenes[0].left, scenes[0].right, scenes[0].ndisp)
    for scene in scenes:
        rows.append(bench_scene(scene, params, args.repeats, pandora=args.pandora))
        print(f"{scene.name}: warm {rows[-1]['warm_s']:.3f} s, sgbm {rows[-1]['sgbm_s']:.3f} s", flush=True)
    keys = list(rows[0])
    median = {k: float(np.median([r[k] for r in rows])) for k in keys if k not in ("scene", "size")}
    rss_gb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
    lines = [
        f"SSW ({args.preset or args.params or 'defaults'}) vs OpenCV StereoSGBM 3-way, {len(rows)} "
        f"pairs, median of {args.repeats} warm runs "
        f"each; jax {jax.__version__}, {jax.devices()[0].platform}; peak RSS {rss_gb:.2f} GB; "
        "stage columns: milliseconds from one profiled run",
        "",
        "| scene | W x H x D | first call s | SSW warm s | SGBM s | SSW / SGBM | Mde/s | "
        + " | ".join(f"{stage} ms" for stage in STAGES)
        + (" | Pandora s | Pandora / SSW" if args.pandora else "") + " |",
        "|---" * (7 + len(STAGES) + 2 * args.pandora) + "|",
    ]
    for r in rows + [{"scene": "**median**", "size": "", **median}]:
        stage_cells = " | ".join(f"{1e3 * r[f'{stage}_s']:.0f}" for stage in STAGES)
        lines.append(
            f"| {r['scene']} | {r['size']} | {r['first_call_s']:.2f} | {r['warm_s']:.3f} | "
            f"{r['sgbm_s']:.3f} | {r['ratio']:.1f} | {r['mde_per_s']:.0f} | {stage_cells} |"
            + (f" {r['pandora_s']:.2f} | {r['pandora_ratio']:.1f} |" if args.pandora else "")
        )
    write_report(args.output, "speed", "\n".join(lines), rows, keys)


if __name__ == "__main__":
    main()
