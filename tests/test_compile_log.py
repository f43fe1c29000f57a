"""A sign of life while a graph compiles (issue 72, item 12).

A call that meets a graph this process has not compiled (a new image size, range or parameters)
logs at ``INFO`` on the ``sswjax`` logger before it compiles and once it is done, with the time
it took; the same call again logs nothing. The library adds a ``NullHandler`` only (silent
unless the application configures logging); the command line shows the lines on stderr as
``sswjax: compiling ...``, a terminal or not, and ``--quiet`` silences them. Each test uses an
image size of its own (a cheap method, the paper's without superpixels and with a 3x3 box), so
that its first call compiles whatever ran before in the process.
"""

from __future__ import annotations

import logging
import os
import re
import subprocess
import sys

import imageio.v3 as iio
import numpy as np

import sswjax

CHEAP = sswjax.preset("paper").replace(segments=None, aggregation="box",
                                       **{"aggregation.radius": 1})
CHEAP_ARGS = ["--preset", "paper", "--set", "segments=none", "--set", "aggregation=box",
              "--set", "aggregation.radius=1"]
NAME = "paper (segments off, aggregation changed)"
COMPILED = re.compile(r"compiled in \d+\.\d s")


def _pair(texture, width: int, height: int = 20):
    right = texture(7, (height, width, 3))
    return np.roll(right, 3, axis=1), right


def _compile_records(caplog):
    return [record for record in caplog.records if record.name.startswith("sswjax")]


def test_a_new_shape_logs_before_and_after_compiling_and_a_warm_call_nothing(texture, caplog):
    left, right = _pair(texture, 36)
    caplog.set_level(logging.INFO, logger="sswjax")
    sswjax.match(left, right, 8, params=CHEAP)
    records = _compile_records(caplog)
    assert [record.levelno for record in records] == [logging.INFO, logging.INFO]
    assert records[0].getMessage() == (f"compiling {NAME} for 36x20, ndisp 8 (first call for "
                                       "this shape; cached for the next)")
    assert COMPILED.fullmatch(records[1].getMessage()), records[1].getMessage()
    caplog.clear()
    sswjax.match(left, right, 8, params=CHEAP)  # compiled: nothing to say
    assert _compile_records(caplog) == []
    sswjax.match(left, right, 6, params=CHEAP)  # another range: another graph
    assert [r.getMessage() for r in _compile_records(caplog)][0] == (
        f"compiling {NAME} for 36x20, ndisp 6 (first call for this shape; cached for the next)")


def test_a_preset_is_named_and_the_library_is_silent_without_logging_configured():
    """The ``sswjax`` logger has a ``NullHandler`` and no level of its own: an application
    that configures nothing sees nothing (Python's last-resort handler shows warnings only)."""
    logger = logging.getLogger("sswjax")
    assert any(isinstance(handler, logging.NullHandler) for handler in logger.handlers)
    assert logger.level == logging.NOTSET and not logger.isEnabledFor(logging.INFO)
    from sswjax.runtime.executables import compiling_message

    image = np.zeros((20, 30, 3), np.float32)
    assert compiling_message(sswjax.match, (image, image),
                             {"params": sswjax.preset("fast"), "ndisp": 16}) == (
        "compiling fast for 30x20, ndisp 16 (first call for this shape; cached for the next)")
    batch = np.zeros((4, 20, 30, 3), np.float32)
    assert compiling_message(sswjax.match, (batch, batch, None, None, sswjax.Params()),
                             {"ndisp": 16}) == (
        "compiling paper for a batch of 4 pairs of 30x20, ndisp 16 (first call for this shape; "
        "cached for the next)")


def _write_pair(texture, folder, width):
    left, right = _pair(texture, width)
    folder.mkdir()
    iio.imwrite(folder / "l.png", left)
    iio.imwrite(folder / "r.png", right)
    return folder / "l.png", folder / "r.png"


def test_the_command_line_shows_the_compile_on_stderr_and_quiet_silences_it(texture, tmp_path,
                                                                           capsys):
    """In process (stderr captured, not a terminal): the two lines, once each; ``--quiet``
    (before the command, as ``--debug``) leaves stderr empty. (conftest's ``run_cli`` passes
    ``--quiet``: ``main`` is called here as it is.)"""
    from sswjax.cli import main

    def run_cli(argv):
        code = main([str(arg) for arg in argv])
        captured = capsys.readouterr()
        return code, captured.out, captured.err

    left, right = _write_pair(texture, tmp_path / "a", 44)
    code, out, err = run_cli(["match", left, right, "--ndisp", "8", *CHEAP_ARGS,
                              "-o", tmp_path / "a.pfm"])
    assert code == 0, err
    lines = err.splitlines()
    assert lines[0] == (f"sswjax: compiling {NAME} for 44x20, ndisp 8 (first call for this "
                        "shape; cached for the next)"), err
    assert len(lines) == 2 and COMPILED.fullmatch(lines[1].removeprefix("sswjax: ")), err
    left, right = _write_pair(texture, tmp_path / "b", 48)
    code, out, err = run_cli(["--quiet", "match", left, right, "--ndisp", "8", *CHEAP_ARGS,
                              "-o", tmp_path / "b.pfm"])
    assert (code, err) == (0, ""), err
    assert (tmp_path / "b.pfm").exists()
    assert not logging.getLogger("sswjax").handlers[1:]  # the command's handler is gone


def test_a_piped_process_shows_the_compile_lines(texture, tmp_path):
    """A script reading stderr (not a terminal) sees the lines too; a second process finds the
    compiled graph in the cache and says nothing."""
    left, right = _write_pair(texture, tmp_path / "p", 52)
    env = {**os.environ, "SSWJAX_CACHE_DIR": str(tmp_path / "cache")}
    argv = [sys.executable, "-m", "sswjax.cli", "match", str(left), str(right), "--ndisp", "8",
            *CHEAP_ARGS, "-o", str(tmp_path / "d.pfm")]
    first = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=300)
    assert first.returncode == 0, first.stderr
    assert first.stderr.startswith(f"sswjax: compiling {NAME} for 52x20, ndisp 8 "), first.stderr
    assert re.search(r"^sswjax: compiled in \d+\.\d s$", first.stderr, re.M), first.stderr
    second = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=300)
    assert (second.returncode, second.stderr) == (0, ""), second.stderr
