"""Observation model of the solvers: sonar sphere centres -> normalised image coordinates.

The measurement of one capture by camera c is the paper's eq. 15 residual
``P-hat^-1(x_C) - pi(R_c X_S / s + t_c)`` in normalised (undistorted, z=1) coordinates,
where ``s`` is the sonar range scale (cloud range = true range * s, about the sonar
origin, so ``X_true = X_cloud / s``). Its covariance is

    S = A cov_uv A^T  (+ the same for every other camera seeing the capture, block-diagonal)
        + J cov_X J^T  (sonar centre covariance through the projection; J stacks all cameras)

with ``A = (d uv / d xy)^-1``. Stacking the cameras of one capture in one block keeps the
sonar noise shared by cam1 and cam2 correlated, which is what maximum likelihood needs
(treating them apart would count the sonar centre twice).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from calib_core.camera import CameraModel, pi_jacobian
from calib_core.errors import SessionError
from calib_core.geometry import exp_so3  # noqa: F401  (the solvers' rotation exponential)

MIN_DEPTH_M = 1e-3  # points nearer than this to the camera plane are treated as behind it


def log_so3(R: np.ndarray) -> np.ndarray:
    """Rotation vector (rad) of a rotation matrix (closed form; scipy near 180 deg)."""
    R = np.asarray(R, float)[:3, :3]
    c = min(1.0, max(-1.0, (R[0, 0] + R[1, 1] + R[2, 2] - 1.0) / 2.0))
    v = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    th = math.acos(c)
    if th < 1e-6:
        return v * (1.0 + th * th / 6.0)
    if th > math.pi - 1e-3:
        from scipy.spatial.transform import Rotation  # lazy: scipy.spatial costs start-up time
        return Rotation.from_matrix(R).as_rotvec()
    return v * (th / math.sin(th))


@dataclass
class CameraData:
    """One camera's correspondences in the solver's form (one row per capture).

    Attributes:
        name: camera name.
        cam: its intrinsics.
        capture_ids: capture id per row.
        uv_px, cov_uv_px2: (N,2) raw pixel centres and (N,2,2) covariances (px^2).
        X_sonar_m, cov_X_m2: (N,3) sonar-frame centres (m, as in the cloud) and (N,3,3) covariances (m^2).
        xy, cov_xy: (N,2) normalised undistorted coordinates and (N,2,2) their covariances.
    """

    name: str
    cam: CameraModel
    capture_ids: list[str]
    uv_px: np.ndarray
    cov_uv_px2: np.ndarray
    X_sonar_m: np.ndarray
    cov_X_m2: np.ndarray
    xy: np.ndarray = field(repr=False, default=None)
    cov_xy: np.ndarray = field(repr=False, default=None)
    range_m: np.ndarray | None = field(repr=False, default=None)
    range_sigma_m: np.ndarray | None = field(repr=False, default=None)

    def __len__(self) -> int:
        return len(self.capture_ids)

    def range_mask(self, mask: np.ndarray) -> np.ndarray:
        """The rows of ``mask`` that carry a camera range (sphere's apparent size) and its sigma
        (a click has none; a look at the predicted place has its range left out, see
        :func:`calib_core.pipeline.correspondences`)."""
        mask = np.asarray(mask, bool)
        if self.range_m is None or self.range_sigma_m is None:
            return np.zeros_like(mask)
        r, s = self.range_m, self.range_sigma_m
        with np.errstate(invalid="ignore"):
            return mask & np.isfinite(r) & np.isfinite(s) & (s > 0) & (r > 0)

    def has_ranges(self, mask: np.ndarray) -> bool:
        """Whether any row in ``mask`` carries a camera range (the range terms use those rows)."""
        return bool(np.any(self.range_mask(mask)))


def _sym_pd(C: np.ndarray, what: str, name: str) -> np.ndarray:
    C = 0.5 * (C + np.swapaxes(C, -1, -2))
    if not np.isfinite(C).all() or np.any(np.linalg.eigvalsh(C) <= 0):
        raise SessionError(None, f"{name}: {what} covariances must be finite and positive definite")
    return C


def camera_data(name: str, cam: CameraModel, capture_ids, uv_px, cov_uv_px2, X_sonar_m, cov_X_m2,
                range_m=None, range_sigma_m=None) -> CameraData:
    """Check shapes and values, and add normalised coordinates (P-hat^-1) with their covariances.

    ``range_m`` / ``range_sigma_m`` (optional, (N,), NaN where unknown): the camera-to-sphere-centre
    distance from the sphere's apparent size and the known diameter, and its 1-sigma."""
    ids = [str(c) for c in capture_ids]
    n = len(ids)
    uv = np.asarray(uv_px, float).reshape(n, 2)
    X = np.asarray(X_sonar_m, float).reshape(n, 3)
    cuv = _sym_pd(np.asarray(cov_uv_px2, float).reshape(n, 2, 2), "image centre", name)
    cX = _sym_pd(np.asarray(cov_X_m2, float).reshape(n, 3, 3), "sonar centre", name)
    if not (np.isfinite(uv).all() and np.isfinite(X).all()):
        raise SessionError(None, f"{name}: correspondences hold NaN or infinite centres")
    if len(set(ids)) != n:
        raise SessionError(None, f"{name}: duplicate capture ids in the correspondences")
    xy = cam.normalize(uv)
    A = np.linalg.inv(cam.distort_jacobian(xy))
    cxy = A @ cuv @ np.swapaxes(A, 1, 2)
    rng = None if range_m is None else np.asarray(range_m, float).reshape(n)
    rsig = None if range_sigma_m is None else np.asarray(range_sigma_m, float).reshape(n)
    return CameraData(name, cam, ids, uv, cuv, X, cX, xy, 0.5 * (cxy + np.swapaxes(cxy, 1, 2)), rng, rsig)


@dataclass
class RigState:
    """Poses of a rig: the reference camera's ``T_ref_sonar``, each other camera's
    ``T_cam_ref`` (identity for the reference) and the sonar range scale."""

    T_ref_sonar: np.ndarray
    T_cam_ref: dict[str, np.ndarray]
    scale: float = 1.0

    def T_cam_sonar(self, cam: str) -> np.ndarray:
        return self.T_cam_ref[cam] @ self.T_ref_sonar


@dataclass
class Group:
    """Captures seen by the same set of cameras, stacked for vectorised evaluation."""

    cams: tuple[int, ...]  # camera indices into RigProblem.cams
    ids: list[str]
    X: np.ndarray  # (G,3)
    cX: np.ndarray  # (G,3,3)
    xy: np.ndarray  # (G,k,2)
    cxy: np.ndarray  # (G,k,2,2)
    rows: np.ndarray  # (G,k) row index into each camera's CameraData


def build_groups(cams: list[CameraData], masks: list[np.ndarray]) -> list[Group]:
    """Stack the used rows of every camera by capture (a capture seen by 2 cameras = one 4-vector)."""
    seen: dict[str, dict[int, int]] = {}
    order: list[str] = []
    for ci, (cd, m) in enumerate(zip(cams, masks)):
        for r in np.flatnonzero(m):
            cid = cd.capture_ids[r]
            if cid not in seen:
                seen[cid] = {}
                order.append(cid)
            seen[cid][ci] = int(r)
    by_sig: dict[tuple, list[str]] = {}
    for cid in order:
        by_sig.setdefault(tuple(sorted(seen[cid])), []).append(cid)
    groups = []
    for sig, ids in by_sig.items():
        rows = np.array([[seen[c][ci] for ci in sig] for c in ids], int).reshape(len(ids), len(sig))
        first = cams[sig[0]]
        X = first.X_sonar_m[rows[:, 0]]
        cX = first.cov_X_m2[rows[:, 0]]
        xy = np.stack([cams[ci].xy[rows[:, j]] for j, ci in enumerate(sig)], axis=1)
        cxy = np.stack([cams[ci].cov_xy[rows[:, j]] for j, ci in enumerate(sig)], axis=1)
        groups.append(Group(sig, ids, X, cX, xy, cxy, rows))
    return groups


def project_group(g: Group, Ts: list[np.ndarray], scale: float):
    """Predicted normalised coords (G,k,2), camera points (G,k,3) and d xy / d X_cloud (G,k,2,3)."""
    G, k = len(g.ids), len(g.cams)
    pred = np.empty((G, k, 2))
    P_all = np.empty((G, k, 3))
    J = np.empty((G, k, 2, 3))
    for j, ci in enumerate(g.cams):
        R, t = Ts[ci][:3, :3], Ts[ci][:3, 3]
        P = g.X @ R.T / scale + t
        z = np.maximum(P[:, 2], MIN_DEPTH_M)
        pred[:, j] = P[:, :2] / z[:, None]
        Pz = P.copy()
        Pz[:, 2] = z
        P_all[:, j] = P
        J[:, j] = pi_jacobian(Pz) @ (R / scale)
    return pred, P_all, J


def group_covariance(g: Group, J: np.ndarray) -> np.ndarray:
    """S (G,2k,2k): image covariances (block-diagonal) + stacked J cov_X J^T."""
    G, k = len(g.ids), len(g.cams)
    Js = J.reshape(G, 2 * k, 3)
    S = Js @ g.cX @ np.swapaxes(Js, 1, 2)
    for j in range(k):
        S[:, 2 * j:2 * j + 2, 2 * j:2 * j + 2] += g.cxy[:, j]
    return 0.5 * (S + np.swapaxes(S, 1, 2))


def whitening(S: np.ndarray) -> np.ndarray:
    """W with W S W^T = I (inverse Cholesky factor), batched."""
    L = np.linalg.cholesky(S)
    return np.linalg.inv(L)


def mahalanobis2(r: np.ndarray, S: np.ndarray) -> np.ndarray:
    """r^T S^-1 r for batched r (G,m) and S (G,m,m)."""
    return np.einsum("gi,gi->g", r, np.linalg.solve(S, r[..., None])[..., 0])


def per_camera_stats(cd: CameraData, T_cam_sonar: np.ndarray, scale: float = 1.0):
    """For every row of one camera at a pose: residual in px (N,2), normalised (N,2),
    single-camera covariance S (N,2,2) and Mahalanobis^2 (N,), depth in the camera (N,)."""
    R, t = T_cam_sonar[:3, :3], T_cam_sonar[:3, 3]
    P = cd.X_sonar_m @ R.T / scale + t
    depth = P[:, 2].copy()
    Pz = P.copy()
    Pz[:, 2] = np.maximum(depth, MIN_DEPTH_M)
    xy_pred = Pz[:, :2] / Pz[:, 2:3]
    r_xy = xy_pred - cd.xy
    J = pi_jacobian(Pz) @ (R / scale)
    S = cd.cov_xy + J @ cd.cov_X_m2 @ np.swapaxes(J, 1, 2)
    m2 = mahalanobis2(r_xy, S)
    m2[depth <= MIN_DEPTH_M] = np.inf
    uv_pred = cd.cam.distort(xy_pred)
    return uv_pred - cd.uv_px, r_xy, S, m2, depth


def prediction_jacobian(cd: CameraData, T_cam_sonar: np.ndarray, rows: np.ndarray, h: float = 1e-7) -> np.ndarray:
    """d xy_pred / d (rotation vector, translation) perturbation, (len(rows),2,6)."""
    X = cd.X_sonar_m[rows]

    def pred(T):
        P = X @ T[:3, :3].T + T[:3, 3]
        return P[:, :2] / P[:, 2:3]

    G = np.zeros((len(rows), 2, 6))
    for i in range(6):
        d = np.zeros(6)
        d[i] = h
        Tp, Tm = T_cam_sonar.copy(), T_cam_sonar.copy()
        Tp[:3, :3] = exp_so3(d[:3]) @ Tp[:3, :3]
        Tm[:3, :3] = exp_so3(-d[:3]) @ Tm[:3, :3]
        Tp[:3, 3] += d[3:]
        Tm[:3, 3] -= d[3:]
        G[:, :, i] = (pred(Tp) - pred(Tm)) / (2 * h)
    return G


def check_count(name: str, n: int, what: str = "usable captures") -> None:
    if n < 4:
        raise SessionError(None, f"{name}: only {n} {what}; at least 4 sphere positions seen by both the "
                                 f"sonar and this camera are needed (9 or more, spread over the view, recommended)")
