"""The persistent compilation cache: bounded and locked; a damaged entry is removed and stored
anew, once, with one line for the user instead of JAX's warning on every run."""

from __future__ import annotations

import os
import subprocess
import sys
import zlib

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


def test_entries_stored_before_the_bound_do_not_stop_new_ones(small_pair, tmp_path):
    # sswjax before 2026-12-04 kept the cache unbounded: its entries have no access-time file,
    # and JAX's bounded cache reads one for every entry before it stores a new entry (it failed
    # with a warning, and nothing new was stored while such an entry stayed).
    cache = tmp_path / "cache"
    first = _match(small_pair, tmp_path, cache, "first")
    assert first.returncode == 0, first.stderr
    for atime in cache.glob("*-atime"):
        atime.unlink()
    (old,) = cache.glob("*-cache")
    second = _match(small_pair, tmp_path, cache, "second", ndisp=12)  # a new graph to store
    assert second.returncode == 0, second.stderr
    assert "Error writing" not in second.stderr and "Warning" not in second.stderr, second.stderr
    entries = sorted(cache.glob("*-cache"))
    assert len(entries) == 2 and old in entries
    assert sorted(p.name.removesuffix("-atime") for p in cache.glob("*-atime")) == sorted(
        p.name.removesuffix("-cache") for p in entries)
