"""The warm command line of two versions of the code, alternating: what a start-up change saves.

A change of a few hundredths of a second to the start of ``sswjax match`` is below this host's
noise between runs of ``benchmarks/cold_start.py`` (runs minutes apart differ by 0.1 s). Here
fresh processes of the two versions alternate in one loop, so that the noise hits both: the
commit ``--base``, checked out in a temporary git worktree and put first on ``PYTHONPATH``,
against this working tree. Each version has a compilation cache of its own, warmed by one run
before the loop (the stored trace and executable written, as a user's second run finds them),
and Python's bytecode cache on (:func:`cold_start.child_environment`). Each round runs both,
in turn first. Prints and writes, per preset and version, the median, least and greatest wall
time of ``sswjax match LEFT RIGHT --ndisp N --preset P -o OUT.pfm``.

    python benchmarks/cli_ab.py --base 7b3b19b [--data ../shared/data] [--scene Motorcycle]
                                [--presets accurate fast] [--runs 15] [-o benchmarks/results]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _report import write_report  # noqa: E402
from cold_start import child_environment  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def _environment(cache: Path, source: Path | None) -> dict[str, str]:
    """A measured process's environment; ``source`` (a checkout) first on ``PYTHONPATH``."""
    env = child_environment(cache)
    if source is not None:
        env["PYTHONPATH"] = os.pathsep.join([str(source), *filter(None, [env.get("PYTHONPATH")])])
    return env


def _imported_from(env: dict[str, str], cwd: str) -> Path:
    """The folder the ``sswjax`` package is imported from in a process with ``env``."""
    done = subprocess.run([sys.executable, "-c", "import sswjax; print(sswjax.__file__)"],
                          env=env, cwd=cwd, check=True, capture_output=True, text=True)
    return Path(done.stdout.strip()).parent.parent


def _match_seconds(command: list[str], env: dict[str, str], cwd: str) -> float:
    """Wall time of ``command`` in a new process (run in ``cwd``: a folder without the
    package, which Python would otherwise import from first)."""
    start = time.perf_counter()
    subprocess.run(command, env=env, cwd=cwd, check=True, capture_output=True)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", required=True, help="the commit to compare the tree with")
    parser.add_argument("--data", type=Path, default=Path(os.environ.get(
        "SSWJAX_DATA", REPO.parent / "shared" / "data")))
    parser.add_argument("--scene", default="Motorcycle")
    parser.add_argument("--ndisp", type=int, default=70)
    parser.add_argument("--presets", nargs="+", default=["accurate", "fast"])
    parser.add_argument("--runs", type=int, default=15, help="rounds (one run of each per round)")
    parser.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results"))
    args = parser.parse_args()
    scene = (args.data / "MiddEval3" / "trainingQ" / args.scene).resolve()
    left, right = scene / "im0.png", scene / "im1.png"
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        base = Path(scratch) / "base"
        subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", str(base),
                        args.base], check=True, capture_output=True)
        try:
            versions = {f"base ({args.base})": _environment(Path(scratch) / "cache-base", base),
                        "tree": _environment(Path(scratch) / "cache-tree", None)}
            if _imported_from(versions[f"base ({args.base})"], scratch) != base.resolve():
                raise SystemExit(f"the base version is not imported from {base}")
            for preset in args.presets:
                command = [sys.executable, "-m", "sswjax.cli", "match", str(left), str(right),
                           "--ndisp", str(args.ndisp), "--preset", preset,
                           "-o", f"{scratch}/out.pfm"]
                for env in versions.values():       # warm each cache: trace and executable
                    _match_seconds(command, env, scratch)
                times = {name: [] for name in versions}
                for round_ in range(args.runs):
                    order = list(versions) if round_ % 2 == 0 else list(versions)[::-1]
                    for name in order:
                        times[name].append(_match_seconds(command, versions[name], scratch))
                    print(preset, round_ + 1, {k: round(v[-1], 3) for k, v in times.items()},
                          flush=True)
                rows += [{"preset": preset, "version": name,
                          "median": f"{statistics.median(t):.3f}", "min": f"{min(t):.3f}",
                          "max": f"{max(t):.3f}", "runs": len(t)} for name, t in times.items()]
        finally:
            subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(base)],
                           check=False, capture_output=True)
    keys = ["preset", "version", "median", "min", "max", "runs"]
    table = (f"Warm `sswjax match` on trainingQ {args.scene} ({args.ndisp} disparities), fresh "
             f"processes of the two versions alternating, seconds\n\n"
             "| " + " | ".join(keys) + " |\n|" + "---|" * len(keys) + "\n"
             + "\n".join("| " + " | ".join(str(row[k]) for k in keys) + " |" for row in rows))
    write_report(args.output, "cli_ab", table, rows, keys)


if __name__ == "__main__":
    main()
