"""What the benchmarks share (a helper module, not a benchmark): the three shared data sets and
how each is scored, and writing a benchmark's results (the Markdown table printed and saved,
the rows as CSV or JSON)."""

from __future__ import annotations

import csv
import json
from collections.abc import Mapping, Sequence
from pathlib import Path

SETS = {  # name -> (folder under the data root, scoring, reported (region, metric) columns)
    "trainingQ": ("MiddEval3", "middeval3",
                  [("nonocc", "bad2.0"), ("all", "bad2.0"), ("nonocc", "bad1.0"), ("all", "bad1.0"),
                   ("nonocc", "bad0.5"), ("all", "bad0.5")]),
    "KITTI2012": ("KITTI2012", "kitti", [("all", "bad2.0"), ("all", "bad3.0")]),
    "Middlebury2001": ("Middlebury2001", "mean", [("all", "bad2.0")]),
}
"""The shared data sets as the benchmarks score them: the scoring is a key of
:data:`sswjax.evaluation.runner.SCORINGS`."""


def whole_pair_graph(params):
    """The jitted program that ``sswjax.match`` runs on a pair matched whole, and the static
    keywords it takes beyond ``ndisp``: ``ssw_aligned`` (the alignment, then the method, in one
    program) when ``params`` hold the alignment, ``ssw_disparity`` otherwise."""
    from sswjax.graph import ssw_disparity
    from sswjax.graph.alignment import ssw_aligned

    if params.alignment is None:
        return ssw_disparity, {}
    return ssw_aligned, {"method": "ssw_disparity"}


def parse_config(text: str):
    """A benchmark's ``--config``: ``NAME=BASE:JSON``, ``NAME=BASE`` or ``BASE`` -> (row name,
    :class:`sswjax.Params`), ``BASE`` a preset's name or a parameter file, ``JSON`` the changes
    on top (``Params.replace`` paths)."""
    import sswjax  # here, so that writing a report needs no JAX

    name, _, spec = text.partition("=") if "=" in text else (text, "", text)
    base, _, changes = spec.partition(":")
    params = sswjax.preset(base) if base in sswjax.PRESETS else sswjax.load_params(base)
    return name, params.replace(**json.loads(changes)) if changes else params


def write_report(folder: Path, stem: str, table: str, rows: Sequence[Mapping], keys: Sequence[str]) -> None:
    """Print ``table`` and write it to ``folder/stem.md``, and ``rows`` to ``folder/stem.csv``."""
    print(table)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{stem}.md").write_text(table + "\n")
    with open(folder / f"{stem}.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(keys))
        writer.writeheader()
        writer.writerows(rows)


def write_json_report(folder: Path, stem: str, table: str, rows) -> None:
    """Print ``table`` and write it to ``folder/stem.md``, and ``rows`` (any JSON) to
    ``folder/stem.json``."""
    print(table)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{stem}.md").write_text(table + "\n")
    (folder / f"{stem}.json").write_text(json.dumps(rows, indent=1) + "\n")
