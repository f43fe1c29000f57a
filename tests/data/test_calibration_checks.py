"""One reader of Middlebury's ``calib.txt`` and one set of checks for every path that reads it
(``match --calib``, ``--rectify``, ``sswjax rectify``, the evaluation layouts, the API), keys
given twice in every calibration format, and inputs that are not regular files (a FIFO is
never opened: its open would wait for a writer)."""

import os

import numpy as np
import pytest

from sswjax._files import InputError
from sswjax.data.calibration import (read_calib, read_calibration, read_kitti_calibration,
                                     read_middlebury_calibration, read_stereo_calibration)
from sswjax.data.io import read_image, read_pfm

MOTORCYCLE = ("cam0=[999.421 0 294.182; 0 999.421 252.932; 0 0 1]\n"
              "cam1=[999.421 0 326.96; 0 999.421 252.932; 0 0 1]\ndoffs=32.778\n"
              "baseline=193.001\nwidth=741\nheight=497\nndisp=70\n")
NO_DOFFS = MOTORCYCLE.replace("doffs=32.778\n", "")
WRONG_DOFFS = MOTORCYCLE.replace("doffs=32.778", "doffs=5")
TWO_CAM0 = "cam0=[500 0 20; 0 500 6; 0 0 1]\nbaseline=60\n" + \
           "cam0=[1000 0 20; 0 1000 6; 0 0 1]\n"


def _one_line(call, path, message):
    with pytest.raises(InputError, match=message) as error:
        call()
    assert str(path) in str(error.value) and "\n" not in str(error.value)
    return str(error.value)


def _write(tmp_path, text, name="calib.txt"):
    path = tmp_path / name
    path.write_text(text)
    return path


# ----------------------------------------------------------------------------- doffs


def test_missing_doffs_is_cam1_cx_minus_cam0_cx(tmp_path):
    """The format defines doffs as the x-difference of the principal points: without the line,
    depth and clouds take it from cam0 and cam1 (not 0, depth 2.67x the truth), as the rig of
    --rectify always did."""
    path = _write(tmp_path, NO_DOFFS)
    assert read_calibration(path).doffs == pytest.approx(32.778, abs=1e-9)
    rig = read_middlebury_calibration(path)
    assert rig.right_matrix[0, 2] - rig.left_matrix[0, 2] == pytest.approx(32.778, abs=1e-9)
    # without cam1 the file gives one camera for both: doffs 0, as --focal without --doffs
    path.write_text("cam0=[500 0 20; 0 500 6; 0 0 1]\nbaseline=60\n")
    assert read_calibration(path).doffs == 0.0


@pytest.mark.parametrize("reader", [read_calib, read_calibration, read_middlebury_calibration,
                                    read_stereo_calibration])
def test_doffs_that_disagrees_with_the_cameras_is_refused_by_every_reader(tmp_path, reader):
    path = _write(tmp_path, WRONG_DOFFS)
    message = _one_line(lambda: reader(path), path, "doffs 5 is not cam1's cx minus cam0's")
    assert message == f"calibration file {path}: doffs 5 is not cam1's cx minus cam0's (32.778)"


def test_doffs_rounded_as_published_is_accepted(tmp_path):
    """MiddEval3's Shelves: cam0 cx 279.184, cam1 cx 326.746, doffs 47.561 (each rounded to 3
    decimals: 47.562 apart); --rectify refused it."""
    text = ("cam0=[1043.189 0 279.184; 0 1043.189 245.193; 0 0 1]\n"
            "cam1=[1043.189 0 326.746; 0 1043.189 245.193; 0 0 1]\ndoffs=47.561\n"
            "baseline=236.922\nwidth=739\nheight=497\nndisp=61\n")
    path = _write(tmp_path, text)
    assert read_middlebury_calibration(path).right_matrix[0, 2] == 326.746
    assert read_calibration(path).doffs == 47.561
    path.write_text(text.replace("doffs=47.561", "doffs=47.5"))
    _one_line(lambda: read_calibration(path), path, r"doffs 47.5 is not cam1's cx minus cam0's "
                                                    r"\(47.562\)")


# ----------------------------------------------------------------------------- keys given twice


@pytest.mark.parametrize("reader", [read_calib, read_calibration, read_middlebury_calibration,
                                    read_stereo_calibration])
def test_key_given_twice_is_refused(tmp_path, reader):
    path = _write(tmp_path, TWO_CAM0)
    message = _one_line(lambda: reader(path), path, "cam0 given twice")
    assert message == f"calibration file {path} line 3: cam0 given twice (lines 1 and 3)"
    path.write_text(MOTORCYCLE + "ndisp=80\n")          # any key, the evaluation's ndisp too
    _one_line(lambda: read_calib(path), path, "line 8: ndisp given twice")


def test_middeval3_layout_refuses_ndisp_given_twice(middeval3, tmp_path):
    from sswjax.data.layouts.middeval3 import load_scene

    scene = middeval3(tmp_path) / "trainingQ" / "Teddy"
    (scene / "calib.txt").write_text((scene / "calib.txt").read_text() + "ndisp=99\n")
    _one_line(lambda: load_scene(scene), scene / "calib.txt", "line 5: ndisp given twice")


EYE = "[ 1., 0., 0., 0., 1., 0., 0., 0., 1. ]"
YAML = "\n".join(["%YAML:1.0", "---", *(f"{key}: !!opencv-matrix\n   rows: 3\n   cols: 3\n"
                                         f"   dt: d\n   data: {EYE}" for key in ("K1", "K2", "R")),
                  "D1: [ 0., 0., 0., 0., 0. ]", "D2: [ 0., 0., 0., 0., 0. ]",
                  "T: [ -0.1, 0., 0. ]"]) + "\n"
XML = ("<?xml version=\"1.0\"?>\n<opencv_storage>\n" + "".join(
    f'<{key} type_id="opencv-matrix"><rows>3</rows><cols>3</cols><dt>d</dt>'
    f"<data>1 0 0 0 1 0 0 0 1</data></{key}>\n" for key in ("K1", "K2", "R"))
    + "<D1>0 0 0 0 0</D1>\n<D2>0 0 0 0 0</D2>\n<T>-0.1 0 0</T>\n</opencv_storage>\n")


def test_yaml_xml_and_kitti_keys_given_twice(tmp_path):
    """OpenCV's YAML and XML (and ROS's camera_info) and KITTI's text took the last."""
    yaml = _write(tmp_path, YAML, "stereo.yaml")
    assert read_stereo_calibration(yaml).translation[0] == -0.1
    yaml.write_text(YAML + "T: [ -0.2, 0., 0. ]\n")
    _one_line(lambda: read_stereo_calibration(yaml), yaml,
              r"line 21: T given twice \(lines 20 and 21\)")
    yaml.write_text(YAML.replace("   dt: d", "   dt: d\n   rows: 3", 1))
    _one_line(lambda: read_stereo_calibration(yaml), yaml,
              r"line 7: rows given twice \(lines 4 and 7\)")
    yaml.write_text(YAML.replace("T: [ -0.1, 0., 0. ]", "T: {a: 1, a: 2}"))
    _one_line(lambda: read_stereo_calibration(yaml), yaml, "line 20: a given twice")
    xml = _write(tmp_path, XML, "stereo.xml")
    assert read_stereo_calibration(xml).translation[0] == -0.1
    xml.write_text(XML.replace("</opencv_storage>", "<T>-0.2 0 0</T>\n</opencv_storage>"))
    _one_line(lambda: read_stereo_calibration(xml), xml, "<T> given twice")
    kitti = _write(tmp_path, "calib_time: 09-Jan-2012\nK_00: 1 0 0 0 1 0 0 0 1\n"
                   "S_00: 1392 512\nK_00: 2 0 0 0 2 0 0 0 1\n", "calib_cam_to_cam.txt")
    _one_line(lambda: read_kitti_calibration(kitti), kitti,
              r"line 4: K_00 given twice \(lines 2 and 4\)")


# ----------------------------------------------------------------------------- the command line


@pytest.mark.parametrize("text, message", [
    (WRONG_DOFFS, "calibration file {calib}: doffs 5 is not cam1's cx minus cam0's (32.778)"),
    (TWO_CAM0, "calibration file {calib} line 3: cam0 given twice (lines 1 and 3)"),
], ids=["wrong-doffs", "cam0-twice"])
@pytest.mark.parametrize("option", ["--calib", "--rectify"])
def test_match_refuses_an_inconsistent_calib_txt(small_pair, tmp_path, run_cli, text, message,
                                                 option):
    """The same file, the same one-line refusal, with --calib (depth) and --rectify."""
    calib = _write(tmp_path, text)
    out = tmp_path / "out"
    out.mkdir()
    folder = small_pair.folder
    code, _, stderr = run_cli(["match", folder / "left.png", folder / "right.png", "--ndisp",
                               small_pair.ndisp, "-o", out / "d.pfm", option, calib,
                               "--depth", out / "z.pfm"])
    assert code == 2
    assert stderr == f"sswjax: error: {message.format(calib=calib)}\n"
    assert list(out.iterdir()) == []


# ----------------------------------------------------------------------------- not regular files


@pytest.fixture()
def fifo(tmp_path):
    path = tmp_path / "pipe"
    os.mkfifo(path)       # never opened here: an open for reading waits for a writer
    return path


@pytest.mark.timeout(20, method="signal")
def test_readers_refuse_a_fifo_without_opening_it(fifo):
    for call, what in [(read_calib, "calibration file"), (read_calibration, "calibration file"),
                       (read_stereo_calibration, "calibration file"),
                       (read_middlebury_calibration, "calibration file"),
                       (read_image, "image"), (read_pfm, "PFM file")]:
        message = _one_line(lambda: call(fifo), fifo, "FIFO")
        assert message == f"{what} {fifo} is not a regular file (a FIFO)", call
    _one_line(lambda: read_image(fifo.parent), fifo.parent, r"is not a regular file \(a directory\)")


@pytest.mark.timeout(30, method="signal")
@pytest.mark.parametrize("argv, message", [
    (["match", "{p}", "{l}", "--ndisp", "8", "-o", "{o}/d.pfm"], "image {p}"),
    (["match", "{l}", "{p}", "--ndisp", "8", "-o", "{o}/d.pfm"], "image {p}"),
    (["match", "{l}", "{r}", "--ndisp", "8", "-o", "{o}/d.pfm", "--calib", "{p}",
      "--depth", "{o}/z.pfm"], "calibration file {p}"),
    (["match", "{l}", "{r}", "--ndisp", "8", "-o", "{o}/d.pfm", "--rectify", "{p}"],
     "calibration file {p}"),
    (["rectify", "{l}", "{r}", "--calib", "{p}", "-o", "{o}/rect"], "calibration file {p}"),
    (["match", "{l}", "{r}", "--ndisp", "8", "-o", "{o}/d.pfm", "--params", "{p}"],
     "parameter file {p}"),
], ids=["left", "right", "calib", "rectify", "rectify-command", "params"])
def test_cli_refuses_a_fifo_in_one_line(small_pair, fifo, tmp_path, run_cli, argv, message):
    out = tmp_path / "out"
    out.mkdir()
    names = {"p": fifo, "l": small_pair.folder / "left.png", "r": small_pair.folder / "right.png",
             "o": out}
    code, _, stderr = run_cli([a.format(**names) for a in argv])
    assert code == 2
    assert stderr == f"sswjax: error: {message.format(**names)} is not a regular file (a FIFO)\n"
    assert list(out.iterdir()) == []
