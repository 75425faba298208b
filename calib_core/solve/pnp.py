"""Initial camera-to-sonar pose: the consensus over captures, then the outlier gate.

The consensus (:mod:`calib_core.solve.consensus`) is grown from the tightest 4-capture core
by a forward search, so several wrong centres cannot outvote the right ones; it says when
two different sets of captures agree about as well. The set found is then refined by
maximum likelihood and decided one capture at a time by the F test of
:mod:`calib_core.solve.gate` (noise level from the data, stated false-alarm rate), so a
capture whose target moved between scan and image is named and good ones are kept.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib_core.solve.consensus import (CORE, MIN_VARIANCE_FACTOR, find_consensus, fit_subset, judge,
                                       no_consensus_phrase, sqpnp)
from calib_core.solve.gate import ALPHA, GateResult, gate_test, next_set
from calib_core.solve.model import CameraData, check_count, per_camera_stats

CHI2_2_999 = 13.8155  # chi-square, 2 dof, 99.9 %: the gate for "this capture does not fit"
MIN_CHECK = 6  # with fewer captures outliers cannot be told apart
# Rows in the fit whose linearised deleted statistic reaches this share of the critical value (the
# EXACT_TOP worst) are tested exactly, by a refit without them.
EXACT_SCREEN = 0.2
EXACT_TOP = 3
READMIT_MARGIN = 4.0  # see _readmit


@dataclass
class PnPStart:
    """Consensus and gate outcome for one camera.

    Attributes:
        T_cam_sonar: the pose after refinement on the final set.
        inliers: (N,) bool.
        gate_result: the F test of every row at that pose (:mod:`calib_core.solve.gate`), None when
            too few captures to test.
        gate: the chi-square gate scaled by noise_factor (for display).
        noise_factor: variance factor (chi2 / dof) of the final set at that pose.
        n_hypotheses: SQPnP hypotheses tried.
        warnings: things the operator should know.
        miss_m: (N,) distance (m) between each sonar centre, mapped into the camera, and its image ray.
        clear: False when another set of captures agrees with another pose about as well.
        rival: (N,) bool of that other set, or None.
    """

    T_cam_sonar: np.ndarray
    inliers: np.ndarray
    gate_result: object
    gate: float
    noise_factor: float
    n_hypotheses: int
    warnings: list[str] = field(default_factory=list)
    miss_m: np.ndarray | None = None
    clear: bool = True
    rival: np.ndarray | None = None


def ransac_pose(cd: CameraData, gate: float = CHI2_2_999, max_hypotheses: int = 400, seed: int = 0,
                check_outliers: bool = True) -> PnPStart:
    """Robust initial pose of one camera from its correspondences (see the module doc).

    With fewer than MIN_CHECK correspondences outliers cannot be told apart, so all are kept (and
    a warning says so). Raises SessionError with fewer than 4.
    """
    n = len(cd)
    check_count(cd.name, n)
    warnings: list[str] = []
    check = check_outliers and n >= MIN_CHECK
    if check_outliers and not check:
        warnings.append(f"{cd.name}: only {n} captures, too few to check for a capture that does not fit "
                        f"(6 at least, 9 or more recommended): add sphere positions")
    if not check:
        T0 = sqpnp(cd.X_sonar_m, cd.xy)
        if T0 is None:
            raise_no_pose(cd)
        T, _ = fit_subset(cd, np.ones(n, bool), T0)
        return PnPStart(T, np.ones(n, bool), None, gate, 1.0, 1, warnings, miss_distances(cd, T))
    cons = find_consensus(cd, max_hypotheses, seed)
    if cons is None:
        raise_no_pose(cd)
    T, inl, stat = _prefer_larger(cd, *_gate_loop(cd, cons.T_cam_sonar, cons.inliers))
    cons = judge(cd, cons, inl, T)
    factor = float(np.sum(per_camera_stats(cd, T)[3][inl])) / max(2 * int(inl.sum()) - 6, 1)
    if not cons.clear:
        warnings.append(no_consensus_phrase(cd, cons))
    elif inl.sum() < max(5, 0.5 * n):
        warnings.append(f"{cd.name}: only {int(inl.sum())} of {n} captures agree with one pose; check the "
                        f"detections (wrong sphere found?) and the intrinsics")
    return PnPStart(T, inl, stat, gate * factor, factor, cons.n_hypotheses, warnings, miss_distances(cd, T),
                    cons.clear, cons.rival)


def raise_no_pose(cd: CameraData):
    from calib_core.errors import SessionError

    raise SessionError(None, f"{cd.name}: no camera pose fits the correspondences (check that image and sonar "
                             f"centres belong to the same captures)")


def _gate_loop(cd: CameraData, T0: np.ndarray, inl: np.ndarray):
    """From the consensus: the F test of :mod:`calib_core.solve.gate` drops failing captures one at a
    time (worst first, refitting after each); then the captures left out are re-admitted when
    they agree with the set, jointly (:func:`_readmit`); then the drop test once more.

    Returns (pose, inliers, gate result)."""
    T, inl, res = _drop(cd, T0, inl)
    seen = {inl.tobytes()}
    # a set of CORE rows leaves 2 dof for its noise level: too few to vouch for others
    while inl.sum() > CORE and not inl.all():
        extra = _readmit(cd, T, inl, res)
        if not extra.any():
            break
        T, inl, res = _drop(cd, T, inl | extra)
        if inl.tobytes() in seen:
            break
        seen.add(inl.tobytes())
    return T, inl, res


def _prefer_larger(cd: CameraData, T: np.ndarray, inl: np.ndarray, res):
    """The consensus set, or the larger set the plain gate keeps when started from every capture,
    when that one fits as well: a nested F test, (chi2 of the larger set at its own fit - chi2 of
    the consensus) / (2k) over the consensus's variance factor, within READMIT_MARGIN times the
    1 - ALPHA/n quantile of F(2k, dof) (the variance factor floored as in the consensus). A consensus grown from a tight 4-capture core can settle on
    a pose that good captures plainly contradict only because that core was wrong (seen in 1 of 300
    clean sessions: 5 of 9 kept, 180 mm off); a fresh fit on every capture then explains them all."""
    from scipy.special import fdtri

    n = len(cd)
    T0 = sqpnp(cd.X_sonar_m, cd.xy) if not inl.all() else None
    if T0 is None:
        return T, inl, res
    T_b, inl_b, res_b = _drop(cd, T0, np.ones(n, bool))
    k = int(inl_b.sum()) - int(inl.sum())
    if k <= 0:
        return T, inl, res
    chi_a = float(np.sum(per_camera_stats(cd, T)[3][inl]))
    dof_a = 2 * int(inl.sum()) - 6
    noise = max(chi_a / max(dof_a, 1), MIN_VARIANCE_FACTOR)  # a tight core's level is low by luck: floored
    F = (float(np.sum(per_camera_stats(cd, T_b)[3][inl_b])) - chi_a) / (2 * k) / noise
    return (T_b, inl_b, res_b) if F <= READMIT_MARGIN * fdtri(2 * k, max(dof_a, 1), 1 - ALPHA / n) else (T, inl, res)


def _drop(cd: CameraData, T: np.ndarray, inl: np.ndarray):
    inl = inl.copy()
    for _ in range(len(cd) + 1):
        T, cov = fit_subset(cd, inl, T)
        res = _exact_deleted(cd, T, inl, gate_test(cd, T, cov, inl))
        new = next_set(res, inl, CORE, readmit=False)
        if new is None:
            break
        inl = new
    return T, inl, res


def _readmit(cd: CameraData, T: np.ndarray, inl: np.ndarray, res: GateResult) -> np.ndarray:
    """Captures outside ``inl`` that do not plainly contradict it, jointly: (chi2 with them - chi2
    without) / (2k) over the set's variance factor, within READMIT_MARGIN times the 1 - ALPHA/n
    quantile of F(2k, dof). Joint, and always against the same set, so wrong centres that each
    pass narrowly (a small set predicts far rows loosely) cannot swamp it one by one. The margin:
    the set was grown from the tightest captures, so its variance factor is low by selection and
    good captures look somewhat bad against it; the drop test that follows, on the larger set,
    decides them at the stated rate."""
    from scipy.special import fdtri

    n = len(cd)
    chi_a = float(np.sum(per_camera_stats(cd, T)[3][inl]))
    dof_a = 2 * int(inl.sum()) - 6
    t = np.where(np.isfinite(res.t), res.t, np.inf)
    extra = np.zeros(n, bool)
    for j in np.flatnonzero(~inl)[np.argsort(t[~inl])]:
        if not np.isfinite(t[j]):
            break
        trial = inl | extra
        trial[j] = True
        T2, _ = fit_subset(cd, trial, T)
        k = int((trial & ~inl).sum())
        F = (float(np.sum(per_camera_stats(cd, T2)[3][trial])) - chi_a) / (2 * k) / max(chi_a / dof_a, 1e-300)
        if F <= READMIT_MARGIN * fdtri(2 * k, dof_a, 1 - ALPHA / n):
            extra[j] = True
    return extra


def _exact_deleted(cd: CameraData, T: np.ndarray, inl: np.ndarray, res):
    """Replace the linearised deleted statistic of the most suspicious rows in the fit by the exact
    one (refit without the row, predict it): a moved target with high leverage pulls the pose
    far enough that the linearisation understates it."""
    ratio = np.nan_to_num(res.ratio, nan=np.inf, posinf=np.inf)
    cand = [i for i in np.argsort(-ratio) if inl[i] and ratio[i] > EXACT_SCREEN][:EXACT_TOP]
    if not cand or inl.sum() - 1 < CORE:
        return res
    F, crit, t, dof = res.F.copy(), res.crit.copy(), res.t.copy(), res.dof.copy()
    for i in cand:
        m = inl.copy()
        m[i] = False
        T2, cov2 = fit_subset(cd, m, T)
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
