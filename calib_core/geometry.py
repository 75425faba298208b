"""Rigid transforms ``T_target_source`` (4x4, maps points in source to target).

Rotation vectors are axis * angle in radians (OpenCV / scipy convention).
"""

from __future__ import annotations

import math

import numpy as np


def make_T(R: np.ndarray, t_m: np.ndarray) -> np.ndarray:
    """4x4 transform from a 3x3 rotation and a translation in metres."""
    T = np.eye(4)
    T[:3, :3] = np.asarray(R, dtype=float)
    T[:3, 3] = np.asarray(t_m, dtype=float).reshape(3)
    return T


def exp_so3(omega_rad: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (rad) (Rodrigues' formula; series near 0)."""
    w = np.asarray(omega_rad, float).reshape(3)
    th2 = float(w @ w)
    Wx = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    if th2 < 1e-12:
        a, b = 1.0 - th2 / 6.0, 0.5 - th2 / 24.0
    else:
        th = math.sqrt(th2)
        a, b = math.sin(th) / th, (1.0 - math.cos(th)) / th2
    return np.eye(3) + a * Wx + b * (Wx @ Wx)


def T_from_rotvec(rotvec_rad: np.ndarray, t_m: np.ndarray) -> np.ndarray:
    """4x4 transform from a rotation vector (rad) and a translation (m)."""
    return make_T(exp_so3(rotvec_rad), t_m)


def rotvec_from_T(T: np.ndarray) -> np.ndarray:
    """Rotation vector (rad) of the rotation part of T."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(np.asarray(T, float)[:3, :3]).as_rotvec()


def invert_T(T_a_b: np.ndarray) -> np.ndarray:
    """Return T_b_a for a rigid T_a_b."""
    R = T_a_b[:3, :3]
    t = T_a_b[:3, 3]
    return make_T(R.T, -R.T @ t)


def transform_points(T_a_b: np.ndarray, points_b: np.ndarray) -> np.ndarray:
    """Map (N,3) points from frame b to frame a."""
    P = np.asarray(points_b, dtype=float).reshape(-1, 3)
    return P @ T_a_b[:3, :3].T + T_a_b[:3, 3]


def rotation_angle_rad(R: np.ndarray) -> float:
    """Angle (rad) of a rotation matrix, in [0, pi]."""
    c = (np.trace(np.asarray(R, float)[:3, :3]) - 1.0) / 2.0
    return float(np.arccos(np.clip(c, -1.0, 1.0)))


def pose_error(T_est: np.ndarray, T_true: np.ndarray) -> tuple[float, float]:
    """(rotation error in rad, translation error in m) between two T_a_b."""
    dR = T_est[:3, :3] @ T_true[:3, :3].T
    return rotation_angle_rad(dR), float(np.linalg.norm(T_est[:3, 3] - T_true[:3, 3]))


def look_at_T_cam_world(eye_world_m, target_world_m, up_world=(0.0, 0.0, 1.0)) -> np.ndarray:
    """T_cam_world for an OpenCV camera (z forward, y down) at eye looking at target."""
    eye = np.asarray(eye_world_m, float)
    z = np.asarray(target_world_m, float) - eye
    z /= np.linalg.norm(z)
    up = np.asarray(up_world, float)
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-9:  # looking along up: pick any perpendicular
        x = np.cross(z, [1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R_world_cam = np.column_stack([x, y, z])
    return invert_T(make_T(R_world_cam, eye))


def is_rigid(T: np.ndarray, atol: float = 1e-5) -> bool:
    """True when the finite 4x4 ``T`` is a rigid transform: an orthonormal, right-handed rotation
    and a last row of 0 0 0 1. Huge entries (1e308) overflow R R^T: not rigid, and no numpy warning."""
    T = np.asarray(T, dtype=float)
    R = T[:3, :3]
    with np.errstate(all="ignore"):
        return bool(np.allclose(R @ R.T, np.eye(3), atol=atol) and np.linalg.det(R) > 0
                    and np.allclose(T[3], [0, 0, 0, 1]))
