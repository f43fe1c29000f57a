"""The stereo calibration readers (``sswjax.data.calibration``): one fixture per format, written
as the tools write them, and every bad file a one-line error naming the file and the field."""

import math

import numpy as np
import pytest

from sswjax._files import InputError
from sswjax.api.geometry import StereoCalibration
from sswjax.api.rectify import as_rectified, rectification, rectified_calibration
from sswjax.data.calibration import (calibration_format, read_kitti_calibration,
                                     read_middlebury_calibration, read_opencv_calibration,
                                     read_ros_calibration, read_stereo_calibration)


def rotation(x, y, z):
    """The rotation of the vector (x, y, z) (Rodrigues), float64 (3, 3)."""
    axis = np.array([x, y, z], np.float64)
    angle = np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]]) / angle
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


K1 = np.array([[700.5, 0, 321.25], [0, 701.0, 239.5], [0, 0, 1]])
K2 = np.array([[698.0, 0, 318.0], [0, 699.5, 242.0], [0, 0, 1]])
D1 = np.array([-0.21, 0.05, 0.001, -0.0005, 0.01])
D2 = np.array([-0.19, 0.04, -0.0008, 0.0006, 0.0])
R = rotation(0.004, -0.012, 0.002)
T = np.array([-0.12, 0.0015, -0.002])
R1, R2 = rotation(0.001, -0.006, 0.001), rotation(0.002, 0.006, -0.001)
P1 = np.array([[690.0, 0, 310.0, 0], [0, 690.0, 240.0, 0], [0, 0, 1, 0]])
P2 = P1.copy()
P2[0, 3] = -690.0 * 0.12
RIG = {"K1": K1, "D1": D1[None], "K2": K2, "D2": D2[None], "R": R, "T": T[:, None]}


def _numbers(values) -> list[str]:
    return [repr(float(v)) if not float(v).is_integer() else f"{float(v):.0f}." for v in values]


def opencv_yaml(keys: dict, header: str = "%YAML:1.0") -> str:
    """A FileStorage YAML text as OpenCV 4 writes it (matrices over several lines)."""
    lines = [header, "---"]
    for key, value in keys.items():
        if isinstance(value, np.ndarray):
            numbers = _numbers(value.ravel())
            lines += [f"{key}: !!opencv-matrix", f"   rows: {value.shape[0]}",
                      f"   cols: {value.shape[1] if value.ndim > 1 else 1}", "   dt: d",
                      f"   data: [ {', '.join(numbers[:4])}" + ("," if len(numbers) > 4 else " ]")]
            if len(numbers) > 4:
                lines.append(f"       {', '.join(numbers[4:])} ]")
        else:
            lines.append(f"{key}: {value}")
    return "\n".join(lines) + "\n"


def opencv_xml(keys: dict) -> str:
    """A FileStorage XML text as OpenCV writes it."""
    lines = ['<?xml version="1.0"?>', "<opencv_storage>"]
    for key, value in keys.items():
        if isinstance(value, np.ndarray):
            lines += [f'<{key} type_id="opencv-matrix">', f"  <rows>{value.shape[0]}</rows>",
                      f"  <cols>{value.shape[1] if value.ndim > 1 else 1}</cols>",
                      "  <dt>d</dt>",
                      f"  <data>\n    {' '.join(_numbers(value.ravel()))}</data></{key}>"]
        else:
            lines.append(f"<{key}>{value}</{key}>")
    return "\n".join(lines + ["</opencv_storage>"]) + "\n"


def ros_yaml(name: str, k, d, r, p) -> str:
    """One camera_info YAML as ROS's camera_calibration writes it."""
    def block(key, value):
        rows, cols = (1, value.size) if value.ndim == 1 else value.shape
        return [f"{key}:", f"  rows: {rows}", f"  cols: {cols}",
                f"  data: [{', '.join(repr(float(v)) for v in value.ravel())}]"]
    return "\n".join(["image_width: 640", "image_height: 480", f"camera_name: {name}",
                      *block("camera_matrix", k), "distortion_model: plumb_bob",
                      *block("distortion_coefficients", d), *block("rectification_matrix", r),
                      *block("projection_matrix", p)]) + "\n"


KITTI_POSES = {"00": (rotation(1e-9, 0, 0), np.zeros(3)),
               "01": (rotation(0.001, -0.002, 0.0005), np.array([-0.537, 0.005, -0.004])),
               "02": (rotation(0.0007, 0.003, -0.001), np.array([0.059, -0.001, 0.0025])),
               "03": (rotation(-0.002, 0.001, 0.0012), np.array([-0.473, 0.0024, 0.0027]))}


def kitti_text(skip: str | None = None, replace: dict | None = None) -> str:
    """A calib_cam_to_cam.txt in KITTI's layout (``%e`` numbers), four cameras."""
    def line(key, values):
        values = (replace or {}).get(key, values)
        return None if key == skip else f"{key}: " + " ".join(f"{v:e}" for v in np.ravel(values))
    lines = ["calib_time: 09-Jan-2012 13:57:47", "corner_dist: 9.950000e-02"]
    for i, (camera, (rot, trans)) in enumerate(KITTI_POSES.items()):
        k = np.array([[984.2 + i, 0, 690.0 + i], [0, 980.8 - i, 233.2], [0, 0, 1]])
        p = np.array([[721.5377, 0, 609.5593, 721.5377 * trans[0]], [0, 721.5377, 172.854, 0],
                      [0, 0, 1, 0]])
        lines += [line(f"S_{camera}", [1392, 512]), line(f"K_{camera}", k),
                  line(f"D_{camera}", [-0.37 + 0.01 * i, 0.2, 0.002, 0.001, -0.07]),
                  line(f"R_{camera}", rot), line(f"T_{camera}", trans),
                  line(f"S_rect_{camera}", [1242, 375]),
                  line(f"R_rect_{camera}", rotation(0.004, -0.003, 0.002 + 0.001 * i)),
                  line(f"P_rect_{camera}", p)]
    return "\n".join(entry for entry in lines if entry is not None) + "\n"


MIDDLEBURY = ("cam0=[999.421 0 294.182; 0 999.421 252.932; 0 0 1]\n"
              "cam1=[999.421 0 326.96; 0 999.421 252.932; 0 0 1]\ndoffs=32.778\n"
              "baseline=193.001\nwidth=741\nheight=497\nndisp=70\nisint=0\nvmin=7\nvmax=65\n")


def _same_rig(calib, k1=K1, d1=D1, k2=K2, d2=D2, r=R, t=T):
    for got, want in zip(calib[:6], (k1, d1, k2, d2, r, t)):
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)


# ----------------------------------------------------------------------------- each format


@pytest.mark.parametrize("header", ["%YAML:1.0", "%YAML 1.2"])
def test_opencv_yaml(tmp_path, header):
    path = tmp_path / "stereo.yaml"
    path.write_text(opencv_yaml({**RIG, "image_width": 640, "image_height": 480}, header))
    calib = read_stereo_calibration(path)
    assert isinstance(calib, StereoCalibration) and calibration_format(path) == "opencv-yaml"
    _same_rig(calib)
    assert calib.image_size == (640, 480) and calib.rectification is None
    assert not calib.rectified


def test_opencv_yaml_with_rectification_and_aliases(tmp_path):
    keys = {"M1": K1, "D1": D1[None], "M2": K2, "D2": D2[None], "R": R, "T": T[:, None],
            "R1": R1, "R2": R2, "P1": P1, "P2": P2, "imageSize": "[ 640, 480 ]"}
    path = tmp_path / "stereo.yml"
    path.write_text(opencv_yaml(keys) + "# written by a calibration script\n")
    calib = read_stereo_calibration(path)
    _same_rig(calib)
    np.testing.assert_array_equal(calib.rectification.p2, P2)
    assert calib.rectification.size == (640, 480) and calib.image_size == (640, 480)


def test_opencv_intrinsics_and_extrinsics_files(tmp_path):
    # OpenCV's stereo_calib.cpp sample writes two files.
    (tmp_path / "intrinsics.yml").write_text(opencv_yaml({k: RIG[k] for k in ("K1", "D1")} |
                                                         {"M2": K2, "D2": D2[None]}))
    (tmp_path / "extrinsics.yml").write_text(opencv_yaml({"R": R, "T": T[:, None]}))
    _same_rig(read_stereo_calibration(tmp_path / "intrinsics.yml",
                                      right=tmp_path / "extrinsics.yml"))


def test_opencv_xml(tmp_path):
    path = tmp_path / "stereo.xml"
    path.write_text(opencv_xml({**RIG, "imageSize": "\n  640 480"}))
    calib = read_stereo_calibration(path)
    assert calibration_format(path) == "opencv-xml" and calib.image_size == (640, 480)
    _same_rig(calib)


def test_filestorage_written_by_opencv(tmp_path):
    cv2 = pytest.importorskip("cv2")
    for name in ("stereo.yaml", "stereo.xml"):
        storage = cv2.FileStorage(str(tmp_path / name), cv2.FILE_STORAGE_WRITE)
        for key, value in {**RIG, "R1": R1, "R2": R2, "P1": P1, "P2": P2}.items():
            storage.write(key, value)
        storage.write("image_width", 640)
        storage.write("image_height", 480)
        storage.release()
        calib = read_stereo_calibration(tmp_path / name)
        _same_rig(calib)
        np.testing.assert_array_equal(calib.rectification.r2, R2)


def test_npz(tmp_path):
    path = tmp_path / "stereo.npz"
    np.savez(path, **RIG, R1=R1, R2=R2, P1=P1, P2=P2, image_size=np.array([640, 480]))
    calib = read_stereo_calibration(path)
    assert calibration_format(path) == "npz" and calib.image_size == (640, 480)
    _same_rig(calib)
    assert read_opencv_calibration(path).rectification.size == (640, 480)


def test_ros_pair(tmp_path):
    left, right = tmp_path / "left.yaml", tmp_path / "right.yaml"
    left.write_text(ros_yaml("narrow_stereo/left", K1, D1, R1, P1))
    right.write_text(ros_yaml("narrow_stereo/right", K2, D2, R2, P2))
    calib = read_stereo_calibration(left, right=right)
    assert calibration_format(left) == "ros" and calib.image_size == (640, 480)
    # x_right = R x_left + T with R = R2^T R1, T = R2^T (-B, 0, 0)
    _same_rig(calib, r=R2.T @ R1, t=R2.T @ np.array([-0.12, 0.0, 0.0]))
    np.testing.assert_array_equal(calib.rectification.p1, P1)
    assert read_ros_calibration(left, right).rectification.size == (640, 480)


def test_kitti_pairs(tmp_path):
    path = tmp_path / "calib_cam_to_cam.txt"
    path.write_text(kitti_text())
    assert calibration_format(path) == "kitti"
    for cameras in (("00", "01"), ("02", "03")):
        calib = read_kitti_calibration(path, cameras=cameras)
        (ra, ta), (rb, tb) = KITTI_POSES[cameras[0]], KITTI_POSES[cameras[1]]
        np.testing.assert_allclose(calib.rotation, rb @ ra.T, atol=1e-6)
        np.testing.assert_allclose(calib.translation, tb - rb @ ra.T @ ta, atol=1e-6)
        assert calib.image_size == (1392, 512) and calib.rectification.size == (1242, 375)
    gray = read_stereo_calibration(path)                       # default: 00 01
    np.testing.assert_allclose(gray.translation, KITTI_POSES["01"][1], atol=1e-6)
    colour = read_stereo_calibration(path, cameras=("02", "03"))
    assert colour.left_matrix[0, 2] == pytest.approx(692.0)


def test_kitti_rectified_images(tmp_path):
    # KITTI's rectified images (S_rect) are the rig of P_rect: rectified, the baseline of Tx
    path = tmp_path / "calib_cam_to_cam.txt"
    path.write_text(kitti_text())
    rig = as_rectified(read_kitti_calibration(path, cameras=("02", "03")))
    assert rig.rectified and rig.image_size == (1242, 375) and rig.left_distortion.size == 0
    assert rig.translation[0] == pytest.approx(-(0.059 + 0.473))
    assert rectified_calibration(rectification(rig)).focal == 721.5377


def test_middlebury(tmp_path):
    path = tmp_path / "calib.txt"
    path.write_text(MIDDLEBURY)
    calib = read_stereo_calibration(path)
    assert calibration_format(path) == "middlebury" and calib.rectified
    assert calib.image_size == (741, 497) and calib.left_distortion.size == 0
    np.testing.assert_array_equal(calib.translation, [-193.001, 0, 0])
    assert calib.right_matrix[0, 2] == 326.96
    path.write_text("cam0=[500 0 20; 0 500 6; 0 0 1]\nbaseline=60\ndoffs=4\n")  # no cam1
    assert read_middlebury_calibration(path).right_matrix[0, 2] == 24


# ----------------------------------------------------------------------------- bad files


def _yaml_without(key, **replace):
    keys = {**RIG, "image_width": 640, "image_height": 480, **replace}
    keys.pop(key, None)
    return opencv_yaml(keys)


BAD_OPENCV = [
    (_yaml_without("K1"), r"lacks K1 \(the left camera matrix; also read as M1 or cameraMatrix1\)"),
    (_yaml_without("T"), "lacks T"),
    (_yaml_without("", K1=np.eye(3)[:2]), "K1 must be 3x3, got 2x3"),
    (_yaml_without("", T=np.ones((2, 1))), "T must be 3, got 2x1"),
    (_yaml_without("", D2=np.zeros((1, 6))), "D2 must have 4, 5, 8, 12 or 14 coefficients, got 6"),
    (_yaml_without("", K2=np.diag([0.0, 700.0, 1.0])), "K2 is singular: a focal length is 0"),
    (_yaml_without("", R=np.ones((3, 3))), r"R is not a rotation matrix \(singular\)"),
    (_yaml_without("", R=np.diag([1.0, 1.0, -1.0])), "R is a reflection"),
    (_yaml_without("", T=np.zeros((3, 1))), "T is zero: the two cameras are at the same place"),
    (_yaml_without("").replace("701.", ".nan", 1), "K1 has non-finite values"),
    (_yaml_without("", image_width=0), "image_width must be a positive integer, got 0"),
    (_yaml_without("image_height"), "lacks image_height"),
    (_yaml_without("", R1=R1, P1=P1), "has R1 P1 but lacks R2 P2: give all of R1 R2 P1 P2 or none"),
    (_yaml_without("").replace("   rows: 3\n", "   rows: 2\n", 1), "K1 is 2x3 but holds 9 numbers"),
    (_yaml_without("").replace("data: [", "data: ", 1),
     "unclosed bracket|must be numbers|bad indentation"),
    ("%YAML:1.0\n---\n  K1: 3\n bad: 4\n", "bad indentation"),
    ("", "is empty"),
]


@pytest.mark.parametrize("text, message", BAD_OPENCV, ids=[
    "no-K1", "no-T", "K1-shape", "T-shape", "D2-length", "K2-singular", "R-singular",
    "R-reflection", "T-zero", "K1-nan", "width-zero", "no-height", "half-rectification",
    "rows-cols", "unclosed", "indentation", "empty"])
def test_bad_opencv_yaml(tmp_path, text, message):
    path = tmp_path / "stereo.yaml"
    path.write_text(text)
    _one_line(lambda: read_opencv_calibration(path), path, message)


def _one_line(call, path, message):
    with pytest.raises(InputError, match=message) as error:
        call()
    assert str(path) in str(error.value) and "\n" not in str(error.value)


def test_bad_xml_and_npz(tmp_path):
    xml = tmp_path / "stereo.xml"
    xml.write_text(opencv_xml({**RIG, "K1": np.full((3, 3), np.inf)}))
    _one_line(lambda: read_stereo_calibration(xml), xml, "K1 has non-finite values")
    xml.write_text("<?xml version='1.0'?><opencv_storage><K1>")
    _one_line(lambda: read_stereo_calibration(xml), xml, "is not readable XML")
    npz = tmp_path / "stereo.npz"
    np.savez(npz, **{k: v for k, v in RIG.items() if k != "R"})
    _one_line(lambda: read_stereo_calibration(npz), npz, "lacks R")
    npz.write_bytes(b"PK\x03\x04 not a zip")
    _one_line(lambda: read_stereo_calibration(npz), npz, "cannot read calibration file")


def test_bad_ros_files(tmp_path):
    left, right = tmp_path / "left.yaml", tmp_path / "right.yaml"
    left.write_text(ros_yaml("left", K1, D1, R1, P1))
    right.write_text(ros_yaml("right", np.diag([700.0, 0.0, 1.0]), D2, R2, P2))
    _one_line(lambda: read_ros_calibration(left, right), right,
              "camera_matrix is singular: a focal length is 0")
    right.write_text(ros_yaml("right", K2, D2, R2, P1))                   # Tx = 0
    _one_line(lambda: read_ros_calibration(left, right), right, "projection_matrix has Tx = 0")
    right.write_text(ros_yaml("right", K2, D2, R2 * 2, P2))
    _one_line(lambda: read_ros_calibration(left, right), right,
              "rectification_matrix is not a rotation matrix")
    right.write_text(ros_yaml("right", K2, D2, R2, P2).replace("image_width: 640",
                                                               "image_width: 320"))
    _one_line(lambda: read_ros_calibration(left, right), right, "differs from the left camera's")
    right.write_text(ros_yaml("right", K2, D2, R2, P2).replace("plumb_bob", "equidistant"))
    _one_line(lambda: read_ros_calibration(left, right), right, "distortion_model 'equidistant'")
    right.write_text(ros_yaml("right", K2, D2, R2, P2).replace("projection_matrix", "P"))
    _one_line(lambda: read_ros_calibration(left, right), right, "lacks projection_matrix")
    _one_line(lambda: read_stereo_calibration(left), left, "give the right camera's file too")


@pytest.mark.parametrize("kwargs, message", [
    ({"skip": "T_01"}, r"lacks T_01 \(camera 01\)"),
    ({"replace": {"K_00": np.eye(3)[:2]}}, "K_00 must hold 9 numbers, got 6"),
    ({"replace": {"K_01": np.zeros((3, 3))}}, "K_01 is singular"),
    ({"replace": {"D_00": [np.nan] * 5}}, "D_00 has non-finite values"),
    ({"replace": {"S_01": [1240, 512]}}, "S_01 1240x512 differs from S_00 1392x512"),
    ({"replace": {"R_rect_00": np.eye(3) * 3}}, "R_rect_00 is not a rotation matrix"),
])
def test_bad_kitti(tmp_path, kwargs, message):
    path = tmp_path / "calib_cam_to_cam.txt"
    path.write_text(kitti_text(**kwargs))
    _one_line(lambda: read_stereo_calibration(path), path, message)


def test_bad_kitti_cameras_and_lines(tmp_path):
    path = tmp_path / "calib_cam_to_cam.txt"
    path.write_text(kitti_text() + "not a key line\n")
    _one_line(lambda: read_kitti_calibration(path), path, "line 35 is not KEY: values")
    with pytest.raises(ValueError, match="cameras must be two of 00, 01, 02, 03"):
        read_kitti_calibration(path, cameras=("00", "04"))
    yaml = tmp_path / "stereo.yaml"
    yaml.write_text(opencv_yaml(RIG))
    _one_line(lambda: read_stereo_calibration(yaml, cameras=("02", "03")), yaml,
              "cameras 02 03 are for KITTI's")


@pytest.mark.parametrize("text, message", [
    (MIDDLEBURY.replace("doffs=32.778", "doffs=30"), "doffs 30 is not cam1's cx minus cam0's"),
    (MIDDLEBURY.replace("cam1=[999.421 0 326.96;", "cam1=[999.421 0;"), "cam1 must be"),
    (MIDDLEBURY.replace("height=497\n", ""), "lacks height"),
    (MIDDLEBURY.replace("baseline=193.001", "baseline=0"), "baseline must be > 0"),
])
def test_bad_middlebury(tmp_path, text, message):
    path = tmp_path / "calib.txt"
    path.write_text(text)
    _one_line(lambda: read_stereo_calibration(path), path, message)


def test_missing_and_unknown_files(tmp_path):
    _one_line(lambda: read_stereo_calibration(tmp_path / "nope.yaml"), tmp_path / "nope.yaml",
              "calibration file not found")
    odd = tmp_path / "odd.bin"
    odd.write_bytes(b"\x00\x01\x02")
    _one_line(lambda: read_stereo_calibration(odd), odd, "not a format sswjax reads")
