"""Dask as the engine, on a real cluster of this machine: a session's LocalCluster of two spawned
single-threaded worker processes. Folders through the cluster equal the single process bit for
bit; a worker killed mid-run loses nothing; a bad pair is named while the others are written;
one pair's strips or tiles are tasks (an aligned pair's too: its right image is moved here
first, then the method's windows are the tasks); without Dask the options say what to
install; ``--workers`` beyond the cores is capped at them, and a cluster closes quietly.

Every pair here is 40 x 64 with ndisp 8 and the cheap method, and the tiled pair's windows are
40 x 64 too: the workers and this process compile one graph between them.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import subprocess
import sys
import threading
import time

import imageio.v3 as iio
import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

import sswjax
from sswjax.cli.distributed import cluster_session
from sswjax.cluster import DaskEngine, PairJob, match_folder, match_pairs, match_tiles
from sswjax.cluster.cores import usable_cores
from sswjax.cluster.workers import PINNED_FLAGS, connect, pin_workers, worker_environment
from sswjax.data.io import read_image, read_pfm
from sswjax.runtime.memory import MemoryEstimateError, worker_peak_bytes

HEIGHT, WIDTH, NDISP, SHIFT = 40, 64, 8, 3
CHEAP = sswjax.Params().replace(segments=None, aggregation={"kind": "box", "radius": 1})
CHEAP_ARGS = ["--preset", "paper", "--set", "segments=none", "--set", "aggregation=box",
              "--set", "aggregation.radius=1"]


@pytest.fixture(scope="session")
def cache(tmp_path_factory):
    """The compilation cache the workers share."""
    return str(tmp_path_factory.mktemp("xla-cache"))


@pytest.fixture(scope="session")
def cluster():
    """Two worker processes, one thread each, XLA pinned to it (closed at the end)."""
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                  dashboard_address=":0", env=worker_environment()) as cluster:
        yield cluster


@pytest.fixture()
def client(cluster):
    with distributed.Client(cluster) as client:
        client.wait_for_workers(2, timeout=120)
        yield client


def _folders(root, texture, count, *, seed=0):
    left, right = root / "L", root / "R"
    left.mkdir(), right.mkdir()
    for i in range(count):
        image = texture(seed + i, (HEIGHT, WIDTH, 3))
        iio.imwrite(left / f"p{i:02d}.png", np.roll(image, SHIFT, axis=1))
        iio.imwrite(right / f"p{i:02d}.png", image)
    return left, right


def _here(left, right, names):
    """The maps of this process, as the reference."""
    return {name: sswjax.match(read_image(left / name), read_image(right / name), NDISP,
                               params=CHEAP) for name in names}


def test_a_folder_through_the_cluster_equals_this_process_bit_for_bit(client, tmp_path, texture,
                                                                      run_cli, cache, monkeypatch):
    left, right = _folders(tmp_path, texture, 4)
    monkeypatch.setenv("SSWJAX_CACHE_DIR", cache)
    out = tmp_path / "out"
    code, stdout, stderr = run_cli(["match", left, right, "--ndisp", NDISP, "-o", out,
                                    "--scheduler", client.scheduler.address, *CHEAP_ARGS])
    assert code == 0, stderr
    assert "wrote 4 disparity maps" in stdout and "on 2 workers" in stdout
    assert "2 Dask workers at" in stderr and "dashboard http" in stderr and "pairs" in stderr
    for name, expected in _here(left, right, sorted(os.listdir(left))).items():
        assert read_pfm(out / name.replace(".png", ".pfm")).tobytes() == expected.tobytes()
    flags = client.run(lambda: os.environ["XLA_FLAGS"])
    assert all(all(f in value.split() for f in PINNED_FLAGS) for value in flags.values())
    # --resume keeps them all: nothing is matched twice
    before = {p.name: p.stat().st_mtime_ns for p in out.glob("*.pfm")}
    code, stdout, _ = run_cli(["match", left, right, "--ndisp", NDISP, "-o", out, "--resume",
                               "--scheduler", client.scheduler.address, *CHEAP_ARGS])
    assert code == 0 and "wrote 0 disparity maps" in stdout and "4 kept from before" in stdout
    assert {p.name: p.stat().st_mtime_ns for p in out.glob("*.pfm")} == before


def test_a_worker_killed_mid_run_loses_nothing(client, tmp_path, texture, cache):
    left, right = _folders(tmp_path, texture, 40, seed=10)
    out = tmp_path / "out"
    pids = client.run(os.getpid)
    summary = {}
    run = threading.Thread(target=lambda: summary.update(result=match_folder(
        client, left, right, out, NDISP, params=CHEAP, cache=cache)))
    run.start()
    deadline = time.monotonic() + 120
    while not list(out.glob("*.pfm")) and time.monotonic() < deadline:
        time.sleep(0.01)
    busy = {}
    while not any(busy.values()) and time.monotonic() < deadline:  # a worker holding a task
        busy = client.processing()
        time.sleep(0.005)
    victim = max(busy, key=lambda address: len(busy[address]))
    assert busy[victim], "no worker was holding a task to kill"
    os.kill(pids[victim], signal.SIGKILL)                       # mid-run, whatever it holds
    killed_at = len(list(out.glob("*.pfm")))
    run.join(timeout=300)
    assert not run.is_alive()
    result = summary["result"]
    assert killed_at < 40 and not result.failed and len(result.written) == 40
    for name, expected in _here(left, right, sorted(os.listdir(left))).items():
        assert read_pfm(out / name.replace(".png", ".pfm")).tobytes() == expected.tobytes()
    assert victim not in client.nthreads()                       # it died; its tasks ran elsewhere
    client.wait_for_workers(2, timeout=120)                      # and its nanny started another


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity") or len(os.sched_getaffinity(0)) < 2,
                    reason="CPU affinity (Linux) and two cores")
def test_each_worker_is_pinned_to_a_core_of_its_own_and_stays_so_when_restarted(client):
    # XLA's pool of threads follows the process's cores: unpinned, each worker spread its
    # graphs over every core of the machine (docs/cluster.md).
    def threads_cores():        # in a worker (nested: sent by value): each thread's cores
        return sorted({tuple(sorted(os.sched_getaffinity(int(thread))))
                       for thread in os.listdir("/proc/self/task")})

    def pins():
        return client.run(threads_cores)

    pin_workers(client)
    before = pins()
    assert all(len(cores) == 1 and len(cores[0]) == 1 for cores in before.values()), before
    assert len({cores[0] for cores in before.values()}) == 2        # two workers, two cores
    names = {info["name"]: address for address, info
             in client.scheduler_info(n_workers=-1)["workers"].items()}
    victim = names[min(names)]
    core = before[victim]
    os.kill(client.run(os.getpid)[victim], signal.SIGKILL)
    deadline = time.monotonic() + 120
    while (victim in client.nthreads() or len(client.nthreads()) < 2) and \
            time.monotonic() < deadline:
        time.sleep(0.05)
    after = pins()                                     # its nanny started another: pinned too
    assert victim not in after and sorted(after.values()) == sorted(before.values())
    assert core in after.values()


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity") or len(os.sched_getaffinity(0)) < 2,
                    reason="CPU affinity (Linux) and two cores")
def test_a_worker_that_joins_later_is_pinned_to_a_free_core():
    def threads_cores():        # in a worker (nested: sent by value): each thread's cores
        return sorted({tuple(sorted(os.sched_getaffinity(int(thread))))
                       for thread in os.listdir("/proc/self/task")})

    with distributed.LocalCluster(n_workers=1, processes=True, threads_per_worker=1,
                                  dashboard_address=None, env=worker_environment()) as cluster, \
            distributed.Client(cluster) as client:
        client.wait_for_workers(1, timeout=120)
        pin_workers(client)
        cluster.scale(2)                               # a worker started after the pins
        client.wait_for_workers(2, timeout=120)
        deadline = time.monotonic() + 60
        while True:                                    # its setup callback runs as it starts
            pins = client.run(threads_cores)
            if all(len(cores) == 1 and len(cores[0]) == 1 for cores in pins.values()) or \
                    time.monotonic() > deadline:
                break
            time.sleep(0.1)
    assert all(len(cores) == 1 and len(cores[0]) == 1 for cores in pins.values()), pins
    assert len({cores[0] for cores in pins.values()}) == 2, pins


def test_a_bad_pair_is_named_and_the_others_are_written(client, tmp_path, texture, run_cli,
                                                        cache, monkeypatch):
    left, right = _folders(tmp_path, texture, 3, seed=50)
    png = (left / "p01.png").read_bytes()
    (left / "p01.png").write_bytes(png[: len(png) // 2])        # its header is whole: it passes
    monkeypatch.setenv("SSWJAX_CACHE_DIR", cache)                # the checks before the run
    out = tmp_path / "out"
    code, stdout, stderr = run_cli(["match", left, right, "--ndisp", NDISP, "-o", out,
                                    "--scheduler", client.scheduler.address, *CHEAP_ARGS])
    assert code == 2 and "wrote 2 disparity maps" in stdout and "1 failed" in stdout
    lines = [line for line in stderr.replace("\r", "\n").splitlines()
             if line.startswith("sswjax: error: ")]
    assert len(lines) == 2, stderr                               # the pair, then the summary
    assert lines[0].startswith("sswjax: error: pair p01.png: ")
    assert str(left / "p01.png") in lines[0]
    assert lines[1].startswith("sswjax: error: 2 of 3 maps written; 1 pair failed: p01.png")
    assert sorted(p.name for p in out.glob("*.pfm")) == ["p00.pfm", "p02.pfm"]
    # through the API: an outcome with the name, never an exception
    jobs = [PairJob("p01.png", str(left / "p01.png"), str(right / "p01.png"),
                    str(tmp_path / "x.pfm"))]
    (outcome,) = match_pairs(client, jobs, NDISP, params=CHEAP, cache=cache)
    assert not outcome.ok and outcome.name == "p01.png" and "\n" not in outcome.message
    # a pair whose image cannot be read at all is named before any task, the others matched
    (left / "p02.png").write_text("not an image\n")
    summary = match_folder(client, left, right, tmp_path / "api", NDISP, params=CHEAP,
                           cache=cache)
    assert summary.written == ["p00.png"] and sorted(summary.failed) == ["p01.png", "p02.png"]
    assert summary.failed["p02.png"].startswith(f"pair p02.png: cannot read image {left}")
    with pytest.raises(ValueError, match=r"^pair p02.png: cannot read image .*$"):
        match_folder(client, left, right, tmp_path / "strict", NDISP, params=CHEAP, strict=True)
    assert not (tmp_path / "strict").exists()


def test_one_pairs_strips_are_tasks(client, tmp_path, texture, run_cli, cache, monkeypatch):
    right = texture(7, (120, WIDTH, 3))
    left = np.roll(right, SHIFT, axis=1)
    plan = sswjax.ExecutionPlan(strip_rows=24, strip_overlap=8)  # windows of 40 x 64
    here = sswjax.match(left, right, NDISP, params=CHEAP, plan=plan)
    there = match_tiles(client, left, right, NDISP, params=CHEAP, plan=plan, cache=cache)
    assert there.tobytes() == here.tobytes()
    iio.imwrite(tmp_path / "l.png", left)
    iio.imwrite(tmp_path / "r.png", right)
    monkeypatch.setenv("SSWJAX_CACHE_DIR", cache)
    code, _, stderr = run_cli(["match", tmp_path / "l.png", tmp_path / "r.png", "--ndisp", NDISP,
                               "-o", tmp_path / "d.pfm", "--strip-rows", 24, "--strip-overlap", 8,
                               "--scheduler", client.scheduler.address, *CHEAP_ARGS])
    assert code == 0, stderr
    assert "tiles" in stderr and "dashboard" in stderr
    assert read_pfm(tmp_path / "d.pfm").tobytes() == \
        sswjax.match(read_image(tmp_path / "l.png"), read_image(tmp_path / "r.png"), NDISP,
                     params=CHEAP, plan=plan).tobytes()


def test_carried_strips_are_one_task_with_the_maps_of_this_process(client, texture, cache):
    # Semi-global paths run on from strip to strip: the chain of strips waits for itself, so it
    # runs as one task, and its maps are those of the strips matched here (the cheap method
    # with accurate's 4 paths: the paths are what is carried).
    # Above the texture of the bottom rows, vertical stripes of period 4 match alike at
    # disparities 3 and 7 (the pair's): there the carried paths decide, and strips that
    # restarted them would give another map (measured: 40 % of the pixels).
    right = texture(9, (96, WIDTH, 3))
    right[:64] = np.array([50, 200, 100, 150], np.uint8)[np.arange(WIDTH) % 4][None, :, None]
    left = np.roll(right, 7, axis=1)
    plan = sswjax.ExecutionPlan(strip_rows=16, strip_overlap=16)
    params = CHEAP.replace(optimizer=sswjax.preset("accurate").optimizer)
    here = sswjax.match(left, right, NDISP, params=params, plan=plan)
    restarted = sswjax.match(left, right, NDISP, params=params,
                             plan=plan._replace(carry_paths=False))
    assert np.mean(restarted != here) > 0.2
    there = match_tiles(client, left, right, NDISP, params=params, plan=plan, cache=cache)
    assert there.tobytes() == here.tobytes()


def _aligned_pair(texture):
    """A 96 x 64 pair whose offset the cheap method can measure, and strips of 40 x 64."""
    right = texture(11, (96, WIDTH, 3))
    params = CHEAP.replace(alignment={"kind": "vertical", "min_pixels": 64})
    assert params.alignment.measurable(right.shape[:2])
    return np.roll(right, SHIFT, axis=1), right, params, sswjax.ExecutionPlan(strip_rows=24,
                                                                              strip_overlap=8)


def test_an_aligned_pairs_windows_are_tasks_with_the_maps_of_this_process(client, texture,
                                                                          cache):
    # The right image is moved here (the alignment, one call on the whole pair), then the
    # method's windows are tasks: the maps of this process.
    left, right, params, plan = _aligned_pair(texture)
    here = sswjax.match(left, right, NDISP, params=params, plan=plan)
    there = match_tiles(client, left, right, NDISP, params=params, plan=plan, cache=cache)
    assert there.tobytes() == here.tobytes()


def test_an_aligned_pair_starts_its_engines_cluster_once(cluster, texture, cache):
    # The command line's engine connects per call (it starts a cluster for its pair): the
    # alignment runs here, the windows on one cluster, with the maps of this process.
    opened = []

    @contextlib.contextmanager
    def connect():
        with distributed.Client(cluster) as client:
            opened.append(client)
            yield client

    left, right, params, plan = _aligned_pair(texture)
    here = sswjax.match(left, right, NDISP, params=params, plan=plan)
    engine = DaskEngine(connect=connect, cache=cache)
    there = sswjax.match(left, right, NDISP, params=params, plan=plan._replace(engine=engine))
    assert len(opened) == 1
    assert there.tobytes() == here.tobytes()


def test_windows_too_large_for_a_worker_are_refused_before_any_task(client, texture, cache):
    left, right, params, plan = _aligned_pair(texture)
    limit = worker_peak_bytes(*left.shape[:2], NDISP, params=params, plan=plan) - 1
    engine = DaskEngine(client, cache=cache, memory_limit=limit)
    with distributed.get_task_stream(client) as stream:
        with pytest.raises(MemoryEstimateError, match="more than the limit"):
            sswjax.match(left, right, NDISP, params=params, plan=plan._replace(engine=engine))
    assert stream.data == []


NO_DASK = r"""
import sys
sys.modules["distributed"] = None      # as if the extra were not installed
from sswjax.cli import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.parametrize("where", [["--workers", "2"], ["--scheduler", "tcp://127.0.0.1:1"]])
def test_without_dask_the_options_say_what_to_install(tmp_path, texture, where):
    left, right = _folders(tmp_path, texture, 1)
    run = subprocess.run([sys.executable, "-c", NO_DASK, "match", str(left), str(right),
                          "--ndisp", "8", "-o", str(tmp_path / "out"), *where],
                         capture_output=True, text=True, timeout=300, check=False)
    assert run.returncode == 2 and run.stdout == ""
    assert run.stderr == (f"sswjax: error: {where[0]} runs on Dask, which is not installed: "
                          'pip install "sswjax[distributed]"\n')
    assert not (tmp_path / "out").exists()


def test_more_workers_than_cores_are_capped_at_the_cores(capsys):
    """``--workers N`` above the cores starts one worker per core, with one line saying so:
    each worker is pinned to a core, two on one core are no faster (and 64 on 2 cores were
    slow to start and printed hundreds of lines when they closed)."""
    cores = usable_cores()
    args = argparse.Namespace(workers=cores + 1, scheduler=None)
    with cluster_session(args) as client:
        assert len(client.nthreads()) == cores
    err = capsys.readouterr().err
    assert f"sswjax: note: --workers {cores + 1} is more than the {cores} cores here: using " \
           f"{cores}\n" in err
    with cluster_session(argparse.Namespace(workers=1, scheduler=None)):
        pass
    assert "more than the" not in capsys.readouterr().err


def test_a_cluster_closed_with_a_busy_worker_closes_quietly(capfd):
    # A worker still running a task when the block ends (Ctrl-C, an error) is killed by its
    # nanny after a few seconds: before, the nanny here and the worker there each said so on
    # stderr (with 64 workers on 2 cores, about 200 lines and tracebacks).
    def nap():                  # in a worker (nested: sent by value)
        time.sleep(60)

    with connect(workers=1) as client:
        task = client.submit(nap, pure=False)
        deadline = time.monotonic() + 120
        while not any(client.processing().values()) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert any(client.processing().values())
        del task
    assert capfd.readouterr().err == ""
