"""Data layouts other than MiddEval3 (KITTI, Middlebury 2001-2006) on tiny fixtures in each."""

from __future__ import annotations

from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from sswjax.data.io import InputError, write_pfm
from sswjax.data.layouts import (
    LAYOUTS,
    Layout,
    detect_layout,
    find_data_root,
    load_scenes,
    ndisp_from_ground_truth,
)
from sswjax.data.layouts.eth3d import Eth3dLayout
from sswjax.data.layouts.kitti import KittiLayout
from sswjax.data.layouts.middeval3 import MiddEval3Layout
from sswjax.data.layouts.middlebury import MiddleburyLayout
from sswjax.data.scaled import read_scaled_disparity

SHAPE = (12, 40)
SHARED = find_data_root().parent  # ../shared/data beside the project, as MiddEval3


def _pair(seed: int, shift: int, *, colour: bool, width: int = SHAPE[1]):
    """A random texture and its copy shifted right by ``shift``: left, right and GT (inf left)."""
    shape = (SHAPE[0], width) + ((3,) if colour else ())
    right = (np.random.default_rng(seed).random(shape) * 255).astype(np.uint8)
    gt = np.full((SHAPE[0], width), float(shift))
    gt[:, :shift] = np.inf
    return np.roll(right, shift, axis=1), right, gt


def _encode(gt: np.ndarray, scale: float, dtype) -> np.ndarray:
    return np.where(np.isfinite(gt), np.round(np.nan_to_num(gt, posinf=0) * scale), 0).astype(dtype)


def write_kitti(root: Path, name: str = "KITTI2012", shifts=(3, 5), *, occ: bool = False) -> Path:
    layout = LAYOUTS[name]
    base = root / name / "training"
    folders = (layout.left, layout.right, layout.ground_truth)
    for folder in folders + ((layout.ground_truth_all,) if occ else ()):
        (base / folder).mkdir(parents=True)
    for i, shift in enumerate(shifts):
        left, right, gt = _pair(i, shift, colour=name == "KITTI2015")
        frame = f"{i:06d}_10.png"
        iio.imwrite(base / layout.left / frame, left)
        iio.imwrite(base / layout.right / frame, right)
        noc = gt.copy()
        noc[:, -4:] = np.inf  # pretend the last columns are occluded: only disp_occ knows them
        iio.imwrite(base / layout.ground_truth / frame, _encode(noc if occ else gt, 256, np.uint16))
        if occ:
            iio.imwrite(base / layout.ground_truth_all / frame, _encode(gt, 256, np.uint16))
    return root / name


def write_middlebury(root: Path, name: str, scenes=("sawtooth", "venus"), shifts=(3, 5), *,
                     width: int = SHAPE[1]) -> Path:
    layout = LAYOUTS[name]
    for i, (scene, shift) in enumerate(zip(scenes, shifts)):
        folder = root / name / scene
        folder.mkdir(parents=True)
        left, right, gt = _pair(i, shift, colour=True, width=width)
        scale = layout.scale or (2.0 if width >= 550 else 3.0)
        iio.imwrite(folder / layout.left, left, extension=Path(layout.left).suffix)
        iio.imwrite(folder / layout.right, right, extension=Path(layout.right).suffix)
        iio.imwrite(folder / layout.ground_truth, _encode(gt, scale, np.uint8),
                    extension=Path(layout.ground_truth).suffix)
    return root / name


MIDDLEBURY_SCENES = {"Middlebury2001": ("sawtooth", "venus"), "Middlebury2003": ("cones", "teddy"),
                     "Middlebury2005": ("Art", "Books"), "Middlebury2006": ("Aloe", "Baby1")}


@pytest.mark.parametrize("name", ["KITTI2012", "KITTI2015"])
def test_kitti_layouts(tmp_path, name):
    root = write_kitti(tmp_path, name)
    assert detect_layout(root).name == name and detect_layout(root / "training").name == name
    scenes = load_scenes(root)
    assert [s.name for s in scenes] == ["000000", "000001"]
    first = scenes[0]
    assert first.left.shape == SHAPE + ((3,) if name == "KITTI2015" else ())
    assert first.left.dtype == np.uint8 and first.left.shape == first.right.shape
    assert first.ground_truth.dtype == np.float32 and first.ground_truth.shape == SHAPE
    assert np.isinf(first.ground_truth[:, :3]).all() and (first.ground_truth[:, 3:] == 3).all()
    # disp_noc only: every known pixel is non-occluded, the others unknown
    assert first.mask.dtype == np.uint8
    assert ((first.mask == 255) == np.isfinite(first.ground_truth)).all()
    assert set(np.unique(first.mask)) == {0, 255}
    assert [s.ndisp for s in scenes] == [8, 8]  # 3 + 2 and 5 + 2 -> 8
    selected = load_scenes(root / "training", scenes=["000001"])
    assert [s.name for s in selected] == ["000001"] and selected[0].ground_truth[0, -1] == 5


def test_kitti_disp_occ_is_the_ground_truth_and_marks_occluded_pixels(tmp_path):
    scene = load_scenes(write_kitti(tmp_path, occ=True), scenes=["000000"])[0]
    assert np.isfinite(scene.ground_truth[:, 3:]).all()
    assert (scene.mask[:, -4:] == 128).all() and (scene.mask[:, 3:-4] == 255).all()
    assert (scene.mask[:, :3] == 0).all()


@pytest.mark.parametrize("name", list(MIDDLEBURY_SCENES))
def test_middlebury_layouts(tmp_path, name):
    root = write_middlebury(tmp_path, name, MIDDLEBURY_SCENES[name])
    assert detect_layout(root).name == name
    scenes = load_scenes(root)
    assert [s.name for s in scenes] == sorted(MIDDLEBURY_SCENES[name])
    for scene, shift in zip(sorted(scenes, key=lambda s: MIDDLEBURY_SCENES[name].index(s.name)), (3, 5)):
        assert scene.left.shape == SHAPE + (3,) and scene.left.dtype == np.uint8
        assert scene.mask is None and scene.ndisp == 8
        assert (scene.ground_truth[:, shift:] == shift).all()
        assert np.isinf(scene.ground_truth[:, :shift]).all()
        assert scene.path == root / scene.name


def test_middlebury_2005_scale_follows_the_image_size(tmp_path):
    root = write_middlebury(tmp_path, "Middlebury2005", ("Art",), (7,), width=600)  # half size
    scene = load_scenes(root)[0]
    assert scene.ground_truth[0, -1] == 7 and scene.ndisp == 16
    (root / "Art" / "dmin.txt").write_text("10\n")  # a full-size offset, added to known pixels
    scene = load_scenes(root)[0]
    assert scene.ground_truth[0, -1] == 17 and np.isinf(scene.ground_truth[0, 0])


def test_same_file_names_told_apart_by_folder_year_then_scene_names(tmp_path):
    root = write_middlebury(tmp_path, "Middlebury2003", ("cones",), (3,))
    assert detect_layout(root).name == "Middlebury2003"
    renamed = root.rename(tmp_path / "older")
    assert detect_layout(renamed).name == "Middlebury2003"  # "cones" is a 2003 scene
    (renamed / "cones").rename(renamed / "mine")
    with pytest.raises(InputError, match="cannot tell Middlebury2001 from Middlebury2003"):
        detect_layout(renamed)
    assert detect_layout(renamed.rename(tmp_path / "set_2001")).name == "Middlebury2001"
    assert load_scenes(tmp_path / "set_2001", layout="Middlebury2003")[0].ground_truth[0, -1] == 3


def test_unknown_layout_is_a_one_line_error_listing_the_known_ones(tmp_path):
    (tmp_path / "photos").mkdir()
    (tmp_path / "photos" / "a.png").write_bytes(b"")
    with pytest.raises(InputError) as error:
        detect_layout(tmp_path)
    message = str(error.value)
    assert "\n" not in message and "no known stereo data layout" in message
    assert all(name in message for name in LAYOUTS)
    with pytest.raises(InputError, match="unknown layout 'KITTI'"):
        load_scenes(tmp_path, layout="KITTI")


def test_middeval3_stays_the_default(tmp_path):
    assert detect_layout(tmp_path / "absent").name == "MiddEval3"
    with pytest.raises(InputError, match="data directory not found"):
        load_scenes(tmp_path / "absent")
    (tmp_path / "trainingQ").mkdir()
    assert detect_layout(tmp_path).name == "MiddEval3"
    with pytest.raises(InputError, match="no scene folders"):
        load_scenes(tmp_path)


def test_ndisp_rule_and_override(tmp_path):
    assert ndisp_from_ground_truth(np.array([[17.875, np.inf]])) == 24
    assert ndisp_from_ground_truth(np.array([[6.0]])) == 8
    assert ndisp_from_ground_truth(np.array([[14.0]])) == 16
    assert ndisp_from_ground_truth(np.array([[14.1, 0.0]])) == 24
    with pytest.raises(ValueError, match="no known disparity"):
        ndisp_from_ground_truth(np.full((2, 2), np.inf))
    root = write_kitti(tmp_path)
    assert [s.ndisp for s in load_scenes(root, ndisp=40)] == [40, 40]
    with pytest.raises(ValueError, match="positive integer"):
        load_scenes(root, ndisp=0)


def test_scene_errors(tmp_path):
    root = write_kitti(tmp_path)
    with pytest.raises(InputError, match="unknown scene.*nope.*available: 000000, 000001"):
        load_scenes(root, scenes=["nope"])
    (root / "training" / "disp_noc" / "000001_10.png").unlink()
    with pytest.raises(InputError, match="scene 000001: no ground truth.*--ndisp"):
        load_scenes(root)
    scene = load_scenes(root, scenes=["000001"], ndisp=16)[0]
    assert scene.ground_truth is None and scene.mask is None and scene.ndisp == 16
    iio.imwrite(root / "training" / "disp_noc" / "000001_10.png", np.zeros((3, 3), np.uint16))
    with pytest.raises(InputError, match="scene 000001: 000001_10.png shape"):
        load_scenes(root, scenes=["000001"])


def test_read_scaled_disparity(tmp_path):
    iio.imwrite(tmp_path / "d.png", np.array([[0, 256, 640]], np.uint16))
    assert read_scaled_disparity(tmp_path / "d.png", scale=256).tolist() == [[np.inf, 1.0, 2.5]]
    iio.imwrite(tmp_path / "c.png", np.zeros((2, 2, 3), np.uint8))
    with pytest.raises(InputError, match="must be 8- or 16-bit gray"):
        read_scaled_disparity(tmp_path / "c.png", scale=8)


def test_real_shared_data():
    if not (SHARED / "Middlebury2001").is_dir() or not (SHARED / "KITTI2012").is_dir():
        pytest.skip(f"KITTI2012 / Middlebury2001 not found in {SHARED}")
    sawtooth = load_scenes(SHARED / "Middlebury2001", scenes=["sawtooth"])[0]
    assert sawtooth.left.shape == (380, 434, 3) and sawtooth.mask is None
    assert np.nanmax(np.where(np.isfinite(sawtooth.ground_truth), sawtooth.ground_truth, np.nan)) == 17.875
    assert sawtooth.ndisp == 24
    kitti = load_scenes(SHARED / "KITTI2012", scenes=["000100"])[0]
    assert kitti.left.shape == kitti.ground_truth.shape == (370, 1226) and kitti.ndisp == 88
    assert ((kitti.mask == 255) == np.isfinite(kitti.ground_truth)).all()
    assert len(load_scenes(SHARED / "KITTI2012", ndisp=8)) == 30


def test_eth3d_two_view_layout(tmp_path, write_eth3d):
    root = write_eth3d(tmp_path)
    assert detect_layout(root).name == "ETH3D"
    assert detect_layout(root / "two_view_training").name == "ETH3D"  # not MiddEval3
    scenes = load_scenes(root)
    assert [s.name for s in scenes] == ["delivery_area_1l", "electro_1l"]
    gray, colour = scenes
    assert gray.left.shape == SHAPE and colour.left.shape == SHAPE + (3,)
    assert gray.ndisp == 32 and colour.ndisp == 8  # calib.txt's ndisp; else 5 + 2 -> 8
    assert np.isinf(colour.ground_truth[:, :5]).all() and (colour.ground_truth[:, 5:] == 5).all()
    assert (colour.mask[:, 5:-2] == 255).all() and (colour.mask[:, -2:] == 128).all()
    assert gray.path == root / "two_view_training" / "delivery_area_1l"
    assert [s.ndisp for s in load_scenes(root / "two_view_training", ndisp=16)] == [16, 16]
    (root / "two_view_training" / "electro_1l" / "calib.txt").unlink()
    assert load_scenes(root, scenes=["electro_1l"])[0].ndisp == 8
    (root / "two_view_training_gt" / "electro_1l" / "disp0GT.pfm").unlink()
    with pytest.raises(InputError, match="scene electro_1l: neither ndisp in .* nor ground truth"):
        load_scenes(root, scenes=["electro_1l"])
    (root / "two_view_training" / "delivery_area_1l" / "im1.png").unlink()
    with pytest.raises(InputError, match="scene delivery_area_1l: missing im1.png"):
        load_scenes(root, scenes=["delivery_area_1l"])
    assert "ETH3D (two_view_training/<scene>/{im0.png,im1.png,calib.txt}" in \
        str(pytest.raises(InputError, detect_layout, tmp_path).value)


def test_eth3d_ndisp_not_below_the_width_is_no_search_range(tmp_path, write_eth3d):
    """ETH3D writes the width as ndisp: the ground-truth rule then sizes the range."""
    root = write_eth3d(tmp_path, ndisps=(40, 39))  # 12x40 scenes of disparities 3 and 5
    images, truth = root / "two_view_training", root / "two_view_training_gt"
    assert [s.ndisp for s in load_scenes(root)] == [8, 39]  # 40 = the width: 3 + 2 -> 8; 39 kept
    gt = np.full(SHAPE, 3.0, np.float32)
    gt[0, -1] = 37.5  # the rule gives 40, the width: at most 39
    write_pfm(truth / "delivery_area_1l" / "disp0GT.pfm", gt)
    assert load_scenes(root, scenes=["delivery_area_1l"])[0].ndisp == 39
    assert load_scenes(root, scenes=["delivery_area_1l"], ndisp=12)[0].ndisp == 12
    (truth / "delivery_area_1l" / "disp0GT.pfm").unlink()
    with pytest.raises(InputError, match=r"scene delivery_area_1l: ndisp=40 in .*calib.txt is not "
                       r"below the image width 40 \(no search range\) and there is no ground "
                       r"truth in .* give sswjax evaluate --ndisp N"):
        load_scenes(root, scenes=["delivery_area_1l"])
    write_pfm(truth / "electro_1l" / "disp0GT.pfm", np.full(SHAPE, np.inf, np.float32))
    (images / "electro_1l" / "calib.txt").write_text("ndisp=40\n")
    with pytest.raises(InputError, match="scene electro_1l: disp0GT.pfm: ground truth has no "
                       "known disparity to size the search range"):
        load_scenes(root, scenes=["electro_1l"])
    assert "ETH3D writes the width there" in LAYOUTS["ETH3D"].ndisp_rule
    # so evaluate searches the estimate there by default; every other layout has a range
    assert [name for name, layout in LAYOUTS.items() if layout.estimates_range] == ["ETH3D"]


def test_rule_at_most_the_width_minus_one_in_every_layout(tmp_path):
    root = write_kitti(tmp_path, shifts=(3, 38))  # 38 + 2 -> 40, the width
    assert [s.ndisp for s in load_scenes(root)] == [8, 39]
    root = write_middlebury(tmp_path, "Middlebury2001", ("venus",), (31,), width=32)
    assert load_scenes(root)[0].ndisp == 31  # 31 + 2 -> 40, at most 32 - 1


def test_layout_problem_says_why_a_loaded_scene_cannot_be_scored(tmp_path, write_eth3d):
    eth3d, root = LAYOUTS["ETH3D"], write_eth3d(tmp_path)
    scene = load_scenes(root, scenes=["delivery_area_1l"])[0]  # ndisp 32
    truth = root / "two_view_training_gt" / "delivery_area_1l"
    assert eth3d.problem(scene) is None
    assert eth3d.problem(scene._replace(mask=None)) == f"missing mask0nocc.png in {truth}"
    assert eth3d.problem(scene._replace(ground_truth=None)) == f"missing disp0GT.pfm in {truth}"
    assert eth3d.problem(scene._replace(ndisp=40)) == "ndisp 40 is not below the image width 40"
    unknown = scene._replace(ground_truth=np.full(SHAPE, np.inf, np.float32))
    assert eth3d.problem(unknown) == "disp0GT.pfm has no known disparity"
    assert eth3d.problem(scene._replace(mask=np.zeros(SHAPE, np.uint8))) == (
        "mask0nocc.png marks no pixel of known disparity non-occluded (255)")
    root = write_kitti(tmp_path)
    kitti = load_scenes(root, scenes=["000000"], ndisp=8)[0]
    assert LAYOUTS["KITTI2012"].problem(kitti._replace(ground_truth=None)) == (
        f"missing 000000_10.png in {root / 'training' / 'disp_noc'}")
    middeval3 = LAYOUTS["MiddEval3"]
    assert middeval3.problem(kitti._replace(ground_truth=None)) == (
        f"missing disp0GT.pfm in {kitti.path}")


def test_registry_classes_scoring_and_required_files():
    """What ``sswjax evaluate`` reads of a layout: its name, scoring and required files."""
    expected = {
        "MiddEval3": (MiddEval3Layout, "middeval3", True,
                      (("ground_truth", "disp0GT.pfm"), ("mask", "mask0nocc.png"))),
        "KITTI2012": (KittiLayout, "kitti", True, (("ground_truth", "disp_noc"),)),
        "KITTI2015": (KittiLayout, "kitti", True, (("ground_truth", "disp_noc_0"),)),
        "Middlebury2001": (MiddleburyLayout, "mean", False, (("ground_truth", "disp2.pgm"),)),
        "Middlebury2003": (MiddleburyLayout, "mean", False, (("ground_truth", "disp2.pgm"),)),
        "Middlebury2005": (MiddleburyLayout, "mean", False, (("ground_truth", "disp1.png"),)),
        "Middlebury2006": (MiddleburyLayout, "mean", False, (("ground_truth", "disp1.png"),)),
        "ETH3D": (Eth3dLayout, "mean", True,
                  (("ground_truth", "disp0GT.pfm"), ("mask", "mask0nocc.png"))),
    }
    assert list(LAYOUTS) == list(expected)
    for name, (cls, scoring, has_masks, required) in expected.items():
        layout = LAYOUTS[name]
        assert type(layout) is cls and isinstance(layout, Layout) and layout.name == name
        assert (layout.scoring, layout.has_masks, layout.required) == (scoring, has_masks, required)
    assert LAYOUTS["KITTI2012"].files == "training/{image_0,image_1,disp_noc}"
    assert LAYOUTS["Middlebury2005"].files == "<scene>/{view1.png,view5.png,disp1.png}"
    assert LAYOUTS["MiddEval3"].files == "<scene>/{im0.png,im1.png,calib.txt}"
    with pytest.raises(TypeError):
        Layout()  # the base class is abstract
