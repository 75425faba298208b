"""Intrinsics: ROS camera_info YAML (ours and hand-written) and OpenCV FileStorage (written by cv2)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import yaml

from calib_core.camera import CameraModel
from calib_core.errors import SessionError
from calib_core.io.intrinsics import camera_info_dict, load_intrinsics, save_intrinsics_ros

K = np.array([[1402.5, 0.0, 961.2], [0.0, 1400.1, 538.9], [0.0, 0.0, 1.0]])
D = np.array([-0.21, 0.07, 0.0011, -0.0007, -0.012])

ROS_TEXT = """image_width: 1920
image_height: 1080
camera_name: cam1
camera_matrix:
  rows: 3
  cols: 3
  data: [1402.5, 0, 961.2, 0, 1400.1, 538.9, 0, 0, 1]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.21, 0.07, 0.0011, -0.0007, -0.012]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
projection_matrix:
  rows: 3
  cols: 4
  data: [1402.5, 0, 961.2, 0, 0, 1400.1, 538.9, 0, 0, 0, 1, 0]
"""


def check(cam: CameraModel, w=1920, h=1080):
    assert (cam.width_px, cam.height_px) == (w, h)
    np.testing.assert_allclose(cam.K, K)
    np.testing.assert_allclose(cam.dist, D)


def test_ros_as_written_by_camera_calibration(tmp_path):
    (tmp_path / "cam1.yaml").write_text(ROS_TEXT)
    cam = load_intrinsics(tmp_path / "cam1.yaml")
    check(cam)
    assert cam.name == "cam1"


def test_ros_round_trip(tmp_path):
    cam = CameraModel(1920, 1080, K, D, name="left")
    save_intrinsics_ros(tmp_path / "i" / "left.yaml", cam)
    back = load_intrinsics(tmp_path / "i" / "left.yaml")
    check(back)
    assert back.name == "left"
    d = yaml.safe_load((tmp_path / "i" / "left.yaml").read_text())
    assert d == camera_info_dict(cam)
    assert d["projection_matrix"]["data"][:3] == list(K[0])


def test_ros_variants(tmp_path):
    d = yaml.safe_load(ROS_TEXT)
    d["distortion_coefficients"] = {"rows": 1, "cols": 4, "data": D[:4].tolist()}  # k3 omitted
    (tmp_path / "a.yaml").write_text(yaml.safe_dump(d))
    assert load_intrinsics(tmp_path / "a.yaml").dist[4] == 0.0
    d["distortion_model"] = "rational_polynomial"
    d["distortion_coefficients"] = {"rows": 1, "cols": 8, "data": D.tolist() + [0, 0, 0]}
    (tmp_path / "b.yaml").write_text(yaml.safe_dump(d))
    check(load_intrinsics(tmp_path / "b.yaml"))
    del d["distortion_coefficients"]
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(d))
    assert not load_intrinsics(tmp_path / "c.yaml").dist.any()
    (tmp_path / "d.yaml").write_text("%YAML 1.1\n---\n" + ROS_TEXT)  # a standard YAML directive
    check(load_intrinsics(tmp_path / "d.yaml"))


@pytest.mark.parametrize("suffix", [".yaml", ".yml", ".xml"])
def test_opencv_filestorage_written_by_cv2(tmp_path, suffix):
    path = str(tmp_path / f"cv{suffix}")
    fs = cv2.FileStorage(path, cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 1920)
    fs.write("image_height", 1080)
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", D.reshape(1, 5))
    fs.release()
    check(load_intrinsics(path))


def test_opencv_filestorage_alternative_names(tmp_path):
    path = str(tmp_path / "calib.yml")
    fs = cv2.FileStorage(path, cv2.FILE_STORAGE_WRITE)
    fs.write("width", 1920)
    fs.write("height", 1080)
    fs.write("cameraMatrix", K)
    fs.write("distCoeffs", D.reshape(5, 1))
    fs.release()
    check(load_intrinsics(path))


@pytest.mark.parametrize("edit,match", [
    (lambda d: d["camera_matrix"].update(data=[1, 0, 0, 0, 1, 0, 0, 1]), "'camera_matrix' has 8 values, expected 9"),
    (lambda d: d["distortion_coefficients"].update(data=[0.1, 0.2, 0.3]), "has 3 values, expected 4 or 5 or 8"),
    (lambda d: d.pop("image_width"), "missing 'image_width'"),
    (lambda d: d.update(image_width="wide"), "whole numbers"),
    (lambda d: d.update(image_width=1920.5), "whole numbers"),
    (lambda d: d.update(image_width=float("inf")), "whole numbers"),
    (lambda d: d.update(image_height=-1080), "not plausible"),
    (lambda d: d["camera_matrix"].update(data=[-1402.5, 0, 961.2, 0, 1400.1, 538.9, 0, 0, 1]), "focal lengths must be positive"),
    (lambda d: d["camera_matrix"].update(data=[1402.5, 0, 961.2, 0, 1400.1, 538.9, 0, 0, 2]), "must be \\[fx"),
    (lambda d: d["camera_matrix"].update(data=["a", 0, 961.2, 0, 1400.1, 538.9, 0, 0, 1]), "list of numbers"),
    (lambda d: d["camera_matrix"].update(data=[float("nan"), 0, 961.2, 0, 1400.1, 538.9, 0, 0, 1]), "NaN or infinite"),
    (lambda d: d["camera_matrix"].update(data=10**400), "list of numbers"),
    (lambda d: d["distortion_coefficients"].update(data=[10**400, 0, 0, 0, 0]), "list of numbers"),
    (lambda d: d.update(distortion_model="double_sphere"), "not supported"),
    (lambda d: d.pop("camera_matrix"), "missing 'camera_matrix'"),
    (lambda d: d.update(camera_matrix=None), "missing 'camera_matrix'"),
    (lambda d: d.update(camera_matrix={"rows": 3}), "has 1 values"),
    # finite but absurd (session 25, sec): detect ran on them, overflow warnings, "no round outline"
    (lambda d: d["camera_matrix"].update(data=[1e308, 0, 961.2, 0, 1e308, 538.9, 0, 0, 1]), "not plausible"),
    (lambda d: d["camera_matrix"].update(data=[1e-300, 0, 961.2, 0, 1e-300, 538.9, 0, 0, 1]), "not plausible"),
    (lambda d: d["camera_matrix"].update(data=[1402.5, 0, 1e308, 0, 1400.1, 538.9, 0, 0, 1]), "principal point"),
    (lambda d: d["camera_matrix"].update(data=[1402.5, 1e308, 961.2, 0, 1400.1, 538.9, 0, 0, 1]), "skew"),
    (lambda d: d["distortion_coefficients"].update(data=[1e308, 0, 0, 0, 0]), "distortion coefficients up to"),
])
def test_bad_ros_files(tmp_path, edit, match):
    d = yaml.safe_load(ROS_TEXT)
    edit(d)
    p = tmp_path / "bad.yaml"
    p.write_text(yaml.safe_dump(d))
    with pytest.raises(SessionError, match=match) as ei:
        load_intrinsics(p)
    assert ei.value.path == p


@pytest.mark.parametrize("content", [
    b"", b"   \n", b"image_width: [1920\n", b"- just\n- a list\n", b"\xff\xfe\x00garbage\x00" * 20,
    b"[" * 5000, b"%YAML:1.0\ncamera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n  data: [1, 2]\n",
    b"%YAML:1.0\n  : : broken [\n", b"<?xml version=\"1.0\"?>\n<opencv_storage><camera_matrix>",
    b"%YAML:1.0\nimage_width: wide\nimage_height: 10\ncamera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n"
    b"  data: [1, 0, 1, 0, 1, 1, 0, 0, 1]\n",
])
def test_corrupt_intrinsics_files(tmp_path, content):
    p = tmp_path / "i.yaml"
    p.write_bytes(content)
    with pytest.raises(SessionError) as ei:
        load_intrinsics(p)
    assert ei.value.path == p


def test_missing_file(tmp_path):
    with pytest.raises(SessionError, match="intrinsics file not found"):
        load_intrinsics(tmp_path / "nope.yaml")
