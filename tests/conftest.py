"""Fixtures shared by the test files.

pytest imports test files with ``--import-mode=importlib``, so a test file cannot import
another one nor this file: what several files share is a fixture here.

- ``texture``: reproducible random uint8 images.
- ``square_pair``: a 90x60 float pair, background at disparity 3, a square at 7.
- ``small_pair``: a 24x40 pair with disparity 3 written in every input form, and broken files.
- ``middeval3``: builds a MiddEval3-like data folder of three small scenes.
- ``write_eth3d``: writes an ETH3D two-view data folder of small scenes.
- ``tiny``: the one cheap configuration that tests of plumbing (files, folders, tiles, cluster,
  command line) share, as ``Params`` and as command-line options, so that they compile few graphs.
- ``run_cli``: the command line's ``main`` (``sswjax.cli``) in process, returning ``(exit code, stdout, stderr)``.
- ``run_on_devices``: a Python script in a fresh process with N simulated CPU devices.
- ``user_environment``: the environment of a process that compiles as a user's does.
- every test process keeps the persistent compilation cache in a new folder of its own.

Tests that are heavy by nature (a large pair, a preset at several shapes, fresh processes that
import JAX and compile) are marked ``slow``: ``pytest -m "not slow"`` is the quick loop, the
README's command runs them too. A test of plumbing (files, folders, options, errors) matches
with ``tiny`` on ``small_pair`` (24x40, ndisp 8) where it can, so that a worker compiles that
graph once for many files; a preset is compiled where its maps are what is tested.

The suite compiles with LLVM's optimisation off (:data:`TEST_XLA_FLAGS`), in this process and
in every process it starts: the tests run small images through many configurations of the
graph, so compiling is most of their time. XLA's graph is the same; only its machine code is
less optimised: on a quiet machine, ``tests/test_graph.py`` and ``tests/test_chunked.py`` took
263 instead of 437 s; one 185 x 144 pair with 64 disparities, ``accurate``, compiled and ran
first in 5.9 instead of 6.7 s, ran warm in 0.42 instead of 0.054 s, its mean disparity 1e-6 off.
Benchmarks and users compile with XLA's defaults, and so do the processes of the tests that
measure memory or run large pairs (``user_environment``); ``tests/test_suite_flags.py`` checks
that both flags give the same maps to rounding. The whole suite took 748 s on a fresh clone
(2026-12-06, 2 cores). XLA's older fusion emitters (``--xla_cpu_use_fusion_emitters=false``)
compile faster still (612 s) but are not what users run and compute differently: three tests
failed with them (a winner changed, an ill-conditioned guided filter moved by 4e-3), so they
are not used. Nor would one compilation cache shared by the two workers help: of the 543 graphs
the workers compile in more than 0.1 s, 38 repeat one compiled before in the run (31 s of 934 s
of compiling; 2026-12-07), and with such a cache (every program of 0.3 s of compile or more)
the suite took 830 s, against 838 and 849 s in two runs without it.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import NamedTuple

import imageio.v3 as iio
import numpy as np
import pytest

from sswjax.data.io import write_pfm

TEST_XLA_FLAGS = "--xla_backend_optimization_level=0"
"""Added to ``XLA_FLAGS`` before JAX starts its backend (the module docstring says why)."""
if TEST_XLA_FLAGS not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {TEST_XLA_FLAGS}".strip()

TESTS = Path(__file__).parent
HEIGHT, WIDTH, SHIFT, NDISP = 24, 40, 3, 8


def _texture(seed: int, shape=(HEIGHT, WIDTH, 3)) -> np.ndarray:
    return (np.random.default_rng(seed).random(shape) * 255).astype(np.uint8)


@pytest.fixture(scope="session", autouse=True)
def _compilation_cache_of_this_worker(tmp_path_factory):
    """Each test process (each pytest-xdist worker) keeps the persistent compilation cache that
    the command line turns on in a new folder of its own, never the user's
    (``~/.cache/sswjax/xla``) nor one written by an earlier run or by another worker: what a
    test compiles and reads is what this run of this code made. Tests of the cache shared
    between processes set ``SSWJAX_CACHE_DIR`` in their own processes."""
    previous = os.environ.get("SSWJAX_CACHE_DIR")
    os.environ["SSWJAX_CACHE_DIR"] = str(tmp_path_factory.mktemp("xla-cache"))
    yield
    if previous is None:
        os.environ.pop("SSWJAX_CACHE_DIR", None)
    else:
        os.environ["SSWJAX_CACHE_DIR"] = previous


@pytest.fixture(scope="session")
def texture():
    """``texture(seed, shape=(24, 40, 3))``: a uniform random uint8 image, fixed by ``seed``."""
    return _texture


class SmallPair(NamedTuple):
    """Where the files of :func:`small_pair` are, and the pair's geometry."""

    folder: Path
    height: int
    width: int
    shift: int  # the disparity of every pixel (np.roll of the right view)
    ndisp: int  # the search range the tests use


@pytest.fixture(scope="session")
def small_pair(tmp_path_factory) -> SmallPair:
    """A 24x40 pair with disparity 3 as colour, gray, 16-bit gray and RGBA PNGs, plus
    ``small.png`` (40x5), ``narrow.png`` (30x20), ``animated.gif`` (two frames) and broken
    files: ``truncated.png``, ``corrupt.png``, ``random.png``, ``empty.png`` and a folder
    ``folder.png``. Read-only: tests write their outputs elsewhere."""
    folder = tmp_path_factory.mktemp("small-pair")
    right = _texture(0)
    left = np.roll(right, SHIFT, axis=1)
    iio.imwrite(folder / "left.png", left)
    iio.imwrite(folder / "right.png", right)
    gray = [np.round(im.astype(np.float64) @ [0.299, 0.587, 0.114]).astype(np.uint8) for im in (left, right)]
    iio.imwrite(folder / "left_gray.png", gray[0])
    iio.imwrite(folder / "right_gray.png", gray[1])
    iio.imwrite(folder / "left_gray16.png", gray[0].astype(np.uint16) * 257)
    iio.imwrite(folder / "right_gray16.png", gray[1].astype(np.uint16) * 257)
    alpha = _texture(1, (HEIGHT, WIDTH, 1))
    iio.imwrite(folder / "left_rgba.png", np.concatenate([left, alpha], axis=-1))
    iio.imwrite(folder / "right_rgba.png", np.concatenate([right, alpha[::-1]], axis=-1))
    iio.imwrite(folder / "small.png", right[:5])
    iio.imwrite(folder / "narrow.png", right[:20, :30])
    iio.imwrite(folder / "animated.gif", np.stack([left, right]))
    png = (folder / "left.png").read_bytes()
    (folder / "truncated.png").write_bytes(png[: len(png) // 2])
    corrupt = bytearray(png)
    idat = png.index(b"IDAT") + 40
    corrupt[idat : idat + 8] = bytes(8)  # zeroes inside the compressed pixels
    (folder / "corrupt.png").write_bytes(bytes(corrupt))
    (folder / "random.png").write_bytes(np.random.default_rng(2).bytes(300))
    (folder / "empty.png").write_bytes(b"")
    (folder / "folder.png").mkdir()
    return SmallPair(folder, HEIGHT, WIDTH, SHIFT, NDISP)


@pytest.fixture(scope="session")
def square_pair():
    """A 90x60 float32 colour pair: background at disparity 3, a nearer square (rows 30-59,
    columns 20-44 of the left view) at disparity 7. Read-only."""
    rng = np.random.default_rng(11)
    right = rng.random((90, 60, 3), dtype=np.float32)
    left = np.roll(right, 3, axis=1)
    left[30:60, 20:45] = np.roll(right, 7, axis=1)[30:60, 20:45]
    return left, right


class FakeMiddEval3:
    """``middeval3(root)`` writes ``root/trainingQ/<scene>`` for the three :attr:`scenes`, each
    a ``height`` x width pair with disparity ``shift`` (ndisp ``ndisp``), its ground truth
    (``inf`` in the first ``shift`` columns) and nonocc mask, and returns ``root``."""

    scenes = (("Adirondack", 40), ("Teddy", 44), ("Vintage", 48))  # widths differ: one compile each
    height, shift, ndisp = HEIGHT, SHIFT, NDISP

    def __call__(self, root: Path) -> Path:
        for seed, (name, width) in enumerate(self.scenes):
            self.scene(root / "trainingQ" / name, width, seed)
        return root

    def scene(self, folder: Path, width: int, seed: int) -> None:
        folder.mkdir(parents=True)
        right = _texture(seed, (self.height, width, 3))
        iio.imwrite(folder / "im0.png", np.roll(right, self.shift, axis=1))
        iio.imwrite(folder / "im1.png", right)
        (folder / "calib.txt").write_text(f"cam0=[1 0 0; 0 1 0; 0 0 1]\nndisp={self.ndisp}\nvmin=0\nvmax=7\n")
        truth = np.full((self.height, width), self.shift, np.float32)
        truth[:, : self.shift] = np.inf
        write_pfm(folder / "disp0GT.pfm", truth)
        mask = np.full((self.height, width), 255, np.uint8)
        mask[:, : self.shift] = 0
        iio.imwrite(folder / "mask0nocc.png", mask)


@pytest.fixture(scope="session")
def middeval3() -> FakeMiddEval3:
    return FakeMiddEval3()


class Tiny(NamedTuple):
    """``params``: ``paper`` without superpixels, a 3 x 3 box aggregation; ``args``: the same as
    command-line options. Tests of what a preset computes use the preset, never this."""

    params: object
    args: tuple[str, ...]


@pytest.fixture(scope="session")
def tiny() -> Tiny:
    import sswjax

    params = sswjax.preset("paper").replace(segments=None, aggregation={"kind": "box", "radius": 1})
    args = ("--preset", "paper", "--set", "segments=none", "--set", "aggregation=box",
            "--set", "aggregation.radius=1")
    return Tiny(params, args)


@pytest.fixture()
def run_cli(capsys):
    """``run_cli(argv)``: ``(exit code, stdout, stderr)`` of ``sswjax.cli.main`` (arguments
    converted to strings); argparse's usage errors give their exit code like the console script.
    Run with ``--quiet``: whether a call compiles depends on what the process compiled before,
    so the compile lines are left out (``tests/test_compile_log.py`` tests them)."""
    from sswjax.cli import main

    def run(argv):
        try:
            code = main(["--quiet", *(str(a) for a in argv)])
        except SystemExit as exit_:
            code = exit_.code
        captured = capsys.readouterr()
        return code, captured.out, captured.err

    return run


def _run_on_devices(script: str, devices: int = 2, timeout: float = 600) -> str:
    """Run ``script`` with ``python -c`` and ``devices`` simulated CPU devices (``XLA_FLAGS``);
    ``tests/`` is importable there (``from test_batching import ...``). Returns the last line
    of its stdout; a failure shows the script's stderr."""
    env = dict(os.environ, XLA_FLAGS=f"--xla_force_host_platform_device_count={devices} "
                                     f"{TEST_XLA_FLAGS}")
    prelude = f"import sys\nsys.path.insert(0, {str(TESTS)!r})\n"
    run = subprocess.run([sys.executable, "-c", prelude + script], env=env, capture_output=True,
                         text=True, timeout=timeout)
    assert run.returncode == 0, run.stderr
    lines = run.stdout.strip().splitlines()
    return lines[-1] if lines else ""


@pytest.fixture(scope="session")
def run_on_devices():
    """``run_on_devices(script, devices=2)``: the last stdout line of ``script`` run in a fresh
    Python process on ``devices`` simulated CPU devices, with ``tests/`` on ``sys.path``."""
    return _run_on_devices


@pytest.fixture(scope="session")
def write_eth3d():
    """``write_eth3d(root, scenes=(...), shifts=(3, 5), ndisps=(32, None), gray=(True, False))``:
    ``root/ETH3D`` as ETH3D's two archives unpack (12x40 scenes of disparity ``shifts[i]``,
    ``inf`` left of it; the mask 255 there and 128 in the last two columns), returned.
    ``ndisps[i]`` None writes a ``calib.txt`` without ``ndisp``."""

    def write(root: Path, scenes=("delivery_area_1l", "electro_1l"), shifts=(3, 5), *,
              ndisps=(32, None), gray=(True, False)) -> Path:
        for i, (scene, shift) in enumerate(zip(scenes, shifts)):
            images = root / "ETH3D" / "two_view_training" / scene
            truth = root / "ETH3D" / "two_view_training_gt" / scene
            images.mkdir(parents=True)
            truth.mkdir(parents=True)
            right = _texture(i, (12, 40) if gray[i] else (12, 40, 3))
            iio.imwrite(images / "im0.png", np.roll(right, shift, axis=1))
            iio.imwrite(images / "im1.png", right)
            calib = "cam0=[500 0 20; 0 500 6; 0 0 1]\nbaseline=60\n"
            (images / "calib.txt").write_text(calib + (f"ndisp={ndisps[i]}\n" if ndisps[i] else ""))
            gt = np.full((12, 40), float(shift), np.float32)
            gt[:, :shift] = np.inf
            write_pfm(truth / "disp0GT.pfm", gt)
            mask = np.where(np.isfinite(gt), 255, 0).astype(np.uint8)
            mask[:, -2:] = 128
            iio.imwrite(truth / "mask0nocc.png", mask)
        return root / "ETH3D"

    return write


@pytest.fixture(scope="session")
def user_environment() -> dict[str, str]:
    """This process's environment with ``XLA_FLAGS`` as the user gave it, without
    :data:`TEST_XLA_FLAGS`: for processes that measure what a user's run costs."""
    flags = os.environ.get("XLA_FLAGS", "").replace(TEST_XLA_FLAGS, "").strip()
    env = {name: value for name, value in os.environ.items() if name != "XLA_FLAGS"}
    return dict(env, XLA_FLAGS=flags) if flags else env
