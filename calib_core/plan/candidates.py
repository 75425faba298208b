"""Candidate sphere positions that the sonar and the cameras can see.

A candidate is a sonar-frame sphere centre on a regular (azimuth, elevation, range) grid over
the sonar field, kept when the whole sphere is inside the sonar field, its range is inside the
working range, it is at least ``min_camera_distance_m`` from every camera, its whole outline
(the tangent cone, 8 points) projects inside a camera's image with a pixel margin (widened by 3
sigma of where the current pose uncertainty may put it), and it is at least ``min_separation_m``
from every capture already taken.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_core.camera import CameraModel
from calib_core.plan.field import SonarField
from calib_core.plan.information import pose_jacobians


@dataclass(frozen=True)
class Limits:
    """Where the operator can put the sphere: sphere-centre range from the sonar (m), nearest
    distance to a camera (m), image margin (px), and spacing from captures already taken (m)."""

    working_range_m: tuple[float, float] = (1.0, 4.0)
    min_camera_distance_m: float = 0.6
    margin_px: float = 10.0
    min_separation_m: float = 0.25

    def text(self) -> str:
        a, b = self.working_range_m
        return (f"working range {a:g}-{b:g} m from the sonar, >= {self.min_camera_distance_m:g} m from each camera, "
                f">= {self.min_separation_m:g} m from captures taken")


def outline_visible(cam: CameraModel, P_cam_m: np.ndarray, radius_m: float, margin_px,
                    n: int = 8) -> np.ndarray:
    """(N,) the whole outline of spheres centred at camera points ``P_cam_m`` inside the image,
    ``margin_px`` (scalar or (N,)) from its border."""
    P = np.asarray(P_cam_m, float).reshape(-1, 3)
    d = np.linalg.norm(P, axis=1)
    ok = d > radius_m * 1.01
    w = P / np.maximum(d, 1e-12)[:, None]
    a = np.arcsin(np.clip(radius_m / np.maximum(d, 1e-12), 0, 1))
    ref = np.where(np.abs(w[:, 1:2]) < 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    e1 = np.cross(w, ref)
    e1 /= np.maximum(np.linalg.norm(e1, axis=1, keepdims=True), 1e-12)
    e2 = np.cross(w, e1)
    phi = np.linspace(0, 2 * np.pi, n, endpoint=False)
    v = (np.cos(a)[:, None, None] * w[:, None] + np.sin(a)[:, None, None]
         * (np.cos(phi)[None, :, None] * e1[:, None] + np.sin(phi)[None, :, None] * e2[:, None]))
    front = (v[..., 2] > 1e-3).all(axis=1)
    m = np.broadcast_to(np.asarray(margin_px, float), (len(P),))[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        uv = cam.project(v.reshape(-1, 3)).reshape(len(P), n, 2)
        inside = ((uv[..., 0] >= -0.5 + m) & (uv[..., 0] <= cam.width_px - 0.5 - m)
                  & (uv[..., 1] >= -0.5 + m) & (uv[..., 1] <= cam.height_px - 0.5 - m)).all(axis=1)
    return ok & front & inside & np.isfinite(uv).all(axis=(1, 2))


def pose_margin_px(cam: CameraModel, T_cam_sonar: np.ndarray, X_sonar_m: np.ndarray, cov6: np.ndarray,
                   k_sigma: float = 3.0) -> np.ndarray:
    """(N,) ``k_sigma`` x the largest 1-sigma (px) of where a sonar-frame point will appear, from the
    pose covariance: a suggestion must stay in view wherever the true pose turns out to be."""
    D, _, P = pose_jacobians(T_cam_sonar, X_sonar_m)
    z = np.maximum(P[:, 2], 1e-3)
    Jpx = cam.distort_jacobian(P[:, :2] / z[:, None]) @ D
    C = Jpx @ cov6 @ np.swapaxes(Jpx, 1, 2)
    return k_sigma * np.sqrt(np.maximum(np.linalg.eigvalsh(C)[:, -1], 0.0))


def visibility(cameras: dict, X_sonar_m: np.ndarray, radius_m: float, limits: Limits,
               pose_cov: dict | None = None) -> np.ndarray:
    """(N, n_cameras) bool: each camera sees the whole sphere (``cameras[name] = (model, T_cam_sonar)``),
    with the image margin widened by :func:`pose_margin_px` for cameras in ``pose_cov`` ({name: 6x6})."""
    X = np.asarray(X_sonar_m, float).reshape(-1, 3)
    cols = []
    for name, (cam, T) in cameras.items():
        P = X @ T[:3, :3].T + T[:3, 3]
        far = np.linalg.norm(P, axis=1) >= limits.min_camera_distance_m
        margin = limits.margin_px
        if pose_cov and name in pose_cov and len(X):
            margin = margin + pose_margin_px(cam, T, X, pose_cov[name])
        cols.append(far & outline_visible(cam, P, radius_m, margin))
    return np.stack(cols, axis=1) if cols else np.zeros((len(X), 0), bool)


def far_from(X_sonar_m: np.ndarray, taken_sonar_m: np.ndarray, min_separation_m: float) -> np.ndarray:
    """(N,) at least ``min_separation_m`` from every taken centre."""
    T = np.asarray(taken_sonar_m, float).reshape(-1, 3)
    if len(T) == 0:
        return np.ones(len(X_sonar_m), bool)
    d = np.linalg.norm(np.asarray(X_sonar_m)[:, None, :] - T[None], axis=2)
    return d.min(axis=1) >= min_separation_m


def grid_points(field: SonarField, limits: Limits, n_az: int = 17, n_el: int = 13, n_range: int = 10) -> np.ndarray:
    """Regular (azimuth, elevation, range) grid over the field within the working range (N,3)."""
    r0 = max(field.range_m[0], limits.working_range_m[0])
    r1 = min(field.range_m[1], limits.working_range_m[1])
    if r1 <= r0:
        return np.zeros((0, 3))
    az = np.linspace(*field.azimuth_deg, n_az + 2)[1:-1]
    el = np.linspace(*field.elevation_deg, n_el + 2)[1:-1]
    rr = np.linspace(r0, r1, n_range)
    A, E, Rr = np.meshgrid(az, el, rr, indexing="ij")
    return field.to_sonar(A.ravel(), E.ravel(), Rr.ravel())


@dataclass
class Candidates:
    """Sonar-frame centres (N,3) and which cameras see each (N, n_cameras)."""

    X_sonar_m: np.ndarray
    visible: np.ndarray


def candidates(cameras: dict, field: SonarField, radius_m: float, limits: Limits, taken_sonar_m=None,
               points: np.ndarray | None = None, pose_cov: dict | None = None) -> Candidates:
    """Filter ``points`` (default: :func:`grid_points`) to the positions both sensors can see
    (``pose_cov``: see :func:`visibility`)."""
    X = grid_points(field, limits) if points is None else np.asarray(points, float).reshape(-1, 3)
    r = np.linalg.norm(X, axis=1)
    keep = field.contains(X, radius_m) & (r >= limits.working_range_m[0]) & (r <= limits.working_range_m[1])
    if taken_sonar_m is not None:
        keep &= far_from(X, taken_sonar_m, limits.min_separation_m)
    X = X[keep]
    vis = visibility(cameras, X, radius_m, limits, pose_cov)
    seen = vis.any(axis=1)
    return Candidates(X[seen], vis[seen])
