"""OpenCV's fisheye (ROS / Kalibr ``equidistant``) lens model: projection, its inverse and
Jacobian, the intrinsics files and bag messages that carry it, the fused cloud, Kalibr export,
and the image detector on a wide-angle render."""

from __future__ import annotations

from types import SimpleNamespace

import cv2
import numpy as np
import pytest
import yaml

from calib_core.camera import CameraModel, distortion_terms
from calib_core.errors import SessionError
from calib_core.io.intrinsics import load_intrinsics, save_intrinsics_ros

K = np.array([[420.0, 0, 640.0], [0, 421.0, 512.0], [0, 0, 1]])
D4 = np.array([0.06, -0.025, 0.004, -0.0006])


def _cam(dist=D4):
    return CameraModel(1280, 1024, K, dist, name="fe", fisheye=True)


def test_forward_matches_opencv_fisheye_and_inverse_round_trips():
    cam = _cam()
    rng = np.random.default_rng(0)
    xy = np.vstack([[0.0, 0.0], [1e-8, -1e-8], rng.uniform(-2.0, 2.0, (500, 2))])
    uv = cam.distort(xy)
    ref = cv2.fisheye.distortPoints(xy.reshape(-1, 1, 2), K, D4).reshape(-1, 2)
    assert np.abs(uv - ref).max() < 1e-8
    back = cam.normalize(uv)
    assert np.isfinite(back).all()
    assert np.abs(back - xy).max() < 1e-9
    assert cam.distortion_model == "equidistant" and not cam.rational
    assert distortion_terms(cam) == "equidistant k1 k2 k3 k4"


def test_jacobian_matches_finite_differences():
    cam = _cam()
    xy = np.random.default_rng(1).uniform(-1.5, 1.5, (300, 2))
    xy[0] = 0.0
    h = 1e-6
    num = np.stack([(cam.distort(xy + [h, 0]) - cam.distort(xy - [h, 0])) / (2 * h),
                    (cam.distort(xy + [0, h]) - cam.distort(xy - [0, h])) / (2 * h)], axis=2)
    J = cam.distort_jacobian(xy)
    assert np.abs(J - num).max() < 1e-6 * np.abs(J).max()


def test_zero_coefficients_are_still_equidistant_not_pinhole():
    cam = _cam(np.zeros(4))
    uv = cam.project(np.array([[1.0, 0.0, 1.0]]))[0]  # 45 deg off the axis
    assert uv[0] == pytest.approx(640.0 + 420.0 * np.pi / 4, abs=1e-9)  # r_d = f theta, not f tan(theta)


def test_ros_equidistant_file_loads_and_round_trips(tmp_path):
    p = tmp_path / "cam1.yaml"
    p.write_text(yaml.safe_dump({
        "image_width": 1280, "image_height": 1024, "camera_name": "cam1",
        "camera_matrix": {"rows": 3, "cols": 3, "data": K.ravel().tolist()},
        "distortion_model": "equidistant",
        "distortion_coefficients": {"rows": 1, "cols": 4, "data": D4.tolist()}}))
    cam = load_intrinsics(p)
    assert cam.fisheye and np.allclose(cam.dist, D4)
    out = tmp_path / "again.yaml"
    save_intrinsics_ros(out, cam)
    assert yaml.safe_load(out.read_text())["distortion_model"] == "equidistant"
    again = load_intrinsics(out)
    assert again.fisheye and np.allclose(again.dist, D4) and np.allclose(again.K, K)


def test_equidistant_with_a_fifth_coefficient_is_refused(tmp_path):
    p = tmp_path / "cam1.yaml"
    p.write_text(yaml.safe_dump({
        "image_width": 1280, "image_height": 1024,
        "camera_matrix": {"rows": 3, "cols": 3, "data": K.ravel().tolist()},
        "distortion_model": "equidistant",
        "distortion_coefficients": {"rows": 1, "cols": 5, "data": D4.tolist() + [0.01]}}))
    with pytest.raises(SessionError, match="equidistant .*4 coefficients"):
        load_intrinsics(p)


def test_camera_info_message_equidistant():
    from calib_core.ingest.rosmsg import camera_from_info

    msg = SimpleNamespace(k=K.ravel(), d=D4, distortion_model="equidistant", width=1280, height=1024)
    cam = camera_from_info(msg, "cam1")
    assert cam.fisheye and np.allclose(cam.dist, D4)
    with pytest.raises(ValueError, match="4 coefficients"):
        camera_from_info(SimpleNamespace(k=K.ravel(), d=np.r_[D4, 0.2], distortion_model="equidistant",
                                         width=1280, height=1024), "cam1")


@pytest.mark.parametrize("model,d,match", [
    ("equidistant", [0.1, float("nan"), 0, 0], "NaN or infinite"),   # was: "has 4 coefficients, got 4"
    ("plumb_bob", [0.1, 0, 0, 0, float("inf")], "NaN or infinite"),  # was: accepted, NaN pixels later
    ("rational_polynomial", list(range(1, 9)) + [0, 0, 0, 0.5], "8 coefficients, but 12"),  # was: 9-12 dropped
    ("plumb_bob", [0.1, 0, 0, 0, 0, 0.2], "k4..k6"),
])
def test_camera_info_message_bad_coefficients(model, d, match):
    from calib_core.ingest.rosmsg import camera_from_info

    with pytest.raises(ValueError, match=match):
        camera_from_info(SimpleNamespace(k=K.ravel(), d=np.array(d, float), distortion_model=model,
                                         width=1280, height=1024), "cam1")


def test_fused_cloud_projection_matches_the_model():
    from calib_core.fusion.cloud import _project

    cam = _cam()
    rng = np.random.default_rng(2)
    pts = np.column_stack([rng.uniform(-3, 3, 2000), rng.uniform(-2.5, 2.5, 2000), rng.uniform(0.5, 4, 2000)])
    u, v, z, valid, _, _ = _project(pts, np.eye(4), cam)[:6]
    ref = cam.project(pts)
    assert valid.sum() > 500
    err = np.hypot(u[valid] - ref[valid, 0], v[valid] - ref[valid, 1])
    assert err.max() < 0.02  # float32
    assert cam.in_image(ref[valid]).all()


def test_kalibr_export_writes_equidistant():
    from calib_core.export import to_kalibr

    calib = {"cameras": {"cam1": {"T_cam_sonar": np.eye(4).tolist()}}}
    out = yaml.safe_load(to_kalibr(calib, {"cam1": _cam()}))
    assert out["cam0"]["distortion_model"] == "equidistant"
    assert np.allclose(out["cam0"]["distortion_coeffs"], D4)


def test_detector_finds_a_sphere_near_the_corner_of_a_wide_angle_render():
    """A 0.15 m sphere seen 55-60 deg off the axis of a ~150 deg fisheye: strongly squashed,
    and still found within 0.5 px of its true centre's projection with the right range."""
    from calib_core.detect.image.detect import detect_sphere_in_image
    from calib_core.synth import world
    from calib_core.synth.camera_render import RenderOptions, finish_image, render_radiance
    from calib_core.synth.scene import Scene

    cam = CameraModel(640, 512, [[210.0, 0, 320.0], [0, 210.0, 256.0], [0, 0, 1]], D4, fisheye=True)
    rng = np.random.default_rng(7)
    water = world.sample_water(rng, False)
    radius = 0.15
    opts = RenderOptions(aa=4, blur_sigma_px=0.5, noise_dn=1.5, shot_gain=0.1)
    T_world_cam = np.eye(4)
    found = 0
    for C in (np.array([1.3, 0.7, 1.0]), np.array([-0.5, -0.3, 1.6])):
        style = world.sample_target_style(rng, radius)
        L, _ = render_radiance(Scene((world.target(style, C, radius, False),)), cam, T_world_cam, water, aa=4)
        img = finish_image(L, opts, rng)
        det = detect_sphere_in_image(img, cam, radius)
        assert det.found, det.reason
        truth = cam.project(C[None])[0]
        assert np.linalg.norm(det.center_uv_px - truth) < 0.5
        assert det.range_m == pytest.approx(float(np.linalg.norm(C)), rel=0.03)
        found += 1
    assert found == 2


def test_vertical_field_of_view_for_any_lens():
    from calib_core.camera import vertical_fov_rad

    pin = CameraModel(1920, 1080, [[1000.0, 0, 960], [0, 1000.0, 540], [0, 0, 1]])
    assert vertical_fov_rad(pin) == pytest.approx(2 * np.arctan(540 / 1000), abs=1e-3)
    fe = CameraModel(1920, 1080, [[500.0, 0, 960], [0, 500.0, 540], [0, 0, 1]], np.zeros(4), fisheye=True)
    assert vertical_fov_rad(fe) == pytest.approx(1080 / 500, abs=1e-3)  # r_d = f theta: 124 deg, not 94


def test_camera_info_export_names_the_lens_model_it_writes():
    """The header comment said plumb_bob above an equidistant (or rational) model."""
    from calib_core.export import to_camera_info

    text = to_camera_info(_cam(), "cam1")
    assert yaml.safe_load(text)["distortion_model"] == "equidistant"
    assert "plumb_bob" not in text and "Distortion equidistant" in text


@pytest.mark.parametrize("flag,n", [(1, 4), (0, 4), (1, 5)])
def test_opencv_filestorage_fisheye_model_flag(tmp_path, flag, n):
    """OpenCV's calibration sample writes ``fisheye_model: 1`` above cv::fisheye's 4 coefficients:
    they were read as plumb_bob (k1, k2, p1, p2)."""
    p = tmp_path / "out_camera_data.yml"
    fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 1280)
    fs.write("image_height", 1024)
    fs.write("fisheye_model", flag)
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", np.r_[D4, [0.0] * (n - 4)].reshape(-1, 1))
    fs.release()
    if n != 4 and flag:
        with pytest.raises(SessionError, match="fisheye_model: 1 .* 4 distortion values, got 5"):
            load_intrinsics(p)
        return
    cam = load_intrinsics(p)
    assert cam.fisheye == bool(flag) and np.allclose(cam.dist[:4], D4)


def test_vertical_field_of_view_past_180_deg():
    from calib_core.camera import vertical_fov_rad

    fe = CameraModel(1000, 1000, [[250.0, 0, 500], [0, 250.0, 500], [0, 0, 1]], np.zeros(4), fisheye=True)
    assert vertical_fov_rad(fe) == pytest.approx(1000 / 250, abs=1e-3)  # 229 deg, not 360 - 229
