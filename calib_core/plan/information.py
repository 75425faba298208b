"""Fisher information of sphere captures about one camera's pose, in the solver's own model.

The solver (:mod:`calib_core.solve.model`) whitens each capture's residual
``xy_meas - pi(R X + t)`` (normalised image coordinates) by

    S = A cov_uv A^T + J_X cov_X J_X^T,   A = (d uv / d xy)^-1,  J_X = d pi / d P . R

and perturbs the pose as ``R <- Exp(w) R``, ``t <- t + dt`` (rotation vector in the camera frame,
rad; translation m). A capture at sonar-frame centre X therefore adds ``D^T S^-1 D`` to the 6x6
information, with ``D = d pi / d P . [-[R X]x, I]`` (2x6): a rank-2 update. Adding it to a
covariance C is the Woodbury update ``C - C D^T (S + D C D^T)^-1 D C``; its log-det gain is
``log det(I + S^-1 D C D^T)`` (2x2). Everything here is batched over candidates.
The range scale is held at 1 (the planner plans the pose, not the scale).
"""

from __future__ import annotations

import numpy as np

from calib_core.camera import CameraModel, pi_jacobian
from calib_core.solve.model import MIN_DEPTH_M


def skew(v: np.ndarray) -> np.ndarray:
    """(N,3,3) cross-product matrices of (N,3) vectors."""
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def pose_jacobians(T_cam_sonar: np.ndarray, X_sonar_m: np.ndarray):
    """d xy / d (w, t) (N,2,6), d xy / d X_sonar (N,2,3) and camera-frame points (N,3)."""
    R, t = T_cam_sonar[:3, :3], T_cam_sonar[:3, 3]
    RX = np.asarray(X_sonar_m, float).reshape(-1, 3) @ R.T
    P = RX + t
    Pz = P.copy()
    Pz[:, 2] = np.maximum(P[:, 2], MIN_DEPTH_M)
    Jpi = pi_jacobian(Pz)
    dP = np.concatenate([-skew(RX), np.broadcast_to(np.eye(3), RX.shape[:1] + (3, 3))], axis=2)
    return Jpi @ dP, Jpi @ R, P


def measurement_cov(cam: CameraModel, P_cam_m: np.ndarray, J_X: np.ndarray, cov_uv_px2: np.ndarray,
                    cov_X_m2: np.ndarray) -> np.ndarray:
    """S (N,2,2) in normalised coordinates for captures at camera points ``P_cam_m`` (the solver's model)."""
    z = np.maximum(P_cam_m[:, 2], MIN_DEPTH_M)
    xy = P_cam_m[:, :2] / z[:, None]
    A = np.linalg.inv(cam.distort_jacobian(xy))
    S = A @ cov_uv_px2 @ np.swapaxes(A, 1, 2) + J_X @ cov_X_m2 @ np.swapaxes(J_X, 1, 2)
    return 0.5 * (S + np.swapaxes(S, 1, 2))


def capture_terms(cam: CameraModel, T_cam_sonar: np.ndarray, X_sonar_m, cov_uv_px2, cov_X_m2):
    """(D (N,2,6), S (N,2,2)) of captures at sonar-frame centres ``X_sonar_m``."""
    D, J_X, P = pose_jacobians(T_cam_sonar, X_sonar_m)
    n = len(P)
    cuv = np.broadcast_to(np.asarray(cov_uv_px2, float), (n, 2, 2))
    cX = np.broadcast_to(np.asarray(cov_X_m2, float), (n, 3, 3))
    return D, measurement_cov(cam, P, J_X, cuv, cX)


def information(D: np.ndarray, S: np.ndarray) -> np.ndarray:
    """6x6 sum of D^T S^-1 D over the captures."""
    if len(D) == 0:
        return np.zeros((6, 6))
    F = np.einsum("nki,nkl,nlj->ij", D, np.linalg.inv(S), D)
    return 0.5 * (F + F.T)


def updated_cov(C: np.ndarray, D: np.ndarray, S: np.ndarray) -> np.ndarray:
    """(N,6,6): the covariance C after adding each candidate alone (Woodbury, rank 2)."""
    CD = C @ np.swapaxes(D, 1, 2)  # (N,6,2)
    M = S + D @ CD  # (N,2,2)
    out = C[None] - CD @ np.linalg.solve(M, np.swapaxes(CD, 1, 2))
    return 0.5 * (out + np.swapaxes(out, 1, 2))


def logdet_gain(C: np.ndarray, D: np.ndarray, S: np.ndarray) -> np.ndarray:
    """(N,) log det(F + D^T S^-1 D) - log det F = log det(I + S^-1 D C D^T) (matrix determinant lemma)."""
    M = np.linalg.solve(S, D @ C @ np.swapaxes(D, 1, 2))
    sign, ld = np.linalg.slogdet(np.eye(D.shape[1])[None] + M)
    return np.where(sign > 0, ld, -np.inf)


def sigmas_deg_mm(cov6: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """1-sigma per axis (...,3) rotation (deg) and (...,3) translation (mm) of 6x6 covariances (...,6,6)."""
    d = np.sqrt(np.maximum(np.diagonal(cov6, axis1=-2, axis2=-1), 0.0))
    return np.degrees(d[..., :3]), 1000.0 * d[..., 3:]


def safe_inverse(F: np.ndarray) -> np.ndarray:
    """Covariance from a 6x6 information matrix; a huge (not infinite) variance where it is singular."""
    w, V = np.linalg.eigh(0.5 * (F + F.T))
    w = np.maximum(w, max(w.max(), 1.0) * 1e-14)
    C = (V / w) @ V.T
    return 0.5 * (C + C.T)
