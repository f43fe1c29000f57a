"""The small version of ``benchmarks/raw_camera.py``: a window of MiddEval3's Motorcycle made
raw (distortion on both views, a rotation of the right camera), matched through
``sswjax match --rectify ... --depth-range`` and directly, with conftest's ``tiny``
configuration; the raw run's cloud must be within 3 points (of the share of points within 2 %
of the true depth) of the direct run's, with at least 80 % as many points. Skipped without
the shared data."""

import importlib.util
from pathlib import Path

import pytest

from sswjax.data.layouts.middeval3 import find_data_root

pytest.importorskip("cv2")
pytest.importorskip("plyfile")

BENCHMARKS = Path(__file__).parents[1] / "benchmarks"
ROOT = find_data_root()                      # SSWJAX_DATA, else ../shared/data/MiddEval3
SCENE = next((p for p in (ROOT / "trainingQ" / "Motorcycle", ROOT / "Motorcycle")
              if p.is_dir()), ROOT / "trainingQ" / "Motorcycle")


@pytest.fixture()
def raw_camera(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    spec = importlib.util.spec_from_file_location("raw_camera", BENCHMARKS / "raw_camera.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow  # a 480 x 320 window of a real pair, matched twice (raw and direct)
def test_raw_motorcycle_window(raw_camera, tmp_path, run_cli, tiny):
    if not SCENE.is_dir():
        pytest.skip(f"MiddEval3 Motorcycle not in {ROOT}")

    def cli(argv):
        code, _, stderr = run_cli(argv)
        assert code == 0, stderr
        return 0.0

    rows, _, _ = raw_camera.run(SCENE, tmp_path, options=tiny.args,
                                            crop=(120, 80, 480, 320), cli=cli, sgbm=False)
    passes, lost, share = raw_camera.verdict(rows)
    assert passes, (lost, share, rows)
    raw, direct = rows
    assert raw["median"] < 0.01 and direct["median"] < 0.01
    assert max(raw["invented"]) < 2          # the raw views stay (almost) inside the pair
