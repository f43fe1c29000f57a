"""The persistent compilation cache: bounded and locked; a damaged entry is removed and stored
anew, once, with one line for the user instead of JAX's warning on every run."""

from __future__ import annotations

import os
import subprocess
import sys
import zlib

import jax

from sswjax.runtime.compilation import damaged_entries


def _match(small_pair, tmp_path, cache, name, ndisp=8):
    env = dict(os.environ, SSWJAX_CACHE_DIR=str(cache))
    files = small_pair.folder
    return subprocess.run([sys.executable, "-m", "sswjax.cli", "match", files / "left.png",
                           files / "right.png", "--ndisp", str(ndisp), "--preset", "paper",
                           "-o", tmp_path / f"{name}.pfm"], env=env, capture_output=True,
                          text=True, timeout=600)


def test_a_damaged_cache_entry_is_replaced(small_pair, tmp_path):
    cache = tmp_path / "cache"
    first = _match(small_pair, tmp_path, cache, "first")
    assert first.returncode == 0, first.stderr
    (entry,) = cache.glob("*-cache")
    # The cache is bounded, so JAX kept its entry through the locked path (processes sharing the
    # folder never read a half-written entry): the lock file and the entry's access time.
    assert (cache / ".lockfile").exists() and [p.name for p in cache.glob("*-atime")] == [
        entry.name.removesuffix("-cache") + "-atime"]
    data = bytearray(entry.read_bytes())
    data[len(data) // 2:len(data) // 2 + 64] = bytes(64)  # zeros inside the compressed program
    entry.write_bytes(bytes(data))
    assert damaged_entries(cache) == [entry]
    for executable in cache.glob("graphs/*.xlaexec"):  # else loaded without XLA's cache
        executable.unlink()
    second = _match(small_pair, tmp_path, cache, "second")
    assert second.returncode == 0, second.stderr
    assert "removed a damaged entry of the compilation cache" in second.stderr
    assert "Warning" not in second.stderr and "site-packages" not in second.stderr
    assert damaged_entries(cache) == [] and zlib.decompress(entry.read_bytes())
    third = _match(small_pair, tmp_path, cache, "third")
    assert third.returncode == 0 and third.stderr.count("\n") <= 1, third.stderr  # no note
    assert (tmp_path / "third.pfm").read_bytes() == (tmp_path / "first.pfm").read_bytes()


def test_the_command_line_in_process_leaves_jax_cache_options_as_they_were(small_pair, tmp_path,
                                                                          tiny, monkeypatch):
    """``main`` called in a process that goes on (a test, a notebook) turns the cache on for its
    command only: the graphs are stored in ``$SSWJAX_CACHE_DIR`` during the command, and JAX's
    options are the process's own again when it returns, so what later code compiles does not
    depend on whether a command line ran before it."""
    from sswjax.cli import main

    names = ("jax_compilation_cache_dir", "jax_persistent_cache_min_compile_time_secs",
             "jax_persistent_cache_min_entry_size_bytes", "jax_compilation_cache_max_size")
    before = {name: getattr(jax.config, name) for name in names}
    mine = str(tmp_path / "mine")
    jax.config.update("jax_compilation_cache_dir", mine)  # the process's own setting
    try:
        monkeypatch.setenv("SSWJAX_CACHE_DIR", str(tmp_path / "cli"))
        narrow = small_pair.folder / "narrow.png"  # a size of its own: compiled here
        assert main(["--quiet", "match", str(narrow), str(narrow), "--ndisp", "5", *tiny.args,
                     "-o", str(tmp_path / "d.pfm")]) == 0
        assert list((tmp_path / "cli" / "graphs").iterdir())
        assert jax.config.jax_compilation_cache_dir == mine
        assert {name: getattr(jax.config, name) for name in names[1:]} == {
            name: before[name] for name in names[1:]}
    finally:
        jax.config.update("jax_compilation_cache_dir", before["jax_compilation_cache_dir"])
