"""Initial camera-to-sonar pose: minimal/linear PnP inside RANSAC, and layout checks.

Hypotheses come from OpenCV's SQPnP on 4-point subsets (all of them when there are few,
random ones otherwise) in normalised coordinates (K = I, no distortion: the points were
already passed through P-hat^-1). Each hypothesis is scored by the captures' Mahalanobis
distances under the full noise model (image + propagated sonar covariance), MSAC style.
The best consensus is then refined by maximum likelihood and the inlier set decided by the
F test of :mod:`calib_core.solve.gate` (noise level from the data, stated false-alarm rate),
so a capture whose target moved between scan and image is named and good ones are kept.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from calib_core.geometry import T_from_rotvec
from calib_core.solve.gate import GateResult, gate_test, next_set
from calib_core.solve.model import CameraData, RigState, check_count, per_camera_stats
from calib_core.solve.refine import RigProblem, refine

CHI2_2_999 = 13.8155  # chi-square, 2 dof, 99.9 %: the gate for "this capture does not fit"
CHI2_2_99 = 9.2103  # 99 %: "suspicious"
CHI2_2_MEDIAN = 1.3863
MIN_HYPOTHESES = 40
# The first inlier set keeps what lies within 2x (in sigma) the gate at the robust noise level of
# the RANSAC pose: generous on purpose, the F test of calib_core.solve.gate then decides.
PRESELECT = 4.0
CORE_SHARE = 0.75
# Rows in the fit whose linearised deleted statistic reaches this share of the critical value (the
# EXACT_TOP worst) are tested exactly, by a refit without them.
EXACT_SCREEN = 0.2
EXACT_TOP = 3


@dataclass
class PnPStart:
    """RANSAC outcome for one camera.

    Attributes:
        T_cam_sonar: the pose after refinement on the consensus set.
        inliers: (N,) bool.
        gate_result: the F test of every row at that pose (:mod:`calib_core.solve.gate`), None when
            too few captures to test.
        gate: the chi-square gate of the first, generous inlier set (scaled by noise_factor).
        noise_factor: robust (median) variance factor of the residuals at the RANSAC pose.
        n_hypotheses: hypotheses tried.
        warnings: things the operator should know.
        miss_m: (N,) distance (m) between each sonar centre, mapped into the camera, and its image ray.
    """

    T_cam_sonar: np.ndarray
    inliers: np.ndarray
    gate_result: object
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
    m2s: list[np.ndarray] = []
    T_all = _sqpnp(cd.X_sonar_m, cd.xy)
    if T_all is not None:
        hyps.append(T_all)
        m2s.append(per_camera_stats(cd, T_all)[3])
    if check_outliers and n >= 6:
        _sample(cd, gate, _subsets(n, max_hypotheses, rng), rng, hyps, m2s)
    elif n < 6:
        warnings.append(f"{cd.name}: only {n} captures, too few to check for a capture that does not fit "
                        f"(6 at least, 9 or more recommended): add sphere positions")
    best = _best_hypothesis(hyps, m2s, gate)
    if best is None:
        raise_no_pose(cd)
    T, inl, stat, factor = _gate_loop(cd, best, gate, check_outliers and n >= 6)
    miss = miss_distances(cd, T)
    if check_outliers and n >= 6 and inl.sum() < max(4, 0.5 * n):
        warnings.append(f"{cd.name}: only {int(inl.sum())} of {n} captures agree with one pose; check the "
                        f"detections (wrong sphere found?) and the intrinsics")
    return PnPStart(T, inl, stat, gate * factor, factor, len(hyps), warnings, miss)


def _noise_factor(m2s: list[np.ndarray]) -> float:
    """Robust variance factor: the least median of squared distances over the hypotheses (LMedS),
    in units of chi-square(2)'s median. Scales exactly with the stated covariances, so the
    consensus below does not depend on whether the stated sigmas are right."""
    meds = [float(np.median(m)) for m in m2s if np.isfinite(m).sum() * 2 > len(m)]
    return max(min(meds) / CHI2_2_MEDIAN, 1e-12) if meds else np.inf


def _sample(cd: CameraData, gate: float, subsets, rng, hyps: list, m2s: list) -> None:
    """Add 4-point SQPnP hypotheses (and their squared distances) until, by the adaptive rule,
    an all-inlier subset has been drawn with 99.9 % probability (counted twice over, as noisy
    4-point poses miss some inliers)."""
    n = len(cd)
    rng.shuffle(subsets)
    best_inl, factor = 0, _noise_factor(m2s)
    for k, sub in enumerate(subsets):
        idx = np.asarray(sub)
        T = _sqpnp(cd.X_sonar_m[idx], cd.xy[idx])
        if T is not None:
            hyps.append(T)
            m2s.append(per_camera_stats(cd, T)[3])
            factor = min(factor, _noise_factor(m2s[-1:]))  # the running LMedS factor
            best_inl = max(best_inl, int(np.sum(m2s[-1] < gate * factor)))
        w = best_inl / n
        if k >= MIN_HYPOTHESES and w > 0 and k >= 2 * math.log(1e-3) / math.log(max(1 - w**4, 1e-12)):
            break


def _best_hypothesis(hyps: list, m2s: list, gate: float):
    """MSAC on the gate scaled by the robust noise factor (see :func:`_noise_factor`)."""
    if not hyps:
        return None
    f = _noise_factor(m2s)
    g = gate * (f if np.isfinite(f) else 1.0)
    costs = [float(np.sum(np.minimum(m, g))) for m in m2s]
    return hyps[int(np.argmin(costs))]


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


def _gate_loop(cd: CameraData, T0: np.ndarray, gate: float, check: bool):
    """From the RANSAC pose: its consensus refined by ML, then a generous first set (PRESELECT x
    the gate, scaled by the robust noise level of the consensus), then the F test of
    :mod:`calib_core.solve.gate` one capture at a time.

    Returns (pose, inliers, gate result or None, robust noise factor)."""
    n = len(cd)
    m2 = per_camera_stats(cd, T0)[3]
    if not check:
        T, _ = _fit(cd, np.ones(n, bool), T0)
        return T, np.ones(n, bool), None, 1.0
    factor = _noise_factor([m2])
    # the consensus at the hypothesis (at least CORE_SHARE of the rows: a small core fits itself too
    # well and swamps good rows), refined by ML before judging the rest
    k = min(n, max(5, math.ceil(CORE_SHARE * n)))
    core = m2 <= max(gate * factor, float(np.sort(m2)[k - 1]))
    if core.sum() >= 5:
        T0, cov = _fit(cd, core, T0)
        m2 = gate_test(cd, T0, cov, core).t  # deleted statistics: a small core predicts the rest loosely
        factor = _noise_factor([m2])
    inl = m2 < PRESELECT * gate * factor
    if inl.sum() < 5:
        inl = np.argsort(m2)[:max(5, n // 2)]
        inl = np.isin(np.arange(n), inl)
    min_keep = max(5, (n + 1) // 2)
    T, seen = T0, set()
    for _ in range(2 * n + 2):
        T, cov = _fit(cd, inl, T)
        res = _exact_deleted(cd, T, inl, gate_test(cd, T, cov, inl))
        new = next_set(res, inl, min_keep)
        key = inl.tobytes()
        if new is None or key in seen:
            break
        seen.add(key)
        inl = new
    return T, inl, res, factor


def _exact_deleted(cd: CameraData, T: np.ndarray, inl: np.ndarray, res):
    """Replace the linearised deleted statistic of the most suspicious rows in the fit by the exact
    one (refit without the row, predict it): a moved target with high leverage pulls the pose
    far enough that the linearisation understates it."""
    ratio = np.nan_to_num(res.ratio, nan=np.inf, posinf=np.inf)
    cand = [i for i in np.argsort(-ratio) if inl[i] and ratio[i] > EXACT_SCREEN][:EXACT_TOP]
    if not cand or inl.sum() - 1 < 5:
        return res
    F, crit, t, dof = res.F.copy(), res.crit.copy(), res.t.copy(), res.dof.copy()
    for i in cand:
        m = inl.copy()
        m[i] = False
        T2, cov2 = _fit(cd, m, T)
        g = gate_test(cd, T2, cov2, m)
        F[i], crit[i], t[i], dof[i] = g.F[i], g.crit[i], g.t[i], g.dof[i]
    return GateResult(t, F, crit, dof, res.variance_factor)


def miss_distances(cd: CameraData, T: np.ndarray) -> np.ndarray:
    """Per row: distance (m) between the sonar centre mapped into the camera and its image ray."""
    Pc = cd.X_sonar_m @ T[:3, :3].T + T[:3, 3]
    d = np.column_stack([cd.xy, np.ones(len(cd))])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    miss = np.linalg.norm(Pc - np.sum(Pc * d, axis=1, keepdims=True) * d, axis=1)
    miss[Pc[:, 2] <= 0] = np.inf
    return miss


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
