"""Which way the soft objective pushes P2, at several soft-argmin temperatures.

    python tuning/p2_temperature.py

The gradient of the search loss (``sswjax.search.batch_loss`` through the ``accurate``
preset's SGM) with respect to the raw P2 (softplus: same sign as d loss / d P2), on 12 fixed
64 x 128 crops of the two Middlebury sets (trainingQ and Middlebury 2001 scenes with
ndisp <= 96, seed 5), at P2 0.8 (``accurate``) and 1.5 (where the leave-one-dataset-out
searches went) and temperatures 0.02, 0.08 (the searches' start) and 0.25 (where they ended).
A negative gradient asks for a larger P2. Figures: ``tuning/README.md``.
"""

from __future__ import annotations

import jax
import numpy as np

from sswjax import search as tuning
from sswjax.config import preset
from sswjax.data.layouts import load_scenes

DATA = ("/work/shared/data/MiddEval3", "/work/shared/data/Middlebury2001")


def main() -> None:
    base = preset("accurate")
    scenes = [tuning.prepare_scene(s, channels=3) for root in DATA for s in load_scenes(root)
              if s.ndisp <= 96]
    batch = tuning.random_crops(scenes, np.random.default_rng(5), batch=12, height=64,
                                width=128, min_valid=0.1)
    objective = jax.jit(jax.value_and_grad(
        lambda raw: tuning.batch_loss(raw, *batch, base=base, ndisp=96)))
    print("| P2 | temperature | loss | d loss / d raw P2 | d loss / d raw sigma |")
    print("|---|---|---|---|---|")
    for p2 in (0.8, 1.5):
        for temperature in (0.02, 0.08, 0.25):
            raw = tuning.to_unconstrained(base.replace(**{"optimizer.p2": p2}),
                                          temperature=temperature, searched=tuning.SGM_SEARCHED)
            value, grads = objective(raw)
            print(f"| {p2} | {temperature} | {float(value):.4f} | {float(grads['optimizer.p2']):+.4f} | "
                  f"{float(grads['optimizer.sigma']):+.4f} |", flush=True)


if __name__ == "__main__":
    main()
