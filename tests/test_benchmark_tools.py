"""The pure helpers of benchmarks/top_ops.py (a stage's wall time from a trace),
benchmarks/graph_ab.py (a function as a commit defines it), benchmarks/front.py (where the
plot's labels go) and benchmarks/compile_kernels.py (kernel times from XLA's log)."""

import subprocess
import sys
from pathlib import Path

import jax.numpy as jnp
import pytest

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))

import compile_kernels  # noqa: E402
import front  # noqa: E402
import graph_ab  # noqa: E402
import top_ops  # noqa: E402


def test_busy_time_counts_overlapping_operations_once():
    # 0-10 and 5-12 overlap (12 us), 20-25 is apart (5 us), 21-22 lies inside it.
    assert top_ops.busy_ms([(20, 25), (0, 10), (5, 12), (21, 22)]) == pytest.approx(0.017)
    assert top_ops.busy_ms([(0, 4), (4, 6)]) == pytest.approx(0.006)


def test_spans_give_each_stage_and_the_idle_time():
    names = {"a": "jit(f)/cost/add", "b": "jit(f)/while/body/optimization/min", "c": "jit(f)/x"}
    events = [{"name": "a", "ts": 100, "dur": 10_000}, {"name": "b", "ts": 15_100, "dur": 5_000},
              {"name": "b", "ts": 18_100, "dur": 4_000}, {"name": "c", "ts": 30_100, "dur": 1_000}]
    table = top_ops.spans(events, names)
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
    found = graph_ab.base_functions("HEAD", "sswjax.stages.loops", ["repeated"])
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
    kernels, total = compile_kernels.kernel_times(log)
    assert kernels == pytest.approx([0.0399, 0.000368])
    assert total == pytest.approx(5.54)
    assert compile_kernels.kernel_times("no XLA log here") == ([], None)
