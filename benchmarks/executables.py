"""Many shapes in one process: the memory mappings with the bound on live compiled graphs, and
what a graph costs to compile again once it was evicted.

1. Every preset over the shared pairs (MiddEval3 trainingQ, KITTI 2012, Middlebury 2001) in this
   one process, through ``sswjax.match`` at exact shapes: before the bound, such a run died
   after about 120 compiled shapes (``vm.max_map_count``). Reports the largest mapping count,
   the distinct graphs compiled and the time.
2. One pair's graph compiled, evicted and compiled again, without and with the persistent
   compilation cache (a fresh folder): the cost of an eviction.

    python benchmarks/executables.py [--data ../shared/data] [--presets paper accurate fast finest]
                                     [-o benchmarks/results]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path


import sswjax
from sswjax.data.layouts import load_scenes
from sswjax.runtime.compilation import enable_compilation_cache
from sswjax.runtime.executables import EXECUTABLES

sys.path.insert(0, str(Path(__file__).parent))
from _report import write_report  # noqa: E402

SETS = ("MiddEval3", "KITTI2012", "Middlebury2001")


def mappings() -> int:
    """This process's memory mappings (``/proc/self/maps`` lines)."""
    with open("/proc/self/maps") as handle:
        return sum(1 for _ in handle)


def many_shapes(data: Path, presets) -> dict:
    """Every preset over every pair of the three sets, in this process."""
    scenes = [scene for name in SETS for scene in load_scenes(data / name)]
    start, shapes, peak = time.perf_counter(), set(), mappings()
    for preset in presets:
        params = sswjax.preset(preset)
        for scene in scenes:
            sswjax.match(scene.left, scene.right, scene.ndisp, params=params)
            shapes.add((preset, scene.left.shape, scene.ndisp))
            peak = max(peak, mappings())
        print(f"{preset}: {len(shapes)} graphs so far, {mappings()} mappings "
              f"(largest {peak}), {time.perf_counter() - start:.0f} s", flush=True)
    return {"graphs": len(shapes), "maps": len(scenes) * len(presets), "peak_mappings": peak,
            "limit": EXECUTABLES.limit, "seconds": time.perf_counter() - start}


def recompile_cost(data: Path, preset: str) -> list[dict]:
    """Compile, evict and compile again one pair's graph, without then with the persistent
    cache; seconds of each call (compilation included)."""
    scene = load_scenes(data / "MiddEval3", scenes=["Teddy"])[0]
    params = sswjax.preset(preset)
    rows = []
    for cached in (False, True):
        if cached:
            enable_compilation_cache(path=tempfile.mkdtemp(prefix="sswjax-cache-"))
        EXECUTABLES.clear()
        times = []
        for evict in (True, False):  # the first compiles (and stores), the second after eviction
            start = time.perf_counter()
            sswjax.match(scene.left, scene.right, scene.ndisp, params=params)
            times.append(time.perf_counter() - start)
            if evict:
                EXECUTABLES.clear()
        warm_start = time.perf_counter()
        sswjax.match(scene.left, scene.right, scene.ndisp, params=params)
        sswjax.match(scene.left, scene.right, scene.ndisp, params=params)
        warm = (time.perf_counter() - warm_start) / 2
        rows.append({"persistent cache": "on" if cached else "off", "first call s": times[0],
                     "after eviction s": times[1], "warm s": warm})
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"))
    parser.add_argument("--presets", nargs="+", default=list(sswjax.PRESETS))
    parser.add_argument("--recompile-preset", default="accurate")
    parser.add_argument("--recompile-only", action="store_true",
                        help="measure only the cost of an eviction (part 2)")
    parser.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results"))
    args = parser.parse_args(argv)
    costs = recompile_cost(args.data, args.recompile_preset)
    if args.recompile_only:
        for row in costs:
            print(row)
        return 0
    run = many_shapes(args.data, args.presets)
    lines = [f"Recompiling an evicted graph (`{args.recompile_preset}`, Teddy Q, fresh process):", "",
             "| persistent cache | first call s | after eviction s | warm s |", "|---|---|---|---|"]
    lines += [f"| {r['persistent cache']} | {r['first call s']:.2f} | {r['after eviction s']:.2f} "
              f"| {r['warm s']:.2f} |" for r in costs]
    lines += ["", f"Every preset ({', '.join(args.presets)}) over the {len(SETS)} shared sets in one "
              f"process: {run['maps']} maps, {run['graphs']} distinct graphs, at most "
              f"{run['limit']} kept; largest mapping count {run['peak_mappings']} "
              f"(vm.max_map_count 65530 by default), {run['seconds']:.0f} s."]
    write_report(args.output, "executables", "\n".join(lines), costs,
                 ["persistent cache", "first call s", "after eviction s", "warm s"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
