"""The benchmarks folder: living scripts only, each saying what it measures and its command;
the pure helpers of benchmarks/speed.py (a stage's wall time from a trace, kernel times from
XLA's log), benchmarks/ab.py (a function as a commit defines it) and benchmarks/front.py
(where the plot's labels go); benchmarks/grid.py's held-out choice from CSV files, run as a
script."""

import ast
import csv
import subprocess
import sys
from pathlib import Path

import jax.numpy as jnp
import pytest

REPO = Path(__file__).resolve().parents[1]
BENCHMARKS = REPO / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))

import ab  # noqa: E402
import front  # noqa: E402
import speed  # noqa: E402


# a figure drawn as another script draws it: the runners of the front's methods, the cloud's plot
REUSED = {("error_maps.py", "front"), ("raw_camera.py", "point_cloud")}


def _scripts() -> list[Path]:
    return sorted(p for p in BENCHMARKS.glob("*.py") if not p.name.startswith("_"))


def test_benchmarks_are_few_and_each_says_what_it_measures_and_its_command():
    scripts = _scripts()
    assert 0 < len(scripts) <= 16, [p.name for p in scripts]
    for path in scripts:
        doc = ast.get_docstring(ast.parse(path.read_text()))
        assert doc and len(doc.split("\n\n")[0]) > 40, f"{path.name}: no docstring to speak of"
        assert f"python benchmarks/{path.name}" in doc, f"{path.name}: no command in its docstring"
        # no private name of the package; no other script but the _report helper and REUSED
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module:
                if node.module.startswith("sswjax"):
                    assert not [a.name for a in node.names if a.name.startswith("_")], path.name
                else:
                    assert not (BENCHMARKS / f"{node.module}.py").is_file() or node.module == (
                        "_report") or (path.name, node.module) in REUSED, (path.name, node.module)


def test_busy_time_counts_overlapping_operations_once():
    # 0-10 and 5-12 overlap (12 us), 20-25 is apart (5 us), 21-22 lies inside it.
    assert speed.busy_ms([(20, 25), (0, 10), (5, 12), (21, 22)]) == pytest.approx(0.017)
    assert speed.busy_ms([(0, 4), (4, 6)]) == pytest.approx(0.006)


def test_spans_give_each_stage_and_the_idle_time():
    names = {"a": "jit(f)/cost/add", "b": "jit(f)/while/body/optimization/min", "c": "jit(f)/x"}
    events = [{"name": "a", "ts": 100, "dur": 10_000}, {"name": "b", "ts": 15_100, "dur": 5_000},
              {"name": "b", "ts": 18_100, "dur": 4_000}, {"name": "c", "ts": 30_100, "dur": 1_000}]
    table = speed.spans(events, names)
    assert "| cost | 0.0 | 10.0 | 10.0 | 1 |" in table
    assert "| optimization | 15.0 | 22.0 | 7.0 | 2 |" in table
    assert "| - | 30.0 | 31.0 | 1.0 | 1 |" in table
    assert "31.0 ms from the first operation to the last, 13.0 ms of it with no operation" in table


def test_labels_of_close_markers_take_places_that_do_not_overlap():
    # Three markers a few points apart on one row (as Middlebury 2001's presets are), one far.
    anchors = [(211.0, 52.7), (206.7, 52.9), (239.4, 53.1), (400.0, 53.0)]
    labels = ["accurate", "balanced", "finest", "pandora"]
    places = front._label_places(anchors, labels)
    assert places[0] == places[3] == front._PLACES[0]  # up and to the right when free
    boxes = []
    for (x, y), label, (dx, dy, align) in zip(anchors, labels, places):
        width = 6.0 * len(label)
        left = x + dx if align == "left" else x + dx - width
        boxes.append((left, left + width, y + dy, y + dy + 9.0))
    for i, (a, b, e, f) in enumerate(boxes):
        for c, d, g, h in boxes[:i]:
            assert not (a < d and c < b and e < h and g < f)


def test_a_function_as_a_commit_defines_it():
    head = subprocess.run(["git", "-C", str(REPO), "rev-parse", "HEAD"], capture_output=True,
                          text=True)
    if head.returncode != 0:
        pytest.skip("not a git checkout")
    found = ab.base_functions("HEAD", "sswjax.stages.loops", ["repeated"])
    repeated = found["repeated"]
    assert repeated.__module__ == "sswjax.stages.loops@HEAD"
    assert float(repeated(lambda x: x * 2.0, jnp.float32(1.0), times=3)) == 8.0


def test_kernel_times_are_read_from_xlas_verbose_log():
    # Lines as jaxlib 0.10.2's XLA CPU writes them, with other lines between.
    log = "\n".join([
        "I1207 06:05:43.156926 30575 ir_compiler.cc:293] Compiled LLVM module: "
        "__compute_module_multiply_divide_fusion.1_kernel_module time: 39.9 ms (39944 us) "
        "(cumulative: 5.56 s, max: 157 ms, #called: 356)",
        "I1207 06:05:43.160000 30575 hlo_pass_pipeline.cc:176] HLO pass: dce time: 4 ms",
        "I1207 06:05:43.300734 30575 ir_compiler.cc:293] Compiled LLVM module: "
        "__compute_module___compute_module_wrapped_multiply time: 368 us (368 us) "
        "(cumulative: 5.83 s, max: 157 ms, #called: 375)",
        "I1207 06:05:43.602436 30575 cpu_compiler.cc:2094] Compiling [jit_ssw_disparity] for "
        "CPU using JIT time: 5.54 s (5537914 us) (cumulative: 5.54 s, max: 5.54 s, #called: 1)",
    ])
    kernels, total = speed.kernel_times(log)
    assert kernels == pytest.approx([0.0399, 0.000368])
    assert total == pytest.approx(5.54)
    assert speed.kernel_times("no XLA log here") == ([], None)


def _write_rows(path, rows):
    """A grid CSV: bad 2.0 / 1.0 / 0.5 per set and region, one row per configuration."""
    keys = ["config"] + [f"{s} {k} {r}" for s, regions in (("trainingQ", ("nonocc", "all")),
                                                           ("KITTI2012", ("all",)),
                                                           ("Middlebury2001", ("all",)))
                         for r in regions for k in ("bad2.0", "bad1.0", "bad0.5")]
    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=keys)
        writer.writeheader()
        for name, bad2 in rows.items():
            # bad 2.0 as given (trainingQ nonocc, all, KITTI, M2001); 1.0 and 0.5 twice and
            # thrice it, so that the thresholds' rule agrees with bad 2.0's here
            values = dict(zip(("trainingQ nonocc", "trainingQ all", "KITTI2012 all",
                               "Middlebury2001 all"), bad2))
            row = {"config": name}
            for column in keys[1:]:
                set_name, key, region = column.split(" ")
                value = values[f"{set_name} {region}"]
                row[column] = "" if value == "" else value * {"bad2.0": 1, "bad1.0": 2,
                                                              "bad0.5": 3}[key]
            writer.writerow(row)


def _grid(*args, cwd):
    return subprocess.run([sys.executable, str(BENCHMARKS / "grid.py"), *map(str, args)],
                          capture_output=True, text=True, cwd=cwd)


def test_grid_chooses_each_fold_on_the_other_two_sets_from_csv_files(tmp_path):
    # "a" is best on trainingQ, "b" on KITTI, "c" on Middlebury 2001; "c" appears in the second
    # file only, and "b"'s second row replaces its first.
    _write_rows(tmp_path / "one.csv", {"a": (8.0, 14.0, 12.0, 2.0), "b": (9.0, 9.0, 9.0, 9.0)})
    _write_rows(tmp_path / "two.csv", {"b": (10.0, 16.0, 10.0, 2.1),
                                       "c": (10.0, 16.0, 12.0, 1.0)})
    done = _grid("held-out", tmp_path / "one.csv", tmp_path / "two.csv", "-o", tmp_path / "out",
                 cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    with open(tmp_path / "out" / "held_out.csv", newline="") as handle:
        folds = {row["held out"]: row for row in csv.DictReader(handle)}
    assert folds["trainingQ"]["chosen on the other two"] == "c"
    assert folds["trainingQ"]["held-out error"] == "13.00"
    assert folds["trainingQ"]["best possible"] == "11.00 (a)"
    assert folds["KITTI2012"]["chosen on the other two"] == "c"
    assert folds["Middlebury2001"]["chosen on the other two"] == "b"
    assert folds["none"]["chosen on the other two"] == "c (on all three)"
    with open(tmp_path / "out" / "held_out_thresholds.csv", newline="") as handle:
        thresholds = {row["held out"]: row for row in csv.DictReader(handle)}
    assert thresholds["trainingQ"]["chosen"] == "c"
    assert thresholds["trainingQ"]["held-out bad 2.0 / 1.0 / 0.5"] == "13.00 / 26.00 / 39.00"


def test_grid_refuses_rows_that_miss_a_set(tmp_path):
    _write_rows(tmp_path / "one.csv", {"a": (8.0, 14.0, 12.0, 2.0), "b": (10.0, 16.0, "", 2.1)})
    done = _grid("held-out", tmp_path / "one.csv", "-o", tmp_path / "out", cwd=tmp_path)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines()[-1] == (
        "grid.py held-out: error: need at least two configurations scored on all three sets")
    assert not (tmp_path / "out").exists()
    done = _grid("held-out", tmp_path / "none.csv", cwd=tmp_path)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines()[-1].endswith(f"no such file: {tmp_path / 'none.csv'}")


def test_results_page_is_written_from_a_front_csv(tmp_path):
    """The results page (docs/results.md) is generated from a run's front.csv: every set, method
    and figure, the run's date, machine and command, and the command that wrote the page."""
    run = tmp_path / "results" / "front"
    run.mkdir(parents=True)
    keys = ["method", "kind", "trainingQ s/pair", "trainingQ x sgbm", "trainingQ bad2.0 nonocc",
            "trainingQ bad2.0 all", "trainingQ ahead", "Middlebury2001 s/pair",
            "Middlebury2001 x sgbm", "Middlebury2001 bad2.0 all", "Middlebury2001 ahead"]
    rows = [["accurate", "preset", 0.5, 9.3, 6.7, 11.47, True, 0.136, 8.8, 1.19, True],
            ["sgbm", "peer", 0.037, 1.0, 15.43, 22.01, "", 0.012, 1.0, 2.73, ""]]
    with open(run / "front.csv", "w", newline="") as handle:
        csv.writer(handle).writerows([keys, *rows])
    (run / "front.json").write_text('{"date": "2026-12-07", "machine": "cpu:0; x86_64", '
                                    '"repeats": 3, "command": "python benchmarks/front.py"}')
    page = tmp_path / "docs" / "results.md"
    assert front.main(["--page", str(page), "--from", str(run)]) == 0
    text = page.read_text()
    assert f"--page {page} --from {run}" in text and "do not edit by hand" in text
    assert "Figures as of 2026-12-07: cpu:0; x86_64" in text and "python benchmarks/front.py" in text
    assert "## MiddEval3 trainingQ" in text and "## Middlebury 2001" in text and "## KITTI" not in text
    assert "| `accurate` | 0.500 | 9.3 | **6.70** / **11.47** | yes |" in text
    assert "(`sgbm`) | 0.037 | 1.0 | 15.43 / 22.01 |  |" in text
    assert "](../results/front/front.csv)" in text
