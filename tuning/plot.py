"""The report of a run of the earlier search driver (``tuning/search.py``, out of the tree since
issue 70, superseded by ``sswjax search``: ``docs/notes/benchmarks-concluded.md``): its curves
and its tables.

    python tuning/plot.py tuning/runs/main [tuning/runs/main/curves.png]

redraws the curves (:func:`plot_run`: the training loss and the held-out crop WTA bad 2.0).
:func:`summarise` and :func:`weighted` average per-scene metrics as ``sswjax evaluate`` does;
:func:`results_markdown` writes the held-out table of a leave-one-dataset-out run.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from sswjax.evaluation.metrics import weighted_average
from sswjax.evaluation.runner import MIDDEVAL3_SCORING


def plot_run(run: Path, png: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run = Path(run)
    logs = sorted(p for p in run.glob("*/log.json"))
    if not logs:
        return
    fig, (ax_loss, ax_val) = plt.subplots(1, 2, figsize=(11, 4))
    for path in logs:
        log = json.loads(path.read_text())
        name = path.parent.name
        if log["loss"]:
            steps, values = np.array([r[0] for r in log["loss"]]), np.array([r[1] for r in log["loss"]])
            k = min(10, len(values))
            smooth = np.convolve(values, np.ones(k) / k, mode="valid")
            line, = ax_loss.plot(steps, values, alpha=0.25)
            ax_loss.plot(steps[k - 1:], smooth, color=line.get_color(), label=name)
        if log["val"]:
            what = "held-out" if name.startswith("fold") else "train"
            ax_val.plot([r[0] for r in log["val"]], [r[1] for r in log["val"]], "o-",
                        label=f"{name} ({what} crops)")
    ax_loss.set(xlabel="step", ylabel="smooth-L1 loss (px), soft-argmin", title="training loss")
    ax_val.set(xlabel="step", ylabel="bad 2.0 (%) of WTA pipeline on fixed crops",
               title="validation error")
    ax_loss.legend(), ax_val.legend()
    fig.tight_layout()
    fig.savefig(png, dpi=100)
    plt.close(fig)


def weighted(per_scene: dict) -> dict:
    """MiddEval3's weighted bad 2.0 / 1.0 / 0.5 of per-scene metrics, nonocc and all."""
    return summarise(per_scene, MIDDEVAL3_SCORING)


def summarise(per_scene: dict, scoring) -> dict:
    """``{region: {metric: average}}`` of per-scene metrics under a data set's ``scoring``
    (:data:`sswjax.evaluation.runner.SCORINGS`: MiddEval3 weighted, the others plain means)."""
    out = {}
    for region in ("nonocc", "all"):
        if not all(region in m for m in per_scene.values()):
            continue
        out[region] = {}
        for key in scoring.keys:
            values = {s: m[region][key] for s, m in per_scene.items()}
            out[region][key] = (weighted_average(values, weights=scoring.weights)
                                if scoring.average == "weighted"
                                else float(np.mean(list(values.values()))))
    return out


TABLE_ROWS = {  # data set -> (region, metric keys) of its held-out row, as the README reports it
    "MiddEval3": ("both", ("bad2.0", "bad1.0", "bad0.5")),
    "KITTI2012": ("all", ("bad2.0", "bad3.0")),
}


def results_markdown(results: dict) -> str:
    """The held-out table (one row per fold and metric) and the searched values, as Markdown."""
    base = results["pipeline"]
    lines = [f"| held out | searched on | metric | `{base}` | searched |", "|---|---|---|---|---|"]
    for fold in results["folds"]:
        region, keys = TABLE_ROWS.get(fold["held_out"], ("all", ("bad2.0",)))
        for key in keys:
            if region == "both":
                what = f"{key[:3]} {key[3:]} nonocc / all (weighted)"
                cells = [f"{fold[c]['nonocc'][key]:.2f} / {fold[c]['all'][key]:.2f}"
                         for c in (base, "searched")]
            else:
                what = f"{key[:3]} {key[3:]} (mean over scenes)"
                cells = [f"{fold[c][region][key]:.2f}" for c in (base, "searched")]
            lines.append(f"| {fold['held_out']} | {' + '.join(fold['trained_on'])} | {what} | "
                         f"{cells[0]} | {cells[1]} |")
    fields = results["searched_fields"]
    lines += ["", "| parameters | " + " | ".join(fields) + " | temperature |",
              "|---|" + "---|" * (len(fields) + 1)]
    first = results["folds"][0]
    lines.append(f"| `{base}` (start) | " + " | ".join(f"{first['start'][k]:.4g}" for k in fields)
                 + " | |")
    for fold in results["folds"]:
        lines.append(f"| searched without {fold['held_out']} | "
                     + " | ".join(f"{fold['params'][k]:.4g}" for k in fields)
                     + f" | {fold['temperature']:.3g} |")
    if "final_params" in results:
        lines.append("| searched on all sets | " + " | ".join(
            f"{results['final_params'][k]:.4g}" for k in fields) + " | |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    run = Path(sys.argv[1])
    plot_run(run, Path(sys.argv[2]) if len(sys.argv) > 2 else run / "curves.png")
