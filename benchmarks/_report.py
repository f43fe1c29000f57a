"""Writing a benchmark's results: the Markdown table printed and saved, and the rows as CSV."""

from __future__ import annotations

import csv
import json
from collections.abc import Mapping, Sequence
from pathlib import Path


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
