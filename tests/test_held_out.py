"""benchmarks/held_out.py: leave-one-data-set-out choice over ablation results."""

import csv
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import held_out  # noqa: E402


def _write(path, rows):
    keys = ["config", "trainingQ bad2.0 nonocc", "trainingQ bad2.0 all", "KITTI2012 bad2.0 all",
            "Middlebury2001 bad2.0 all"]
    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=keys)
        writer.writeheader()
        for name, values in rows.items():
            writer.writerow(dict(zip(keys, [name, *values])))


def test_each_fold_chooses_on_the_other_two_sets(tmp_path):
    # "a" is best on trainingQ, "b" on KITTI and "c" on Middlebury 2001; with trainingQ held out
    # the choice is made on KITTI and Middlebury 2001 only, and so on.
    _write(tmp_path / "one.csv", {"a": (8.0, 14.0, 12.0, 2.0), "b": (10.0, 16.0, 10.0, 2.1)})
    _write(tmp_path / "two.csv", {"c": (10.0, 16.0, 12.0, 1.0)})
    errors = held_out.read_errors([tmp_path / "one.csv", tmp_path / "two.csv"])
    assert errors["a"]["trainingQ"] == 11.0
    rows = {r["held out"]: r for r in held_out.held_out_rows(errors)}
    assert rows["trainingQ"]["chosen on the other two"] == "c"     # 1.2 + 1.0 beats b's 1.0 + 2.1
    assert rows["trainingQ"]["held-out error"] == "13.00"
    assert rows["trainingQ"]["best possible"] == "11.00 (a)"
    assert rows["KITTI2012"]["chosen on the other two"] == "c"     # 13/11 + 1.0 < 1.0 + 2.0
    assert rows["Middlebury2001"]["chosen on the other two"] == "b"  # 13/11 + 1.0 < 1.0 + 1.2
    assert rows["none"]["chosen on the other two"] == "c (on all three)"


def test_rows_missing_a_set_are_left_out(tmp_path):
    _write(tmp_path / "one.csv", {"a": (8.0, 14.0, 12.0, 2.0), "b": (10.0, 16.0, "", 2.1)})
    assert list(held_out.read_errors([tmp_path / "one.csv"])) == ["a"]
    assert held_out.main([str(tmp_path / "one.csv"), "-o", str(tmp_path / "out")]) == 2
