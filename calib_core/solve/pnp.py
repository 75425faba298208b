"""Initial camera-to-sonar pose: minimal/linear PnP inside RANSAC, and layout checks.

Hypotheses come from OpenCV's SQPnP on 4-point subsets (all of them when there are few,
random ones otherwise) in normalised coordinates (K = I, no distortion: the points were
already passed through P-hat^-1). Each hypothesis is scored by the captures' Mahalanobis
distances under the full noise model (image + propagated sonar covariance), MSAC style.
The best consensus is then refined by maximum likelihood and the inlier set re-gated until
it stops changing, so a capture whose target moved between scan and image is named.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from calib_core.geometry import T_from_rotvec
from calib_core.solve.model import CameraData, RigState, check_count, per_camera_stats, prediction_jacobian
from calib_core.solve.refine import RigProblem, refine

CHI2_2_999 = 13.8155  # chi-square, 2 dof, 99.9 %: the gate for "this capture does not fit"
CHI2_2_99 = 9.2103  # 99 %: "suspicious"
CHI2_2_MEDIAN = 1.3863
MIN_HYPOTHESES = 40
# A capture whose sonar centre passes within this distance of its image ray is never left out
# (at most flagged): detection covariances are often optimistic, and a moved target or a wrong
# detection misses by far more than 1 cm.
MIN_MISS_M = 0.01


@dataclass
class PnPStart:
    """RANSAC outcome for one camera.

    Attributes:
        T_cam_sonar: the pose after refinement on the consensus set.
        inliers: (N,) bool.
        mahalanobis2: (N,) the gate statistic of every row at that pose: squared Mahalanobis distance
            with the pose's own uncertainty accounted for (see :func:`gate_statistics`).
        gate: the chi-square gate used (inflated when the covariances look too optimistic).
        noise_factor: >1 when the residuals are larger than the stated covariances explain.
        n_hypotheses: hypotheses tried.
        warnings: things the operator should know.
        miss_m: (N,) distance (m) between each sonar centre, mapped into the camera, and its image ray.
    """

    T_cam_sonar: np.ndarray
    inliers: np.ndarray
    mahalanobis2: np.ndarray
    gate: float
    noise_factor: float
    n_hypotheses: int
    warnings: list[str] = field(default_factory=list)
    miss_m: np.ndarray | None = None


def _sqpnp(X: np.ndarray, xy: np.ndarray) -> np.ndarray | None:
    try:
        ok, rvec, tvec = cv2.solvePnP(X.reshape(-1, 1, 3), xy.reshape(-1, 1, 2), np.eye(3), None,
                                      flags=cv2.SOLVEPNP_SQPNP)
    except cv2.error:
        return None
    if not ok or not np.isfinite(rvec).all() or not np.isfinite(tvec).all():
        return None
    return T_from_rotvec(rvec.ravel(), tvec.ravel())


def _subsets(n: int, max_hypotheses: int, rng: np.random.Generator):
    if math.comb(n, 4) <= max_hypotheses:
        return list(itertools.combinations(range(n), 4))
    return [tuple(int(i) for i in rng.choice(n, 4, replace=False)) for _ in range(max_hypotheses)]


def ransac_pose(cd: CameraData, gate: float = CHI2_2_999, max_hypotheses: int = 400, seed: int = 0,
                check_outliers: bool = True) -> PnPStart:
    """Robust initial pose of one camera from its correspondences (see the module doc).

    With fewer than 6 correspondences outliers cannot be told apart, so all are kept (and a
    warning says so). Raises SessionError with fewer than 4.
    """
    n = len(cd)
    check_count(cd.name, n)
    warnings: list[str] = []
    rng = np.random.default_rng(seed)
    hyps: list[np.ndarray] = []
    T_all = _sqpnp(cd.X_sonar_m, cd.xy)
    if T_all is not None:
        hyps.append(T_all)
    best, best_cost, best_inl = None, np.inf, 0

    def score(T):
        nonlocal best, best_cost, best_inl
        m2 = per_camera_stats(cd, T)[3]
        cost = float(np.sum(np.minimum(m2, gate)))
        if cost < best_cost:
            best, best_cost, best_inl = T, cost, int(np.sum(m2 < gate))

    if T_all is not None:
        score(T_all)
    if check_outliers and n >= 6:
        subsets = _subsets(n, max_hypotheses, rng)
        rng.shuffle(subsets)
        for k, sub in enumerate(subsets):
            idx = np.asarray(sub)
            T = _sqpnp(cd.X_sonar_m[idx], cd.xy[idx])
            if T is not None:
                hyps.append(T)
                score(T)
            # adaptive stop: enough samples to have drawn an all-inlier subset with 99.9 % probability
            # (counted twice over, as noisy 4-point poses miss some inliers)
            w = best_inl / n
            if k >= MIN_HYPOTHESES and w > 0 and k >= 2 * math.log(1e-3) / math.log(max(1 - w**4, 1e-12)):
                break
    elif n < 6:
        warnings.append(f"{cd.name}: only {n} captures, too few to check for a capture that does not fit "
                        f"(6 at least, 9 or more recommended): add sphere positions")
    if best is None:
        raise_no_pose(cd)
    inl = per_camera_stats(cd, best)[3] < gate if (check_outliers and n >= 6) else np.ones(n, bool)
    if inl.sum() < 4:
        inl = np.ones(n, bool)
    factor = 1.0
    T = best
    miss = np.zeros(n)
    for _ in range(6):
        T, cov = _fit(cd, inl, T)
        m2 = per_camera_stats(cd, T)[3]
        if not (check_outliers and n >= 6):
            break
        stat, miss = gate_statistics(cd, T, cov, inl)
        # Residuals larger than the stated covariances explain: gate on the observed spread instead.
        factor = max(1.0, float(np.median(stat[inl])) / CHI2_2_MEDIAN)
        new = (stat < gate * factor) | (miss < MIN_MISS_M)
        m2 = stat
        if new.sum() < 4 or np.array_equal(new, inl):
            break
        inl = new
    if factor > 2.0:
        warnings.append(f"{cd.name}: residuals are {math.sqrt(factor):.1f}x larger than the detections' stated "
                        f"uncertainty; the outlier gate was widened accordingly (check intrinsics and detections)")
    if check_outliers and n >= 6 and inl.sum() < max(4, 0.5 * n):
        warnings.append(f"{cd.name}: only {int(inl.sum())} of {n} captures agree with one pose; check the "
                        f"detections (wrong sphere found?) and the intrinsics")
    return PnPStart(T, inl, m2, gate * factor, factor, len(hyps), warnings, miss)


def raise_no_pose(cd: CameraData):
    from calib_core.errors import SessionError

    raise SessionError(None, f"{cd.name}: no camera pose fits the correspondences (check that image and sonar "
                             f"centres belong to the same captures)")


def _fit(cd: CameraData, inl: np.ndarray, T0: np.ndarray):
    """Linear start on the inliers (when it beats T0) then ML refinement: (T_cam_sonar, 6x6 covariance)."""
    T_lin = _sqpnp(cd.X_sonar_m[inl], cd.xy[inl])
    cands = [T0] + ([T_lin] if T_lin is not None else [])
    costs = [float(np.sum(np.minimum(per_camera_stats(cd, T)[3][inl], 1e6))) for T in cands]
    start = cands[int(np.argmin(costs))]
    prob = RigProblem([cd], [inl])
    res = refine(prob, RigState(start, {cd.name: np.eye(4)}), max_outer=6)
    return res.state.T_ref_sonar, res.cov


def gate_statistics(cd: CameraData, T: np.ndarray, cov6: np.ndarray, inl: np.ndarray):
    """Per row: (gate statistic, miss distance in m).

    The statistic is chi-square(2)-distributed under the noise model for every row: rows in the
    fit have their squared Mahalanobis distance divided by (1 - leverage), because the fit has
    already pulled towards them (with 9 captures and 6 parameters, by two thirds on average);
    rows outside it are measured against S + G C G^T, the prediction's own uncertainty added.
    The miss distance is between the sonar centre mapped into the camera and its image ray.
    """
    _, r, S, m2, depth = per_camera_stats(cd, T)
    G = prediction_jacobian(cd, T, np.arange(len(cd)))
    P = G @ cov6 @ np.swapaxes(G, 1, 2)
    lev = 0.5 * np.einsum("nii->n", np.linalg.solve(S, P))
    stat_in = m2 / np.maximum(1.0 - lev, 0.05)
    Sp = S + P
    stat_out = np.einsum("ni,ni->n", r, np.linalg.solve(Sp, r[..., None])[..., 0])
    stat = np.where(inl, stat_in, stat_out)
    stat[depth <= 0] = np.inf
    Pc = cd.X_sonar_m @ T[:3, :3].T + T[:3, 3]
    d = np.column_stack([cd.xy, np.ones(len(cd))])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    miss = np.linalg.norm(Pc - np.sum(Pc * d, axis=1, keepdims=True) * d, axis=1)
    miss[depth <= 0] = np.inf
    return stat, miss


def layout_warnings(cd: CameraData, used: np.ndarray, T_cam_sonar: np.ndarray) -> list[str]:
    """Warnings about near-degenerate sphere layouts, each saying what to do."""
    out = []
    X = cd.X_sonar_m[used]
    n = len(X)
    if n < 3:
        return out
    sv = np.linalg.svd(X - X.mean(axis=0), compute_uv=False)
    if sv[0] < 1e-9:
        return [f"{cd.name}: all sphere positions coincide: move the sphere between captures"]
    if sv[1] / sv[0] < 0.08:
        out.append(f"{cd.name}: the sphere positions lie nearly on one line; the rotation about that line is "
                   f"poorly determined: move the sphere sideways and up/down as well")
    elif sv[2] / sv[0] < 0.05:
        out.append(f"{cd.name}: the sphere positions lie nearly in one plane; vary the distance as well as the "
                   f"position in the view")
    P = X @ T_cam_sonar[:3, :3].T + T_cam_sonar[:3, 3]
    z = P[:, 2]
    if np.all(z > 0) and (z.max() - z.min()) / np.median(z) < 0.25:
        out.append(f"{cd.name}: little depth spread ({z.min():.2f}-{z.max():.2f} m from the camera): move the "
                   f"sphere nearer and farther (e.g. from {0.6 * np.median(z):.1f} to {1.5 * np.median(z):.1f} m)")
    uv = cd.uv_px[used]
    spread_u = (uv[:, 0].max() - uv[:, 0].min()) / cd.cam.width_px
    spread_v = (uv[:, 1].max() - uv[:, 1].min()) / cd.cam.height_px
    if spread_u < 0.3 or spread_v < 0.3:
        side = "left-right" if spread_u < spread_v else "top-bottom"
        out.append(f"{cd.name}: the sphere covers only {100 * spread_u:.0f}% x {100 * spread_v:.0f}% of the image; "
                   f"spread the positions across the view ({side} especially)")
    return out
