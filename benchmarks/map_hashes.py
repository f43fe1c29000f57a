"""SHA-256 of every map each preset computes on the shared data sets, to prove a change bit-neutral.

Run it on two commits and compare the outputs (``diff``): a refactoring that must not change
results shows no difference. Each preset runs in a fresh process (a process that compiles
many shapes grows its memory mappings; one preset's ~50 shapes stay far from the limit).
Per pair it hashes the float32 disparity of ``sswjax.match`` at the exact shape, and on
Middlebury 2001 the three maps of ``sswjax.match_with_confidence`` too. Only names that every
version of sswjax has are used, so the same script measures an older checkout
(``PYTHONPATH=/path/to/old/checkout python benchmarks/map_hashes.py ...``).

    python benchmarks/map_hashes.py [--data ../shared/data] [--presets paper accurate fast finest]
                                    [--sets MiddEval3 KITTI2012 Middlebury2001] -o hashes.txt
"""

from __future__ import annotations

import argparse
import hashlib
import subprocess
import sys
from pathlib import Path

import numpy as np

import sswjax
from sswjax.data.layouts import load_scenes

SETS = ("MiddEval3", "KITTI2012", "Middlebury2001")
PRESETS = ("paper", "accurate", "fast", "finest")


def digest(array) -> str:
    """Hex SHA-256 of an array's dtype, shape and bytes."""
    array = np.ascontiguousarray(array)
    header = f"{array.dtype.str}{array.shape}".encode()
    return hashlib.sha256(header + array.tobytes()).hexdigest()


def hash_preset(preset: str, data: Path, sets) -> list[str]:
    """``<preset> <set> <scene> <what> <sha256>`` lines for one preset, in this process."""
    params = sswjax.preset(preset)
    lines = []
    for name in sets:
        for scene in load_scenes(data / name):
            disparity = sswjax.match(scene.left, scene.right, scene.ndisp, params=params)
            lines.append(f"{preset} {name} {scene.name} disparity {digest(disparity)}")
            if name == "Middlebury2001":
                matched = sswjax.match_with_confidence(scene.left, scene.right, scene.ndisp,
                                                       params=params)
                for what in ("disparity", "confidence", "validity"):
                    lines.append(f"{preset} {name} {scene.name} matched.{what} "
                                 f"{digest(getattr(matched, what))}")
            print(lines[-1], file=sys.stderr, flush=True)
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data"),
                        help="folder holding the data sets (default ../shared/data)")
    parser.add_argument("--presets", nargs="+", default=list(PRESETS))
    parser.add_argument("--sets", nargs="+", default=list(SETS))
    parser.add_argument("-o", "--output", type=Path, required=True)
    parser.add_argument("--one", help=argparse.SUPPRESS)  # the child process: one preset
    args = parser.parse_args(argv)
    if args.one:
        print("\n".join(hash_preset(args.one, args.data, args.sets)))
        return 0
    lines = []
    for preset in args.presets:
        run = subprocess.run([sys.executable, __file__, "--one", preset, "--data", str(args.data),
                              "--sets", *args.sets, "-o", str(args.output)],
                             stdout=subprocess.PIPE, text=True, check=True)
        lines += run.stdout.strip().splitlines()
    args.output.write_text("\n".join(lines) + "\n")
    print(f"wrote {len(lines)} hashes to {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
