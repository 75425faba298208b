"""CameraModel (the paper's eqs. 1-9) against OpenCV and numeric differentiation."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from calib_core.camera import CameraModel, pi_jacobian

K_HD = np.array([[1000.0, 0, 955.3], [0, 1003.0, 541.7], [0, 0, 1]])
CASES = {
    "none": (K_HD, np.zeros(5)),
    "mild": (K_HD, np.array([-0.12, 0.05, 0.0008, -0.0005, -0.01])),
    "tangential": (K_HD, np.array([0.02, -0.01, 0.004, -0.003, 0.0])),
    "pincushion": (K_HD, np.array([0.15, 0.05, 0.0, 0.0, 0.01])),
    # wide lens, strong barrel: corners sit close to the fold of the radial polynomial
    "strong": (np.array([[900.0, 0, 960], [0, 900, 540], [0, 0, 1]]), np.array([-0.25, 0.08, 0.0005, -0.0003, -0.01])),
}


def cam_of(case: str) -> CameraModel:
    K, d = CASES[case]
    return CameraModel(1920, 1080, K, d, name=case)


def image_grid(cam: CameraModel, nu=60, nv=34) -> np.ndarray:
    """Pixels covering the whole image, corners included (pixel-centre convention: -0.5 .. W-0.5)."""
    u, v = np.meshgrid(np.linspace(-0.5, cam.width_px - 0.5, nu), np.linspace(-0.5, cam.height_px - 0.5, nv))
    return np.column_stack([u.ravel(), v.ravel()])


def random_points_in_view(cam: CameraModel, n=500, seed=0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    uv = rng.uniform([0, 0], [cam.width_px, cam.height_px], size=(n, 2))
    xy = cam.normalize(uv)
    z = rng.uniform(0.3, 8.0, n)
    return np.column_stack([xy * z[:, None], z])


@pytest.mark.parametrize("case", list(CASES))
def test_project_matches_opencv(case):
    cam = cam_of(case)
    X = random_points_in_view(cam, seed=1)
    rvec, tvec = np.zeros(3), np.zeros(3)
    uv_cv, _ = cv2.projectPoints(X.reshape(-1, 1, 3), rvec, tvec, cam.K, cam.dist)
    np.testing.assert_allclose(cam.project(X), uv_cv.reshape(-1, 2), atol=1e-8)
    xy = X[:, :2] / X[:, 2:]
    np.testing.assert_allclose(cam.distort(xy), uv_cv.reshape(-1, 2), atol=1e-8)


def test_project_with_skew_matches_opencv():
    K = K_HD.copy()
    K[0, 1] = 2.5
    cam = CameraModel(1920, 1080, K, CASES["mild"][1])
    X = random_points_in_view(cam, seed=2)
    # cv2.projectPoints ignores the skew term: distort with K = I there, then apply the full K
    xyd, _ = cv2.projectPoints(X.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), np.eye(3), cam.dist)
    ref = (np.column_stack([xyd.reshape(-1, 2), np.ones(len(X))]) @ K.T)[:, :2]
    np.testing.assert_allclose(cam.project(X), ref, atol=1e-8)
    np.testing.assert_allclose(cam.distort(cam.normalize(cam.project(X))), cam.project(X), atol=1e-6)


def test_points_behind_the_camera_give_nan():
    cam = cam_of("mild")
    uv = cam.project(np.array([[0.1, 0.2, -1.0], [0.0, 0.0, 0.0], [0.1, 0.1, 2.0]]))
    assert np.isnan(uv[:2]).all() and np.isfinite(uv[2]).all()


@pytest.mark.parametrize("case", ["none", "mild", "tangential", "pincushion"])
def test_normalize_matches_opencv_undistort(case):
    cam = cam_of(case)
    uv = image_grid(cam, 30, 17)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-14)
    ref = cv2.undistortPoints(uv.reshape(-1, 1, 2), cam.K, cam.dist, None, None, None, crit).reshape(-1, 2)
    # OpenCV's fixed-point iteration is itself approximate: compare in pixels, loosely
    np.testing.assert_allclose(cam.distort(cam.normalize(uv)), uv, atol=1e-6)
    assert np.max(np.abs(cam.normalize(uv) - ref)) * cam.fx < 0.05


@pytest.mark.parametrize("case", list(CASES))
def test_round_trip_below_1e6_px_everywhere_including_corners(case):
    cam = cam_of(case)
    uv = image_grid(cam)
    xy = cam.normalize(uv)
    assert np.isfinite(xy).all(), "every pixel of the image must have a viewing ray"
    err = np.abs(cam.distort(xy) - uv).max()
    assert err < 1e-6, f"round trip error {err} px"
    # the other direction: normalise(project(X)) gives back X's direction
    X = random_points_in_view(cam, seed=3)
    np.testing.assert_allclose(cam.normalize(cam.project(X)), X[:, :2] / X[:, 2:], atol=1e-9)


def test_strong_distortion_corner_is_on_the_monotonic_branch():
    cam = cam_of("strong")
    corner = np.array([[-0.5, -0.5], [1919.5, 1079.5]])
    xy = cam.normalize(corner)
    J = cam.distort_jacobian(xy)
    assert (np.linalg.det(J) > 0).all()
    # the radial profile r_d(r) is still increasing there
    r = np.linalg.norm(xy, axis=1)
    k1, k2, _, _, k3 = cam.dist
    assert (1 + 3 * k1 * r**2 + 5 * k2 * r**4 + 7 * k3 * r**6 > 0).all()


def test_unreachable_pixels_and_nan_give_nan_not_garbage():
    # this barrel distortion folds back before the image corner: no ray maps there
    cam = CameraModel(1920, 1080, [[1000, 0, 960], [0, 1000, 540], [0, 0, 1]], [-0.3, 0.1, 0.001, -0.001, -0.02])
    xy = cam.normalize(np.array([[0.0, 0.0], [960.0, 540.0], [np.nan, 3.0], [1300.0, 700.0]]))
    assert np.isnan(xy[0]).all() and np.isnan(xy[2]).all()
    assert np.isfinite(xy[[1, 3]]).all()
    np.testing.assert_allclose(cam.distort(xy[[1, 3]]), [[960, 540], [1300, 700]], atol=1e-6)
    assert cam.normalize(np.zeros((0, 2))).shape == (0, 2)


def test_rays_are_unit_and_point_through_the_pixel():
    cam = cam_of("mild")
    uv = image_grid(cam, 8, 5)
    d = cam.rays(uv)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
    assert (d[:, 2] > 0).all()
    np.testing.assert_allclose(cam.project(d * 3.7), uv, atol=1e-6)


def _numeric_jacobian(f, x, eps=1e-6):
    """Central differences of f: R^n -> R^m at each row of x; returns (N, m, n)."""
    x = np.asarray(x, float)
    cols = []
    for k in range(x.shape[1]):
        dx = np.zeros_like(x)
        dx[:, k] = eps
        cols.append((f(x + dx) - f(x - dx)) / (2 * eps))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("case", list(CASES))
def test_distort_jacobian_matches_numeric(case):
    cam = cam_of(case)
    xy = cam.normalize(image_grid(cam, 12, 7))
    J = cam.distort_jacobian(xy)
    Jn = _numeric_jacobian(cam.distort, xy)
    np.testing.assert_allclose(J, Jn, rtol=1e-6, atol=1e-4)


def test_distort_jacobian_with_skew():
    K = K_HD.copy()
    K[0, 1] = 3.0
    cam = CameraModel(1920, 1080, K, CASES["tangential"][1])
    xy = np.random.default_rng(4).uniform(-0.8, 0.8, (50, 2))
    np.testing.assert_allclose(cam.distort_jacobian(xy), _numeric_jacobian(cam.distort, xy), rtol=1e-6, atol=1e-4)


@pytest.mark.parametrize("case", list(CASES))
def test_project_jacobian_matches_numeric(case):
    cam = cam_of(case)
    X = random_points_in_view(cam, n=60, seed=5)
    J = cam.project_jacobian(X)
    assert J.shape == (60, 2, 3)
    np.testing.assert_allclose(J, _numeric_jacobian(cam.project, X, eps=1e-7), rtol=1e-5, atol=1e-3)


def test_pi_jacobian_matches_numeric():
    X = np.random.default_rng(6).uniform([-2, -2, 0.2], [2, 2, 6], (40, 3))
    pi = lambda P: P[:, :2] / P[:, 2:3]  # noqa: E731
    np.testing.assert_allclose(pi_jacobian(X), _numeric_jacobian(pi, X, eps=1e-7), rtol=1e-6, atol=1e-6)


def test_project_jacobian_agrees_with_opencv_chain():
    # OpenCV's projectPoints Jacobian w.r.t. tvec equals d uv / d X for R = I, t = 0
    cam = cam_of("mild")
    X = random_points_in_view(cam, n=20, seed=7)
    for i, P in enumerate(X):
        _, jac = cv2.projectPoints(np.zeros((1, 1, 3)), np.zeros(3), P.copy(), cam.K, cam.dist)
        np.testing.assert_allclose(cam.project_jacobian(P[None])[0], jac[:, 3:6], rtol=1e-6, atol=1e-6)


def test_constructor_pads_distortion_and_properties():
    cam = CameraModel(640, 480, np.eye(3) * [500, 510, 1] + [[0, 0, 320], [0, 0, 240], [0, 0, 0]], [0.1, -0.2, 0.0, 0.0])
    assert cam.dist.shape == (5,) and cam.dist[4] == 0.0
    assert (cam.fx, cam.fy, cam.cx, cam.cy) == (500.0, 510.0, 320.0, 240.0)


def test_in_image_mask():
    cam = CameraModel(100, 50, [[80, 0, 49.5], [0, 80, 24.5], [0, 0, 1]])
    uv = np.array([[-0.5, -0.5], [99.5, 49.5], [-0.6, 10], [10, 49.6], [np.nan, 1], [50, 25]])
    assert cam.in_image(uv).tolist() == [True, True, False, False, False, True]
    assert cam.in_image(uv, margin_px=2).tolist() == [False, False, False, False, False, True]
