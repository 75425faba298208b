"""OpenCV's rational distortion model (ROS ``rational_polynomial``, k4..k6), as depth cameras
such as the Azure Kinect publish it: projection, inverse, Jacobian, files, bags and the solve."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
import yaml

from calib_core.camera import CameraModel
from calib_core.errors import SessionError
from calib_core.fusion.cloud import project_cloud
from calib_core.geometry import pose_error, transform_points
from calib_core.io.intrinsics import camera_info_dict, load_intrinsics, save_intrinsics_ros
from calib_core.solve.model import camera_data
from calib_core.solve.single import solve_camera

K = np.array([[612.0, 0.0, 638.0], [0.0, 611.0, 366.0], [0.0, 0.0, 1.0]])
# an Azure-Kinect-like colour camera: strong k1..k3 largely cancelled by k4..k6
D8 = np.array([0.55, -2.7, 0.0006, -0.0003, 1.55, 0.43, -2.53, 1.48])


@pytest.fixture
def cam():
    return CameraModel(1280, 720, K, D8, name="kinect")


def _points(n=60, seed=0):
    rng = np.random.default_rng(seed)
    z = rng.uniform(0.8, 4.0, n)
    return np.column_stack([rng.uniform(-0.8, 0.8, n) * z, rng.uniform(-0.45, 0.45, n) * z, z])


def test_projection_matches_opencv_and_inverts(cam):
    assert cam.rational and cam.dist.size == 8
    P = _points()
    ref, _ = cv2.projectPoints(P, np.zeros(3), np.zeros(3), K, D8)
    uv = cam.project(P)
    np.testing.assert_allclose(uv, ref.reshape(-1, 2), atol=1e-9)
    xy = P[:, :2] / P[:, 2:]
    np.testing.assert_allclose(cam.normalize(uv), xy, atol=1e-10)
    # dropping k4..k6 (what the tool did before) would put pixels tens of px off
    assert np.abs(CameraModel(1280, 720, K, D8[:5]).project(P) - uv).max() > 20


def test_jacobian_matches_finite_differences(cam):
    xy = _points(20, 1)[:, :2] / _points(20, 1)[:, 2:]
    e = 1e-6
    J = cam.distort_jacobian(xy)
    Jn = np.stack([(cam.distort(xy + [e, 0]) - cam.distort(xy - [e, 0])) / (2 * e),
                   (cam.distort(xy + [0, e]) - cam.distort(xy - [0, e])) / (2 * e)], axis=2)
    np.testing.assert_allclose(J, Jn, atol=1e-4 * np.abs(J).max())


def test_plumb_bob_stays_five_coefficients():
    assert CameraModel(640, 480, K, list(D8[:5]) + [0, 0, 0]).dist.size == 5
    assert not CameraModel(640, 480, K, D8[:5]).rational


def test_fused_cloud_projection_uses_k4_to_k6(cam):
    P = _points(200, 2)
    uv, _, valid = project_cloud(P, np.eye(4), cam)
    ok = valid & cam.in_image(cam.project(P))
    assert ok.sum() > 50
    assert np.abs(uv[ok] - cam.project(P[ok])).max() < 0.02


def test_ros_yaml_round_trip_and_plumb_bob_with_k4_refused(tmp_path, cam):
    save_intrinsics_ros(tmp_path / "k.yaml", cam)
    d = yaml.safe_load((tmp_path / "k.yaml").read_text())
    assert d["distortion_model"] == "rational_polynomial" and d["distortion_coefficients"]["cols"] == 8
    back = load_intrinsics(tmp_path / "k.yaml")
    np.testing.assert_array_equal(back.dist, cam.dist)
    d["distortion_model"] = "plumb_bob"
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump(d))
    with pytest.raises(SessionError, match="rational_polynomial") as ei:
        load_intrinsics(tmp_path / "bad.yaml")
    assert ei.value.path == tmp_path / "bad.yaml"
    assert camera_info_dict(CameraModel(640, 480, K, D8[:5]))["distortion_model"] == "plumb_bob"


def test_opencv_filestorage_with_eight_coefficients(tmp_path):
    fs = cv2.FileStorage(str(tmp_path / "cv.yaml"), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 1280)
    fs.write("image_height", 720)
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", D8.reshape(1, 8))
    fs.release()
    np.testing.assert_allclose(load_intrinsics(tmp_path / "cv.yaml").dist, D8)


def test_pose_is_recovered_through_the_rational_model(cam):
    rng = np.random.default_rng(4)
    ang = rng.normal(0, 0.2, 3)
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(ang)[0]
    T[:3, 3] = [0.1, -0.4, 0.2]
    X_cam = _points(9, 5)
    X_cam = X_cam[cam.in_image(cam.project(X_cam), 20)]
    X_sonar = transform_points(np.linalg.inv(T), X_cam)
    uv = cam.project(X_cam) + rng.normal(0, 0.2, (len(X_cam), 2))
    n = len(X_cam)
    cd = camera_data("kinect", cam, [f"p{i:02d}" for i in range(n)], uv, np.tile(np.eye(2) * 0.04, (n, 1, 1)),
                     X_sonar, np.tile(np.eye(3) * 1e-6, (n, 1, 1)))
    sol = solve_camera(cd, loo=False)
    dr, dt = pose_error(sol.T_cam_sonar, T)
    assert math.degrees(dr) < 0.2 and dt < 0.01 and sol.rms_px < 1.0


def test_camera_info_message_keeps_k4_to_k6():
    from types import SimpleNamespace

    from calib_core.ingest.rosmsg import camera_from_info

    msg = SimpleNamespace(k=K.ravel().tolist(), d=D8.tolist(), distortion_model="rational_polynomial",
                          width=1280, height=720)
    np.testing.assert_allclose(camera_from_info(msg, "rgb").dist, D8)
    msg.distortion_model = "plumb_bob"
    with pytest.raises(ValueError, match="k4..k6"):
        camera_from_info(msg, "rgb")
