"""A ball and its copy in a plane mirror seen at an angle (a glass wall receding from the camera):
the copy shows another side of the ball, so the first-order flip of the disc does not match it;
the exact reflection through the plane bisecting the two 3D centres does
(calib_core.detect.image.mirror.exact_samples). A twin ball (the same print, the same way up,
under the same light) stays "two round objects"."""

from __future__ import annotations

import numpy as np

from calib_core.camera import CameraModel
from calib_core.detect.image.detect import detect_sphere_in_image

R_M = 0.11
C_BALL = np.array([-0.25, 0.0, 1.5])  # camera frame, m
N_MIRROR = np.array([0.78, 0.0, 0.62]) / np.linalg.norm([0.78, 0.0, 0.62])  # the wall's normal, oblique
GAP_M = 0.25  # the ball's centre to the mirror plane
C_FAR = C_BALL + 2 * GAP_M * N_MIRROR  # the virtual ball (or the twin)
LIGHT = np.array([-0.5, -0.7, -0.5]) / np.linalg.norm([-0.5, -0.7, -0.5])  # towards the light
SPOTS = np.array([[0.3, -0.5, -0.8], [0.9, 0.2, -0.4], [-0.2, 0.6, -0.77], [0.5, 0.5, 0.7], [-0.9, -0.1, -0.4]])


def _camera() -> CameraModel:
    return CameraModel(960, 540, np.array([[600.0, 0, 480.0], [0, 600.0, 270.0], [0, 0, 1]]), np.zeros(5))


def _albedo(normals: np.ndarray) -> np.ndarray:
    """An orange float's print: dark spots of different sizes at fixed directions (asymmetric)."""
    s = SPOTS / np.linalg.norm(SPOTS, axis=1, keepdims=True)
    dark = np.max(np.exp(-(1 - normals @ s.T) / np.array([0.05, 0.03, 0.08, 0.04, 0.06])), axis=1)
    return np.array([230.0, 120.0, 30.0])[None, :] * (1 - 0.8 * dark)[:, None]


def _hit(rays: np.ndarray, centre: np.ndarray) -> np.ndarray:
    b = rays @ centre
    disc = b * b - (centre @ centre - R_M ** 2)
    with np.errstate(invalid="ignore"):
        return np.where(disc >= 0, b - np.sqrt(disc), np.inf)


def _render(mirror: bool) -> np.ndarray:
    """The ball at C_BALL and, at C_FAR, its mirror copy (mirror=True: each pixel shows the
    reflected real surface point, 0.85 as bright) or a twin (the same print, not reflected)."""
    cam = _camera()
    ss = 3
    ys, xs = np.mgrid[0:540 * ss, 0:960 * ss]
    uv = np.column_stack([(xs.ravel() + 0.5) / ss - 0.5, (ys.ravel() + 0.5) / ss - 0.5])
    rays = cam.rays(uv)
    t_a, t_b = _hit(rays, C_BALL), _hit(rays, C_FAR)
    col = np.tile(np.array([40.0, 95.0, 110.0]), (len(rays), 1)) + 25.0 * (uv[:, 1:] / 540.0)
    for on, t, centre, gain in ((t_b < t_a, t_b, C_FAR, 0.85 if mirror else 1.0), (t_a < t_b, t_a, C_BALL, 1.0)):
        n = rays[on] * t[on, None] - centre
        n /= R_M
        if mirror and centre is C_FAR:  # the real surface point this pixel sees through the mirror
            n = n - 2 * (n @ N_MIRROR)[:, None] * N_MIRROR[None, :]
        col[on] = gain * _albedo(n) * (0.25 + 0.75 * np.clip(n @ LIGHT, 0, 1))[:, None]
    img = col.reshape(540, ss, 960, ss, 3).mean(axis=(1, 3))
    rng = np.random.default_rng(3)
    return np.clip(img + rng.normal(0, 2.0, img.shape), 0, 255).astype(np.uint8)


def test_a_copy_in_an_oblique_mirror_is_set_aside_and_named():
    cam = _camera()
    det = detect_sphere_in_image(_render(mirror=True), cam, R_M)
    assert det.found, det.reason
    assert np.hypot(*(det.center_uv_px - cam.project(C_BALL[None])[0])) < 0.5
    assert np.hypot(*(np.asarray(det.extras["mirror_copy_uv_px"]) - cam.project(C_FAR[None])[0])) < 2.0
    assert det.extras["mirror_evidence"]["flip_corr"] >= det.extras["mirror_evidence"]["direct_corr"] + 0.1


def test_a_twin_ball_stays_two_round_objects():
    det = detect_sphere_in_image(_render(mirror=False), _camera(), R_M)
    assert not det.found and det.reason.startswith("two round objects: ("), det.reason
