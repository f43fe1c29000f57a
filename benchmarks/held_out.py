"""Choose a configuration on two data sets and score it on the third: leave-one-data-set-out.

Reads the CSV files that ``benchmarks/ablation.py`` writes (several runs may be combined; a
configuration name seen twice keeps its last row) and, for each data set held out, picks the
configuration with the lowest mean over the other sets of its error divided by the best error on
that set. A set's error is its bad 2.0: trainingQ's the mean of weighted nonocc and all, the
others' the mean over scenes. The held-out error of the choice is what a user on a new kind of
scene should expect; "best possible" is the lowest error on the held-out set itself.

    python benchmarks/held_out.py benchmarks/results/ablation/ablation.csv other-run/ablation.csv
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

from _report import write_report  # benchmarks/, on the path when run as a script

ERRORS = {  # set -> the CSV columns whose mean is its error
    "trainingQ": ("trainingQ bad2.0 nonocc", "trainingQ bad2.0 all"),
    "KITTI2012": ("KITTI2012 bad2.0 all",),
    "Middlebury2001": ("Middlebury2001 bad2.0 all",),
}


def read_errors(paths) -> dict[str, dict[str, float]]:
    """Configuration name -> {set: error}, for the configurations scored on every set."""
    errors = {}
    for path in paths:
        with open(path, newline="") as handle:
            for row in csv.DictReader(handle):
                if all(row.get(column) not in (None, "") for cols in ERRORS.values()
                       for column in cols):
                    errors[row["config"]] = {
                        name: sum(float(row[c]) for c in cols) / len(cols)
                        for name, cols in ERRORS.items()}
    return errors


def choose(errors: dict[str, dict[str, float]], sets) -> str:
    """The configuration with the lowest mean relative error over ``sets``."""
    best = {name: min(e[name] for e in errors.values()) for name in sets}
    return min(errors, key=lambda config: sum(errors[config][name] / best[name] for name in sets))


def held_out_rows(errors: dict[str, dict[str, float]]) -> list[dict]:
    """One row per held-out set, and a last row chosen on all three."""
    rows = []
    for held in ERRORS:
        chosen = choose(errors, [name for name in ERRORS if name != held])
        best = min(errors, key=lambda config: errors[config][held])
        rows.append({"held out": held, "chosen on the other two": chosen,
                     "held-out error": f"{errors[chosen][held]:.2f}",
                     "best possible": f"{errors[best][held]:.2f} ({best})"})
    chosen = choose(errors, list(ERRORS))
    rows.append({"held out": "none", "chosen on the other two": f"{chosen} (on all three)",
                 "held-out error": "", "best possible": ""})
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("csv", nargs="+", type=Path, help="ablation.csv files")
    parser.add_argument("-o", "--output", type=Path, default=Path("benchmarks/results/held_out"))
    args = parser.parse_args(argv)
    errors = read_errors(args.csv)
    if len(errors) < 2:
        print("held_out: need at least two configurations scored on all three sets",
              file=sys.stderr)
        return 2
    rows = held_out_rows(errors)
    keys = list(rows[0])
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(row[k] for k in keys) + " |" for row in rows]
    write_report(args.output, "held_out", "\n".join(lines), rows, keys)
    return 0


if __name__ == "__main__":
    sys.exit(main())
