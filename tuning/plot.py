"""Plot the training loss and the held-out crop WTA bad 2.0 of a search run.

    python tuning/plot.py tuning/runs/main [tuning/runs/main/curves.png]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path


def plot_run(run: Path, png: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

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


if __name__ == "__main__":
    run = Path(sys.argv[1])
    plot_run(run, Path(sys.argv[2]) if len(sys.argv) > 2 else run / "curves.png")
