"""One camera's registration vouches for (or against) another's plain detections through the
session's stereo transform.

The session flow registers each camera to the sonar on its own (:mod:`calib_core.disambiguate.image`):
a camera with few plain detections, two of them wrong, cannot tell which are wrong (gym s48 cam2:
3 right, 2 wrong, and both wrong centres went into the solve). When the session states a stereo
transform ``T_b_a``, the better registered camera ``a`` predicts where camera ``b`` sees each
sphere: ``T_b_sonar = T_b_a @ T_a_sonar``. A plain detection of ``b`` far from that prediction, in
units of the prediction's stated uncertainty and its own, is refused (a chi-square test with 2
degrees of freedom at the false-alarm rate VOUCH_FALSE_ALARM); where ``b`` has too few plain
detections to predict on its own, the prediction is a place to look.

The prediction's uncertainty per image axis (px), root sum of squares of:
- the error of ``a``'s registration where it predicts, propagated from its N plain detections
  (:func:`registration_cov`): each detection's centre scatters along ``a``'s ray by one
  detection's range error (RANGE_REL_SIGMA) and across it by the image scatter that, with those
  range errors, explains the registration's image residuals (:func:`lateral_scatter_px`); the rigid fit's 6x6 covariance carried to the
  predicted centre and through the stereo transform into ``b``'s image (largest axis), so a
  range error seen across the baseline and a prediction far from the N points (leverage) are
  both in it; with a floor VOUCH_FLOOR_PX (``b``'s own lens and intrinsics);
- the stereo rotation's sigma x f_b, and its translation's sigma x f_b / range (the stated
  ``stereo_covariance``, else the solver's assumed default);
- the detection's own centre covariance (largest eigenvalue).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib_core.camera import CameraModel
from calib_core.disambiguate.image import RANGE_REL_SIGMA

# the rate at which a right detection is refused (chi-square, 2 degrees of freedom): 1 in 1000
VOUCH_FALSE_ALARM = 1e-3
VOUCH_CHI2 = float(-2.0 * np.log(VOUCH_FALSE_ALARM))  # 13.8, i.e. 3.7 sigma
# the least per-axis uncertainty of a prediction carried from another camera (px)
VOUCH_FLOOR_PX = 0.5


@dataclass(frozen=True)
class StereoPrediction:
    """Where camera ``b`` must see capture's sphere according to camera ``a``.

    uv_px: (2,) the projection; range_m: camera ``b`` to the centre; sigma_px: per-axis 1-sigma of
    the projection (without the detection's own error); source: camera ``a``'s name; terms_px:
    {term: its per-axis 1-sigma (px)}, the root sum of squares of which is sigma_px."""

    uv_px: np.ndarray
    range_m: float
    sigma_px: float
    source: str
    terms_px: dict = field(default_factory=dict)


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def registration_cov(T_a_sonar: np.ndarray, support_sonar_m: np.ndarray, sigma_lat_px: float, fx_a: float) -> np.ndarray:
    """6x6 covariance (left rotation vector, additive translation) of the rigid registration
    ``T_a_sonar`` fitted to the sphere centres ``support_sonar_m`` (N,3), each seen by ``a`` with
    ``sigma_lat_px`` across its ray and RANGE_REL_SIGMA of its range along it. The registration is
    an unweighted 3D fit (:func:`calib_core.disambiguate.image.rigid_fit`, Kabsch), so the covariance is
    that estimator's (the sandwich H^-1 M H^-1), not the weighted optimum's."""
    H, M = np.zeros((6, 6)), np.zeros((6, 6))
    for X in np.asarray(support_sonar_m, float).reshape(-1, 3):
        J, _, S_lat, S_rng = _point_terms(T_a_sonar, X, fx_a)
        H += J.T @ J
        M += J.T @ (sigma_lat_px ** 2 * S_lat + S_rng) @ J
    Hi = np.linalg.pinv(H)
    return Hi @ M @ Hi


# the least image scatter across the rays that a's residuals are read as (px per axis): a sharp
# outline's centre is good to about this
MIN_LATERAL_PX = 0.1


def _point_terms(T_a_sonar: np.ndarray, X: np.ndarray, fx_a: float) -> tuple:
    """(J 3x6 of the registered centre on the registration, A 2x3 of a's pixel on that centre,
    the centre's 3x3 covariance across the ray at 1 px, and along it at RANGE_REL_SIGMA)."""
    RX = T_a_sonar[:3, :3] @ X
    P = RX + T_a_sonar[:3, 3]
    r = float(np.linalg.norm(P))
    u = P / r
    A = fx_a / P[2] * np.array([[1.0, 0.0, -P[0] / P[2]], [0.0, 1.0, -P[1] / P[2]]])
    return (np.hstack([-_skew(RX), np.eye(3)]), A, (r / fx_a) ** 2 * (np.eye(3) - np.outer(u, u)),
            (RANGE_REL_SIGMA * r) ** 2 * np.outer(u, u))


def lateral_scatter_px(T_a_sonar: np.ndarray, support_sonar_m: np.ndarray, residual_px: float, fx_a: float) -> float:
    """a's image scatter across the rays (px per axis) that, with the stated range error along them,
    gives the registration's image residual RMS ``residual_px``: the unweighted fit's residuals are
    (I - G) e (G its hat matrix), so E[sum |uv residual|^2] = a s^2 + b, and s^2 = (N rms^2 - b) / a.
    The range errors' share of the residuals is not read as image scatter (it is counted along the
    rays already)."""
    from scipy.linalg import block_diag

    terms = [_point_terms(T_a_sonar, X, fx_a) for X in np.asarray(support_sonar_m, float).reshape(-1, 3)]
    J = np.vstack([t[0] for t in terms])
    Q = np.eye(len(J)) - J @ np.linalg.pinv(J.T @ J) @ J.T
    A = block_diag(*[t[1] for t in terms])
    a = float(np.trace(A @ Q @ block_diag(*[t[2] for t in terms]) @ Q.T @ A.T))
    b = float(np.trace(A @ Q @ block_diag(*[t[3] for t in terms]) @ Q.T @ A.T))
    s2 = (len(terms) * residual_px ** 2 - b) / max(a, 1e-12)
    return float(np.sqrt(max(s2, MIN_LATERAL_PX ** 2)))


def _registration_px(cam_b: CameraModel, T_b_a: np.ndarray, T_a_sonar: np.ndarray, cov6: np.ndarray, X: np.ndarray,
                     X_b: np.ndarray) -> float:
    """Largest per-axis 1-sigma (px) in ``b``'s image of the registration's error at centre ``X``."""
    J = T_b_a[:3, :3] @ np.hstack([-_skew(T_a_sonar[:3, :3] @ X), np.eye(3)])
    x, y, z = X_b
    A = cam_b.fx / z * np.array([[1.0, 0.0, -x / z], [0.0, 1.0, -y / z]])
    C = A @ J @ cov6 @ J.T @ A.T
    return float(np.sqrt(max(np.linalg.eigvalsh(0.5 * (C + C.T)).max(), 0.0)))


def stereo_predictions(cam_b: CameraModel, T_b_a: np.ndarray, cov_stereo6: np.ndarray, T_a_sonar: np.ndarray,
                       residual_px_a: float, fx_a: float, centers_sonar_m: dict, source: str,
                       support_sonar_m=None) -> dict:
    """{capture: StereoPrediction} for every sonar centre that lands in front of camera ``b`` and
    inside its image; ``support_sonar_m``: (N,3) the sonar centres of the plain detections ``a``'s
    registration rests on (None: the registration's error is left to the floor)."""
    T_b_sonar = T_b_a @ T_a_sonar
    cov = np.asarray(cov_stereo6, float)
    sig_rot = float(np.sqrt(np.max(np.linalg.eigvalsh(cov[:3, :3]))))
    sig_t = float(np.sqrt(np.max(np.linalg.eigvalsh(cov[3:, 3:]))))
    support = np.zeros((0, 3)) if support_sonar_m is None else np.asarray(support_sonar_m, float).reshape(-1, 3)
    n = len(support)
    cov_reg = None
    if n >= 3:
        cov_reg = registration_cov(T_a_sonar, support, lateral_scatter_px(T_a_sonar, support, residual_px_a, fx_a), fx_a)
    out = {}
    for cid, X in centers_sonar_m.items():
        X = np.asarray(X, float)
        X_b = T_b_sonar[:3, :3] @ X + T_b_sonar[:3, 3]
        if X_b[2] <= 0:
            continue
        uv = cam_b.project(X_b[None])[0]
        if not (np.isfinite(uv).all() and cam_b.in_image(uv[None])[0]):
            continue
        r = float(np.linalg.norm(X_b))
        reg = 0.0 if cov_reg is None else _registration_px(cam_b, T_b_a, T_a_sonar, cov_reg, X, X_b)
        terms = {"registration": max(VOUCH_FLOOR_PX, reg), "stereo rotation": cam_b.fx * sig_rot,
                 "stereo translation": cam_b.fx * sig_t / r}
        s = float(np.sqrt(sum(v ** 2 for v in terms.values())))
        out[cid] = StereoPrediction(uv, r, s, source, terms)
    return out


def vouch_chi2(pred: StereoPrediction, uv_px, cov_px2=None) -> float:
    """The squared distance between a detection and the prediction in units of both
    uncertainties (chi-square with 2 degrees of freedom when both are right)."""
    C = np.eye(2) * pred.sigma_px ** 2
    if cov_px2 is not None:
        C = C + np.asarray(cov_px2, float).reshape(2, 2)
    d = np.asarray(uv_px, float).reshape(2) - pred.uv_px
    return float(d @ np.linalg.solve(C, d))


def refused(pred: StereoPrediction, uv_px, cov_px2=None) -> bool:
    """Whether the detection fails the test (VOUCH_CHI2, false-alarm rate VOUCH_FALSE_ALARM)."""
    return vouch_chi2(pred, uv_px, cov_px2) > VOUCH_CHI2
