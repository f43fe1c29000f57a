"""Traced graphs and executables stored on disk (sswjax.runtime.stored) and ``sswjax warmup``: a
stored graph gives jax.jit's results bit for bit, is found again by the same signature only,
survives a damaged file, runs under transformations; a warmed shape is matched in a new process
without tracing or compiling."""

from __future__ import annotations

import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.experimental.compilation_cache import compilation_cache

import sswjax
from sswjax.graph import ssw_disparity, ssw_outputs
from sswjax.runtime import folder_bound
from sswjax.runtime.graph_keys import graph_key, host_digest, source_digest
from sswjax.runtime.stored import StoredGraph

_STATIC = ("ndisp", "chunk", "measure")
# The paper's method without segments and smoothing: the quickest graph to compile here.
_PARAMS = sswjax.preset("paper").replace(segments=None, smoothing=None)


@pytest.fixture(autouse=True)
def _xla_compiles_here(monkeypatch):
    """XLA's persistent cache off in this process (whether an earlier test of the worker turned
    it on or not): an executable read from it is not stored, and these tests store. The command
    line tests below run with the cache, in their own processes. Executables are stored
    (``SSWJAX_STORE_EXECUTABLES=1``, the default) here and in those processes, but where a test
    says otherwise."""
    monkeypatch.setenv("SSWJAX_STORE_EXECUTABLES", "1")
    enabled = jax.config.jax_enable_compilation_cache
    jax.config.update("jax_enable_compilation_cache", False)
    compilation_cache.reset_cache()  # JAX reads the option when it next compiles
    yield
    jax.config.update("jax_enable_compilation_cache", enabled)
    compilation_cache.reset_cache()


@pytest.fixture(scope="module")
def pair():
    rng = np.random.default_rng(3)
    right = rng.random((20, 36, 3), dtype=np.float32)
    return jnp.asarray(np.roll(right, 3, axis=1)), jnp.asarray(right)


def _stored(fn, folder, left, right, params, **static):
    return StoredGraph(fn, (left, right, params), static, static=_STATIC, folder=folder)


def test_a_stored_graph_gives_the_jitted_results_bit_for_bit(tmp_path, pair):
    fn = ssw_outputs  # a namedtuple of results (ssw_disparity's array: the tests below)
    first = _stored(fn.__wrapped__, tmp_path, *pair, _PARAMS, ndisp=8)
    assert not first.loaded and len(list(tmp_path.glob("*.jaxexport"))) == 1
    assert not list(tmp_path.glob("*.xlaexec"))  # compiled at the first call, not before
    first(*pair, _PARAMS, ndisp=8)
    (executable,) = tmp_path.glob("*.xlaexec")
    assert host_digest()[:16] in executable.name
    again = _stored(fn.__wrapped__, tmp_path, *pair, _PARAMS, ndisp=8)
    assert again.loaded and again.executable_loaded
    expected = fn(*pair, _PARAMS, ndisp=8)
    got = again(*pair, _PARAMS, ndisp=8)
    assert type(got) is type(expected)
    for a, b in zip(got, expected):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_executables_are_stored_unless_turned_off(tmp_path, pair, monkeypatch):
    monkeypatch.setenv("SSWJAX_STORE_EXECUTABLES", "0")
    fn = ssw_disparity.__wrapped__
    expected = np.asarray(ssw_disparity(*pair, _PARAMS, ndisp=8))
    np.testing.assert_array_equal(
        np.asarray(_stored(fn, tmp_path, *pair, _PARAMS, ndisp=8)(*pair, _PARAMS, ndisp=8)),
        expected)
    assert len(list(tmp_path.glob("*.jaxexport"))) == 1
    assert not list(tmp_path.glob("*.xlaexec"))
    monkeypatch.delenv("SSWJAX_STORE_EXECUTABLES")  # the default: stored
    _stored(fn, tmp_path, *pair, _PARAMS, ndisp=8)(*pair, _PARAMS, ndisp=8)
    (executable,) = tmp_path.glob("*.xlaexec")
    monkeypatch.setenv("SSWJAX_STORE_EXECUTABLES", "0")
    again = _stored(fn, tmp_path, *pair, _PARAMS, ndisp=8)
    assert again.loaded and not again.executable_loaded  # the file is there, and not read
    np.testing.assert_array_equal(np.asarray(again(*pair, _PARAMS, ndisp=8)), expected)


def test_another_signature_is_another_graph(tmp_path, pair):
    params = _PARAMS
    fn = ssw_disparity.__wrapped__
    _stored(fn, tmp_path, *pair, params, ndisp=8)
    assert not _stored(fn, tmp_path, *pair, params, ndisp=9).loaded  # a static argument
    changed = params.replace(aggregation=params.aggregation.replace(iterations=1))  # static
    assert not _stored(fn, tmp_path, *pair, changed, ndisp=8).loaded
    traced = params.replace(cost=params.cost.replace(tad_weight=0.1))  # a traced option
    graph = _stored(fn, tmp_path, *pair, traced, ndisp=8)
    assert graph.loaded  # the same graph, called with another value
    np.testing.assert_array_equal(np.asarray(graph(*pair, traced, ndisp=8)),
                                  np.asarray(ssw_disparity(*pair, traced, ndisp=8)))
    smaller = tuple(image[:, :-1] for image in pair)
    assert not _stored(fn, tmp_path, *smaller, params, ndisp=8).loaded  # a shape
    assert len(list(tmp_path.glob("*.jaxexport"))) == 4


def test_the_folder_keeps_the_most_recently_used_graphs_within_its_bound(tmp_path, pair,
                                                                         monkeypatch):
    fn = ssw_disparity.__wrapped__
    _stored(fn, tmp_path, *pair, _PARAMS, ndisp=8)(*pair, _PARAMS, ndisp=8)
    (trace,), (executable,) = tmp_path.glob("*.jaxexport"), tmp_path.glob("*.xlaexec")
    size = trace.stat().st_size + executable.stat().st_size
    for path in (trace, executable):
        os.utime(path, (1, 1))                             # used long ago
    assert _stored(fn, tmp_path, *pair, _PARAMS, ndisp=8).executable_loaded
    assert executable.stat().st_mtime > 1 and trace.stat().st_mtime == 1  # read: used now
    bound = 2 * size - trace.stat().st_size // 2           # room for two graphs but a trace
    monkeypatch.setattr(folder_bound, "GRAPHS_BYTES", bound)
    _stored(fn, tmp_path, *pair, _PARAMS, ndisp=9)(*pair, _PARAMS, ndisp=9)
    kept = list(tmp_path.iterdir())
    assert sum(path.stat().st_size for path in kept) <= bound
    assert not trace.exists() and executable.exists()     # the least recently used went
    assert len(kept) == 3


def test_the_key_holds_the_source_and_the_static_values(pair):
    leaves, treedef = jax.tree_util.tree_flatten(((*pair, _PARAMS), {}))
    specs = [jax.ShapeDtypeStruct(np.shape(x), jnp.result_type(x)) for x in leaves]
    key = graph_key(ssw_disparity, treedef, specs, {"ndisp": 8})
    assert key.startswith("ssw_disparity-") and key.endswith(".jaxexport")
    assert key != graph_key(ssw_disparity, treedef, specs, {"ndisp": 9})
    assert len(source_digest()) == 64


def test_a_damaged_stored_graph_is_traced_and_stored_anew(tmp_path, pair):
    params = _PARAMS
    fn = ssw_disparity.__wrapped__
    _stored(fn, tmp_path, *pair, params, ndisp=8)
    (path,) = tmp_path.glob("*.jaxexport")
    path.write_bytes(path.read_bytes()[:100])
    graph = _stored(fn, tmp_path, *pair, params, ndisp=8)
    assert not graph.loaded and path.stat().st_size > 100
    np.testing.assert_array_equal(np.asarray(graph(*pair, params, ndisp=8)),
                                  np.asarray(ssw_disparity(*pair, params, ndisp=8)))
    assert _stored(fn, tmp_path, *pair, params, ndisp=8).loaded


def test_a_stored_executable_survives_damage_and_transformations(tmp_path, pair):
    params = _PARAMS
    fn = ssw_disparity.__wrapped__
    expected = np.asarray(ssw_disparity(*pair, params, ndisp=8))
    _stored(fn, tmp_path, *pair, params, ndisp=8)(*pair, params, ndisp=8)
    (path,) = tmp_path.glob("*.xlaexec")
    whole = path.read_bytes()
    middle = len(whole) // 2
    for damaged in (whole[:100], whole[:middle] + bytes(64) + whole[middle + 64:]):
        path.write_bytes(damaged)  # cut short; zeros inside the machine code
        graph = _stored(fn, tmp_path, *pair, params, ndisp=8)
        assert graph.loaded and not graph.executable_loaded  # the trace is still good
        np.testing.assert_array_equal(np.asarray(graph(*pair, params, ndisp=8)), expected)
        assert path.read_bytes() not in (damaged, b"")  # compiled again and stored anew
    graph = _stored(fn, tmp_path, *pair, params, ndisp=8)
    assert graph.executable_loaded
    doubled = jax.jit(lambda left, right: 2 * graph(left, right, params, ndisp=8))(*pair)
    # under a transformation the call goes through the trace, inlined in a larger program that
    # XLA may fuse otherwise: equal up to float32 rounding
    np.testing.assert_allclose(np.asarray(doubled), 2 * expected, rtol=1e-6)
    graph.clear_cache()  # dropped, then read again from its file
    np.testing.assert_array_equal(np.asarray(graph(*pair, params, ndisp=8)), expected)


def test_importing_the_package_leaves_jax_unstarted():
    """No JAX array at import: a user may still configure JAX (platform, devices) after
    ``import sswjax``, and a stored executable's host key sees the configured devices."""
    code = ("import sswjax, jax\n"  # JAX refuses this option once a backend is up
            "jax.config.update('jax_num_cpu_devices', 2)\nprint(jax.device_count())")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, env=dict(os.environ, JAX_PLATFORMS="cpu"))
    assert done.returncode == 0 and done.stdout.strip() == "2", done.stderr


def _cli(*args, cache):
    env = dict(os.environ, SSWJAX_CACHE_DIR=str(cache))
    return subprocess.run([sys.executable, "-m", "sswjax.cli", *map(str, args)], env=env,
                          capture_output=True, text=True, timeout=600)


def _files(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())


_QUICK = ["--preset", "paper", "--set", "segments=none", "--set", "smoothing=none"]


def test_a_warmed_shape_is_matched_without_tracing_or_compiling(small_pair, tmp_path):
    cache, files = tmp_path / "cache", small_pair.folder
    warmed = _cli("warmup", "--size", "40x24", "--gray", "--ndisp", 8, *_QUICK, cache=cache)
    assert warmed.returncode == 0, warmed.stderr
    assert "compiled 1 shape" in warmed.stdout
    before = _files(cache)
    assert any(name.startswith("graphs/") for name in before)
    pair = (files / "left_gray.png", files / "right_gray.png")
    matched = _cli("match", *pair, "--ndisp", 8, *_QUICK, "-o", tmp_path / "d.pfm", cache=cache)
    assert matched.returncode == 0, matched.stderr
    assert _files(cache) == before  # nothing traced, nothing compiled: all found
    plain = _cli("--no-cache", "match", *pair, "--ndisp", 8, *_QUICK, "-o",
                 tmp_path / "plain.pfm", cache=tmp_path / "unused")
    assert plain.returncode == 0, plain.stderr
    assert (tmp_path / "d.pfm").read_bytes() == (tmp_path / "plain.pfm").read_bytes()


_LAPACK_OR_NOT = """
import sys
from pathlib import Path
import jax, jax.numpy as jnp, numpy as np
from sswjax.runtime.stored import StoredGraph
functions = {"inverse": jnp.linalg.inv, "plain": lambda a: a @ a + 1}
a = jax.device_put(np.eye(3, dtype=np.float32) * 2)
graph = StoredGraph(functions[sys.argv[2]], (a,), {}, static=(), folder=Path(sys.argv[1]))
out = np.asarray(graph(a))
print(graph.executable_loaded, graph.loaded, out.sum(), "scipy.linalg" in sys.modules)
"""


@pytest.mark.parametrize("store", ["1", "0"])
def test_a_stored_graph_runs_in_a_new_process_with_or_without_lapack(tmp_path, store):
    """A stored executable that calls LAPACK (``jnp.linalg.inv``; the ``plane`` fill solves
    with it) once died on its first run in a new process with a segmentation fault: nothing
    there had registered LAPACK's kernels. A stored trace that calls none is lowered without
    them, and without importing SciPy (0.14 s)."""
    env = dict(os.environ, SSWJAX_STORE_EXECUTABLES=store)
    for name, total in (("inverse", 1.5), ("plain", 21.0)):
        runs = [subprocess.run([sys.executable, "-c", _LAPACK_OR_NOT, str(tmp_path), name],
                               env=env, capture_output=True, text=True, timeout=300)
                for _ in range(2)]
        assert [run.returncode for run in runs] == [0, 0], runs[-1].stderr
        (first, again) = [run.stdout.split() for run in runs]
        assert first[:2] == ["False", "False"] and float(first[2]) == total
        assert again[:2] == [str(store == "1"), "True"] and float(again[2]) == total
        if name == "plain" and store == "1":
            assert again[3] == "False"  # the executable loaded: SciPy not imported


_STORING_EVERYTHING = """
import sys
import sswjax.runtime.stored as stored
from sswjax.cli.app import main
# what a process that did not tell XLA's cache from a fresh compile would store
stored.compile_lowered = lambda lowered: (lowered.compile(), True)
sys.exit(main(sys.argv[1:]))
"""


def test_only_fresh_executables_are_stored_and_a_broken_one_is_replaced(small_pair, tmp_path):
    cache, files = tmp_path / "cache", small_pair.folder
    pair = (files / "left_gray.png", files / "right_gray.png")
    command = ["match", *pair, "--ndisp", 8, *_QUICK, "-o"]

    def matched(name, *, python=None):
        out = tmp_path / f"{name}.pfm"
        if python is None:
            done = _cli(*command, out, cache=cache)
        else:
            env = dict(os.environ, SSWJAX_CACHE_DIR=str(cache))
            done = subprocess.run([sys.executable, "-c", python, *map(str, command), str(out)],
                                  env=env, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr
        return out.read_bytes()

    first = matched("first")  # compiled here: stored
    (executable,) = cache.glob("graphs/*.xlaexec")
    executable.unlink()
    assert matched("second") == first  # from XLA's cache: not stored
    assert not list(cache.glob("graphs/*.xlaexec"))
    assert matched("third", python=_STORING_EVERYTHING) == first
    assert list(cache.glob("graphs/*.xlaexec")) == [executable]  # what the cache hit gave
    assert matched("fourth") == first  # it fails to run: removed, the trace runs instead
    assert not executable.exists()


@pytest.mark.parametrize("args, message", [
    (["--ndisp", "8"], "name the sizes to compile for"),
    (["--size", "40x24", "--ndisp", "0"], "--ndisp must be >= 1"),
    (["--size", "40x0", "--ndisp", "8"], "a size is WIDTHxHEIGHT"),
    (["--size", "40x24", "--ndisp", "8", "--workers", "2"], "warmup compiles in this process"),
])
def test_warmup_refuses_bad_requests(tmp_path, args, message):
    done = _cli("warmup", *args, cache=tmp_path / "cache")
    assert done.returncode == 2 and message in done.stderr, done.stderr
    assert done.stderr.count("\n") == 1 or "usage:" in done.stderr


def test_warmup_needs_the_cache_and_images_to_be_like(tmp_path):
    done = _cli("--no-cache", "warmup", "--size", "40x24", "--ndisp", "8", cache=tmp_path / "c")
    assert done.returncode == 2 and "--no-cache" in done.stderr, done.stderr
    (tmp_path / "empty").mkdir()
    done = _cli("warmup", "--like", tmp_path / "empty", "--ndisp", "8", cache=tmp_path / "c")
    assert done.returncode == 2 and "no images in this folder" in done.stderr, done.stderr
