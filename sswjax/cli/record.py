"""The record a folder run keeps beside its outputs, so that ``--resume`` continues that run.

A run that writes into a folder (``sswjax match LEFT_DIR RIGHT_DIR -o OUT_DIR``, ``sswjax
evaluate -o OUT``) starts ``OUT/.sswjax-run.json`` with its settings (the command, the
version, the parameters, the range, what changes results of the plan) and adds each output's
name as it is written. ``--resume`` refuses a record whose settings differ from the new
command's, naming what changed, and keeps only the outputs the record lists: a folder never
ends up holding maps of two configurations.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

from sswjax._files import atomic_output

__all__ = ["RECORD_NAME", "RunRecord", "differences"]

RECORD_NAME = ".sswjax-run.json"
"""The record's file name in the run's folder."""

_SHOWN = 4
"""Differences named in a refusal (the rest are counted)."""


def differences(old, new, prefix: str = "") -> list[str]:
    """What changed from the settings ``old`` to ``new``, one ``"key NEW (was OLD)"`` each,
    mappings compared key by key (a stage turned on or off is one difference).

    Examples
    --------
    >>> differences({"ndisp": 16, "params": {"coarse": None, "fill": {"kind": "vote"}}},
    ...             {"ndisp": 32, "params": {"coarse": {"levels": 1}, "fill": {"kind": "vote"}}})
    ['ndisp 32 (was 16)', 'params.coarse {...} (was null)']
    """
    if isinstance(old, Mapping) and isinstance(new, Mapping):
        out = []
        for key in sorted(set(old) | set(new)):
            out += differences(old.get(key), new.get(key), f"{prefix}.{key}" if prefix else key)
        return out
    return [] if old == new else [f"{prefix} {_show(new)} (was {_show(old)})"]


def _show(value) -> str:
    return "{...}" if isinstance(value, Mapping) else json.dumps(value)


class RunRecord:
    """The settings of a folder run and the outputs it has written.

    Use :meth:`start` for a new run and :meth:`resume` for ``--resume``; then :meth:`done` says
    whether an output belongs to the run and :meth:`finished` adds one (written at once).
    """

    def __init__(self, folder: Path, settings: Mapping, finished=()):
        self.folder = Path(folder)
        self.settings = json.loads(json.dumps(dict(settings)))  # as it reads back
        self._finished = list(finished)

    @property
    def path(self) -> Path:
        """The record's file."""
        return self.folder / RECORD_NAME

    @classmethod
    def start(cls, folder: Path, settings: Mapping) -> RunRecord:
        """A new run's record, written (an older record in ``folder`` is replaced)."""
        record = cls(folder, settings)
        record._write()
        return record

    @classmethod
    def resume(cls, folder: Path, settings: Mapping) -> RunRecord:
        """The record of the run to continue; ``ValueError`` (one line) when there is none or
        its settings differ from ``settings``."""
        path = Path(folder) / RECORD_NAME
        try:
            stored = json.loads(path.read_text(encoding="utf-8"))
            old, finished = stored["settings"], stored["finished"]
        except FileNotFoundError:
            raise ValueError(f"cannot --resume {folder}: it holds no record of the settings it "
                             f"was made with ({RECORD_NAME}); run without --resume") from None
        except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError) as error:
            raise ValueError(f"cannot --resume {folder}: its record {path} is unreadable "
                             f"({type(error).__name__}); run without --resume") from None
        record = cls(folder, settings, finished)
        changed = differences(old, record.settings)
        if changed:
            listed = "; ".join(changed[:_SHOWN])
            more = f" and {len(changed) - _SHOWN} more" if len(changed) > _SHOWN else ""
            raise ValueError(f"cannot --resume {folder} with other settings than it was made "
                             f"with: {listed}{more}; run without --resume to start again")
        return record

    def done(self, name: str) -> bool:
        """Whether the output ``name`` was written by this run."""
        return name in self._finished

    def finished(self, name: str) -> None:
        """Add the output ``name`` (written) to the record, at once."""
        if name not in self._finished:
            self._finished.append(name)
            self._write()

    def _write(self) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        with atomic_output(self.path) as tmp:
            tmp.write_text(json.dumps({"settings": self.settings, "finished": self._finished},
                                      indent=1) + "\n", encoding="utf-8")
