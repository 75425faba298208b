"""Synthetic correspondences for the solver's tests and benchmark (no images, no clouds).

A rig like the paper's test frame: two cameras about 0.74 m apart on a bar, a sonar about
0.75 m above their midpoint, all looking forward, with random perturbations of every pose;
sphere centres spread over the cameras' common view at 1-3 m. Noise: Gaussian on the image
centres (px) and on the sonar centres (m, optionally larger across the beam than along it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_core.camera import CameraModel
from calib_core.geometry import invert_T, make_T, transform_points
from calib_core.solve.model import exp_so3

# Sonar frame axes (x forward, y left, z up) expressed in the rig frame (x right, y down, z forward).
_R_RIG_SONAR = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])


@dataclass
class SyntheticRig:
    """Ground truth and noisy measurements.

    Attributes:
        cameras: {name: CameraModel}.
        T_cam_sonar: {name: true 4x4}.
        T_cam2_cam1: true stereo transform (second camera from the first).
        X_true_sonar_m: (N,3) true centres in the (unscaled) sonar frame.
        scale: range scale (cloud = true * scale).
        capture_ids: ids.
        X_sonar_m, cov_X_m2: measured cloud-frame centres and their covariances.
        uv_px, cov_uv_px2: {cam: (N,2)} measured raw pixels and {cam: (N,2,2)} covariances.
        visible: {cam: (N,) bool} centre inside that camera's image.
    """

    cameras: dict
    T_cam_sonar: dict
    T_cam2_cam1: np.ndarray
    X_true_sonar_m: np.ndarray
    scale: float
    capture_ids: list
    X_sonar_m: np.ndarray
    cov_X_m2: np.ndarray
    uv_px: dict
    cov_uv_px2: dict
    visible: dict


def default_camera(name: str, rng: np.random.Generator | None = None) -> CameraModel:
    f = 1200.0 if rng is None else rng.uniform(1000, 1500)
    dist = [-0.12, 0.06, 0.0005, -0.0003, 0.0] if rng is None else [rng.uniform(-0.2, 0.0), rng.uniform(0, 0.1),
                                                                     rng.normal(0, 5e-4), rng.normal(0, 5e-4), 0.0]
    K = [[f, 0, 960 + (0 if rng is None else rng.normal(0, 10))], [0, f, 540 + (0 if rng is None else rng.normal(0, 10))],
         [0, 0, 1]]
    return CameraModel(1920, 1080, K, dist, name)


def sonar_cov(X_true_sonar_m: np.ndarray, sigma_m: float, cross_factor: float = 1.0) -> np.ndarray:
    """(N,3,3) covariances: sigma_m along the sonar ray, sigma_m * cross_factor across it."""
    n = len(X_true_sonar_m)
    u = X_true_sonar_m / np.linalg.norm(X_true_sonar_m, axis=1, keepdims=True)
    P = u[:, :, None] * u[:, None, :]
    return sigma_m**2 * (P + cross_factor**2 * (np.eye(3)[None] - P)).reshape(n, 3, 3)


def synthetic_rig(seed: int, n_captures: int = 9, sigma_px: float = 0.3, sigma_m: float = 0.003,
                  scale: float = 1.0, cross_factor: float = 1.0, depth_m=(1.0, 3.0),
                  random_intrinsics: bool = False) -> SyntheticRig:
    """Draw a two-camera rig, ``n_captures`` sphere positions visible to both cameras, and noise."""
    rng = np.random.default_rng(seed)
    small = lambda deg: exp_so3(rng.normal(0, np.radians(deg), 3))  # noqa: E731
    T_rig_cam1 = make_T(small(2.0), [-0.37 + rng.normal(0, 0.01), rng.normal(0, 0.01), 0.0])
    T_rig_cam2 = make_T(exp_so3([0, np.radians(-4.0), 0]) @ small(2.0), [0.37 + rng.normal(0, 0.01), rng.normal(0, 0.01), 0.0])
    T_rig_sonar = make_T(small(5.0) @ _R_RIG_SONAR, [rng.normal(0, 0.05), -0.75 + rng.normal(0, 0.03), rng.normal(0, 0.05)])
    cams = {n: default_camera(n, rng if random_intrinsics else None) for n in ("cam1", "cam2")}
    T = {"cam1": invert_T(T_rig_cam1) @ T_rig_sonar, "cam2": invert_T(T_rig_cam2) @ T_rig_sonar}
    pts = []
    while len(pts) < n_captures:
        z = rng.uniform(*depth_m)
        p_rig = np.array([rng.uniform(-0.55, 0.55) * z, rng.uniform(-0.3, 0.3) * z, z])
        X = transform_points(invert_T(T_rig_sonar), p_rig)[0]
        ok = all(cams[c].in_image(cams[c].project(transform_points(T[c], X)), margin_px=60)[0] for c in cams)
        if ok:
            pts.append(X)
    X_true = np.array(pts)
    cov_X = sonar_cov(X_true, sigma_m, cross_factor)
    X_meas = scale * X_true + np.stack([rng.multivariate_normal(np.zeros(3), C) for C in cov_X])
    uv, cuv, vis = {}, {}, {}
    for c, cam in cams.items():
        clean = cam.project(transform_points(T[c], X_true))
        uv[c] = clean + rng.normal(0, sigma_px, clean.shape)
        cuv[c] = np.repeat((sigma_px**2 * np.eye(2))[None], n_captures, axis=0)
        vis[c] = cam.in_image(clean)
    ids = [f"p{i + 1:02d}" for i in range(n_captures)]
    return SyntheticRig(cams, T, T["cam2"] @ invert_T(T["cam1"]), X_true, scale, ids, X_meas,
                        cov_X, uv, cuv, vis)


def wrong_centres(uv_px: np.ndarray, k: int, rng: np.random.Generator, lo_px: float = 30.0,
                  hi_px: float = 80.0) -> tuple[np.ndarray, np.ndarray]:
    """``uv_px`` with ``k`` rows moved ``lo_px``-``hi_px`` in random directions (a decoy found, a
    mislocated ball: tens of pixels off, where a sphere could be). Returns (uv, wrong rows)."""
    uv = np.asarray(uv_px, float).copy()
    bad = rng.choice(len(uv), k, replace=False)
    for i in bad:
        d = rng.normal(size=2)
        uv[i] += rng.uniform(lo_px, hi_px) * d / np.linalg.norm(d)
    return uv, np.sort(bad)
