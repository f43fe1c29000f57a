from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from sswjax.data.calibration import read_calib
from sswjax.data.io import InputError, write_pfm
from sswjax.data.layouts import StereoScene, find_data_root
from sswjax.data.layouts.middeval3 import load_middeval3, load_scene, scene_dirs

CALIB = """cam0=[999.421 0 294.182; 0 999.421 252.932; 0 0 1]
cam1=[999.421 0 326.96; 0 999.421 252.932; 0 0 1]
doffs=32.778
baseline=193.001
width=741
height=497
ndisp={ndisp}
isint=0
vmin=7
vmax=65
dyavg=0.23
dymax=0.379
"""


def make_scene(root, name, *, ndisp=16, ground_truth=True, shape=(8, 12)):
    rng = np.random.default_rng(sum(name.encode()))
    scene = root / name
    scene.mkdir(parents=True)
    iio.imwrite(scene / "im0.png", rng.integers(0, 256, shape + (3,), dtype=np.uint8))
    iio.imwrite(scene / "im1.png", rng.integers(0, 256, shape + (3,), dtype=np.uint8))
    (scene / "calib.txt").write_text(CALIB.format(ndisp=ndisp))
    if ground_truth:
        gt = rng.uniform(0, ndisp, shape).astype(np.float32)
        gt[0, 0] = np.inf
        write_pfm(scene / "disp0GT.pfm", gt)
        mask = np.full(shape, 255, np.uint8)
        mask[:, :2] = 128
        mask[0, 0] = 0
        iio.imwrite(scene / "mask0nocc.png", mask)
    return scene


@pytest.fixture
def fake_root(tmp_path):
    root = tmp_path / "MiddEval3"
    make_scene(root / "trainingQ", "Zebra", ndisp=20)
    make_scene(root / "trainingQ", "Alpha", ndisp=16)
    (root / "trainingQ" / "notes").mkdir()  # not a scene: no im0.png
    return root


def test_read_calib_real_format(tmp_path):
    path = tmp_path / "calib.txt"
    path.write_text(CALIB.format(ndisp=70))
    calib = read_calib(path)
    assert calib["ndisp"] == 70 and isinstance(calib["ndisp"], int)
    assert calib["baseline"] == pytest.approx(193.001)
    assert calib["cam0"] == "[999.421 0 294.182; 0 999.421 252.932; 0 0 1]"
    assert calib["isint"] == 0.0 and len(calib) == 12


@pytest.mark.parametrize("ndisp_line", ["", "ndisp=0\n", "ndisp=-4\n", "ndisp=7.5\n", "ndisp=x\n"])
def test_read_calib_bad_ndisp(tmp_path, ndisp_line):
    path = tmp_path / "calib.txt"
    path.write_text("baseline=193.001\n" + ndisp_line)
    with pytest.raises(InputError, match="ndisp"):
        read_calib(path)


def test_read_calib_malformed_line(tmp_path):
    path = tmp_path / "calib.txt"
    path.write_text("ndisp=70\nthis is not a pair\n")
    with pytest.raises(InputError, match="line 2"):
        read_calib(path)


def test_load_fake_middeval3(fake_root):
    scenes = load_middeval3(fake_root)
    assert [s.name for s in scenes] == ["Alpha", "Zebra"]
    alpha = scenes[0]
    assert isinstance(alpha, StereoScene)
    assert alpha.ndisp == 16 and scenes[1].ndisp == 20
    assert alpha.left.shape == alpha.right.shape == (8, 12, 3) and alpha.left.dtype == np.uint8
    assert alpha.ground_truth.shape == (8, 12) and alpha.ground_truth.dtype == np.float32
    assert np.isinf(alpha.ground_truth[0, 0])
    assert alpha.mask.dtype == np.uint8 and alpha.mask[0, 0] == 0 and alpha.mask[0, 1] == 128
    assert alpha.path == fake_root / "trainingQ" / "Alpha"


def test_split_folder_and_scene_selection(fake_root):
    assert [p.name for p in scene_dirs(fake_root / "trainingQ")] == ["Alpha", "Zebra"]
    selected = load_middeval3(fake_root / "trainingQ", scenes=["Zebra"])
    assert [s.name for s in selected] == ["Zebra"]
    with pytest.raises(InputError, match="Nope"):
        load_middeval3(fake_root, scenes=["Alpha", "Nope"])


def test_scene_without_ground_truth(tmp_path):
    scene = load_scene(make_scene(tmp_path, "Test", ground_truth=False))
    assert scene.ground_truth is None and scene.mask is None and scene.ndisp == 16


def test_missing_required_file(fake_root):
    (fake_root / "trainingQ" / "Alpha" / "im1.png").unlink()
    with pytest.raises(InputError, match="scene Alpha: missing im1.png"):
        load_middeval3(fake_root)


def test_ground_truth_shape_mismatch(tmp_path):
    scene = make_scene(tmp_path, "Bad")
    write_pfm(scene / "disp0GT.pfm", np.zeros((3, 3), np.float32))
    with pytest.raises(InputError, match="scene Bad: disp0GT.pfm shape"):
        load_scene(scene)


def test_missing_data_directory(tmp_path):
    with pytest.raises(InputError, match="not found"):
        scene_dirs(tmp_path / "absent")
    with pytest.raises(InputError, match="no scene folders"):
        scene_dirs(tmp_path)


def test_find_data_root_priority(tmp_path, monkeypatch):
    monkeypatch.setenv("SSWJAX_DATA", str(tmp_path / "env"))
    assert find_data_root(data=tmp_path / "arg") == tmp_path / "arg"
    assert find_data_root() == tmp_path / "env"
    monkeypatch.delenv("SSWJAX_DATA")
    default = find_data_root()
    assert default.parts[-3:] == ("shared", "data", "MiddEval3")
    project = Path(__file__).resolve().parents[2]  # tests/data/test_datasets.py -> project
    assert default == project.parent / "shared" / "data" / "MiddEval3"


def test_real_middeval3_training():
    root = find_data_root()
    if not (root / "trainingQ").is_dir() and not root.is_dir():
        pytest.skip(f"MiddEval3 data not found at {root}")
    scenes = load_middeval3(root)
    assert len(scenes) == 15
    by_name = {s.name: s for s in scenes}
    assert by_name["Motorcycle"].ndisp == 70
    for s in scenes:
        assert s.left.shape == s.right.shape and s.left.ndim == 3
        assert s.ground_truth.shape == s.mask.shape == s.left.shape[:2]
        assert s.ground_truth.dtype == np.float32 and s.mask.dtype == np.uint8
