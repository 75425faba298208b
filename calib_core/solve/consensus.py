"""Which captures agree with one pose, found without trusting any of them (one camera).

Several wrong image centres (a decoy found, a partly hidden ball mislocated) can outvote a
least-squares fit and smear their error over every capture, so that no single one stands
out. The consensus is therefore grown from the tightest small core, never pruned from the
whole (the forward search of Atkinson & Riani):

1. **Hypotheses**: OpenCV's SQPnP on 4-capture subsets (all of them when there are few,
   random ones otherwise), in normalised coordinates.
2. **Cores**: each hypothesis' 4 best-fitting captures and the sum of their squared
   Mahalanobis distances. Ranking by that sum does not depend on the stated sigmas (a common
   factor on every covariance keeps the order), and wrong centres tens of pixels off rarely
   make a tight core.
3. **Forward search** from the tightest core: refit by maximum likelihood, then add the
   capture outside the set that agrees best, judged by the gate's deleted-residual F test
   (:mod:`calib_core.solve.gate`: noise level from the set itself), until every capture
   outside the set fails it at 1 - ALPHA (the smallest of them is tested, so no Bonferroni
   correction: with only good captures left, the search stops early with probability at most
   ALPHA per step, and the final gate re-admits them).
4. **Rivals**: the same search from the tightest cores made mostly of captures left out,
   among those captures. A
   rival is a set that holds together (its own search, from its own tightest core, gives it
   back), is about as large (at most one capture fewer, and at least MIN_RIVAL) and is about as tight (no F test of
   the two noise levels at 1 % tells them apart). A rival means there is no clear consensus;
   :func:`no_consensus_phrase` says so, once for every shell.

The set found is then handed to the gate's one-at-a-time test (:mod:`calib_core.solve.pnp`).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from calib_core.geometry import T_from_rotvec
from calib_core.solve.gate import f_critical, gate_test
from calib_core.solve.model import CameraData, RigState, per_camera_stats
from calib_core.solve.refine import RigProblem, refine

CHI2_2_MEDIAN = 1.3863
CORE = 4  # captures in a core (SQPnP's minimum; 2 dof left to judge it)
MIN_HYPOTHESES = 40
N_RIVALS = 3  # rival searches tried
RIVAL_ALPHA = 0.01  # F test of two noise levels: below this they differ
# the only trust put in the stated covariances: they are not more than ~3x too large (in sigma)
MIN_VARIANCE_FACTOR = 0.1
MIN_RIVAL = 5  # a rival needs 4 dof of its own: any 4 captures fit some pose within 2 dof of luck
BATCH_FROM = 12
NO_CONSENSUS = "no clear consensus"  # the words that open the phrase, for shells that look for it  # from this set size on, several agreeing captures join per step


@dataclass
class Consensus:
    """Outcome of :func:`find_consensus`.

    T_cam_sonar: pose fitted on ``inliers``; inliers: (N,) bool; cov: 6x6 pose covariance from
    the stated covariances; clear: False when a rival set is about as large and as tight;
    rival: (N,) bool of the best rival, or None; n_hypotheses: SQPnP hypotheses tried.
    """

    T_cam_sonar: np.ndarray
    inliers: np.ndarray
    cov: np.ndarray
    clear: bool = True
    rival: np.ndarray | None = None
    n_hypotheses: int = 0
    rival_T: np.ndarray | None = field(default=None, repr=False)
    ranked: list = field(default_factory=list, repr=False)


def sqpnp(X: np.ndarray, xy: np.ndarray) -> np.ndarray | None:
    """OpenCV's SQPnP on sonar points and normalised image points (K = I), or None."""
    try:
        ok, rvec, tvec = cv2.solvePnP(X.reshape(-1, 1, 3), xy.reshape(-1, 1, 2), np.eye(3), None,
                                      flags=cv2.SOLVEPNP_SQPNP)
    except cv2.error:
        return None
    if not ok or not np.isfinite(rvec).all() or not np.isfinite(tvec).all():
        return None
    return T_from_rotvec(rvec.ravel(), tvec.ravel())


def fit_subset(cd: CameraData, inl: np.ndarray, T0: np.ndarray, max_outer: int = 6, linear: bool = True):
    """Linear start on ``inl`` (when ``linear`` and it beats T0) then ML refinement: (T_cam_sonar,
    6x6 covariance)."""
    T_lin = sqpnp(cd.X_sonar_m[inl], cd.xy[inl]) if linear else None
    cands = [T0] + ([T_lin] if T_lin is not None else [])
    costs = [float(np.sum(np.minimum(per_camera_stats(cd, T)[3][inl], 1e6))) for T in cands]
    start = cands[int(np.argmin(costs))]
    res = refine(RigProblem([cd], [inl]), RigState(start, {cd.name: np.eye(4)}), max_outer=max_outer)
    return res.state.T_ref_sonar, res.cov


def _subsets(n: int, max_hypotheses: int, rng: np.random.Generator) -> list:
    if math.comb(n, CORE) <= max_hypotheses:
        return list(itertools.combinations(range(n), CORE))
    return [tuple(int(i) for i in rng.choice(n, CORE, replace=False)) for _ in range(max_hypotheses)]


def cores(cd: CameraData, max_hypotheses: int = 400, seed: int = 0) -> tuple[list, int]:
    """Distinct cores, tightest first: [(score, core rows tuple, T)], and hypotheses tried.

    Random subsets stop by the adaptive RANSAC rule once a subset of captures that all agree
    (at the running LMedS noise level) has been drawn with 99.9 % probability, counted twice over."""
    n = len(cd)
    rng = np.random.default_rng(seed)
    subsets = _subsets(n, max_hypotheses, rng)
    exhaustive = math.comb(n, CORE) <= max_hypotheses
    best: dict[tuple, tuple] = {}
    best_inl, med_min, tried = 0, np.inf, 0
    for k, sub in enumerate(subsets):
        idx = np.asarray(sub)
        T = sqpnp(cd.X_sonar_m[idx], cd.xy[idx])
        tried += 1
        if T is not None:
            m2 = per_camera_stats(cd, T)[3]
            rows = tuple(sorted(int(i) for i in np.argsort(m2)[:CORE]))
            score = float(np.sum(np.sort(m2)[:CORE]))
            if np.isfinite(score) and (rows not in best or score < best[rows][0]):
                best[rows] = (score, rows, T)
            med_min = min(med_min, float(np.median(m2)))
            best_inl = max(best_inl, int(np.sum(m2 < 13.8155 * med_min / CHI2_2_MEDIAN)))
        w = best_inl / n
        if (not exhaustive and k >= MIN_HYPOTHESES and w > 0
                and k >= 2 * math.log(1e-3) / math.log(max(1 - w**CORE, 1e-12))):
            break
    return sorted(best.values(), key=lambda c: c[0]), tried


def _mask(n: int, rows) -> np.ndarray:
    m = np.zeros(n, bool)
    m[list(rows)] = True
    return m


def forward_search(cd: CameraData, core, T0: np.ndarray, allowed: np.ndarray | None = None):
    """Grow a set from ``core`` (rows) while the best-agreeing capture outside it passes the gate.

    Returns (inliers, T_cam_sonar, cov). ``allowed`` restricts the rows that may join."""
    n = len(cd)
    inl = _mask(n, core)
    allowed = np.ones(n, bool) if allowed is None else allowed
    T = T0
    while True:
        # warm-started from the previous step's pose (one capture more): two weight refreshes do
        T, cov = fit_subset(cd, inl, T, max_outer=2, linear=inl.sum() == CORE)
        out = np.flatnonzero(allowed & ~inl)
        if not len(out):
            return inl, T, cov
        ratio = _outside_ratio(cd, T, cov, inl, allowed)[out]
        order = out[np.argsort(ratio)]
        passing = order[np.sort(ratio) <= 1.0]
        if not len(passing):
            return inl, T, cov
        k = 1 if inl.sum() < BATCH_FROM else max(1, int(inl.sum()) // 4)
        inl[passing[:k]] = True


def _outside_ratio(cd: CameraData, T: np.ndarray, cov: np.ndarray, inl: np.ndarray, allowed: np.ndarray) -> np.ndarray:
    """Each row's gate F over its critical value, for growing the set.

    The smallest of the outside statistics is tested, so no Bonferroni correction: its 1 - ALPHA
    quantile (the final gate of calib_core.solve.pnp tests the largest, with the correction). The
    noise level is at least the median of the allowed rows' statistics (in chi-square(2) units): the
    tightest core is tight partly by luck, and its own 2 dof would make good captures look bad; and
    it is at least MIN_VARIANCE_FACTOR: when the core is all that fits that well, only the stated
    covariances can say that a capture outside it is good."""
    g = gate_test(cd, T, cov, inl)
    t = np.where(np.isfinite(g.t), g.t, np.inf)
    ta = np.sort(t[allowed])
    # the upper median: the core's own rows (fitted, no deleted residual) count among the small ones
    v_rob = max(float(ta[len(ta) // 2]) / CHI2_2_MEDIAN, MIN_VARIANCE_FACTOR)
    v_row = t / (2 * np.maximum(g.F, 1e-300))
    F = t / (2 * np.maximum(np.maximum(v_row, v_rob), 1e-300))
    return np.nan_to_num(F / f_critical(g.dof, 1), nan=np.inf, posinf=np.inf)


def _variance_factor(cd: CameraData, inl: np.ndarray, T: np.ndarray) -> tuple[float, int]:
    dof = 2 * int(inl.sum()) - 6
    return float(np.sum(per_camera_stats(cd, T)[3][inl])) / max(dof, 1), dof


def _same_noise(cd: CameraData, a, b) -> bool:
    """Whether two fitted sets (inliers, T) show noise levels an F test at RIVAL_ALPHA cannot tell apart."""
    from scipy.special import fdtr

    (va, da), (vb, db) = _variance_factor(cd, *a), _variance_factor(cd, *b)
    if da < 1 or db < 1:
        return True
    hi, lo, dhi, dlo = (va, vb, da, db) if va >= vb else (vb, va, db, da)
    p = 1.0 - fdtr(dhi, dlo, hi / max(lo, 1e-300))
    return p > RIVAL_ALPHA / 2  # two-sided


def _holds_together(cd: CameraData, inl: np.ndarray, ranked: list) -> bool:
    """A set holds together when the search from its own tightest core gives it back."""
    own = next((c for c in ranked if inl[list(c[1])].all()), None)
    if own is None:
        return False
    back, _, _ = forward_search(cd, own[1], own[2], allowed=inl)
    return bool(np.array_equal(back, inl))


def _rival(cd: CameraData, found, ranked: list):
    """The largest set that competes with ``found`` (see the module doc), or None."""
    inl, T, _ = found
    rivals = [c for c in ranked if int((~inl[list(c[1])]).sum()) >= 2][:N_RIVALS]
    best = None
    need = max(int(inl.sum()) - 1, MIN_RIVAL)
    for _, rows, T0 in rivals:  # grown from what the consensus left out (and the rival's own core)
        allowed = ~inl | _mask(len(cd), rows)
        if allowed.sum() < need:
            continue
        b, Tb, _ = forward_search(cd, rows, T0, allowed=allowed)
        if int((b & ~inl).sum()) < 2 or b.sum() < need:
            continue
        if not _same_noise(cd, (inl, T), (b, Tb)) or not _holds_together(cd, b, ranked):
            continue
        if best is None or b.sum() > best[0].sum():
            best = (b, Tb)
    return best


def find_consensus(cd: CameraData, max_hypotheses: int = 400, seed: int = 0) -> Consensus | None:
    """The largest set of captures that agree with one pose (see the module doc); None when no
    hypothesis could be formed. Its ``clear`` is judged again on the final set by :func:`judge`."""
    ranked, tried = cores(cd, max_hypotheses, seed)
    if not ranked:
        return None
    _, rows, T0 = ranked[0]
    found = forward_search(cd, rows, T0)
    rival = _rival(cd, found, ranked)
    inl, T, cov = found
    if rival is not None and rival[0].sum() > inl.sum():  # the larger of two sets that hold together
        inl, T = rival[0], rival[1]
        T, cov = fit_subset(cd, inl, T)
    return Consensus(T, inl, cov, True, None, tried, None, ranked)


def judge(cd: CameraData, cons: Consensus, inl: np.ndarray, T: np.ndarray) -> Consensus:
    """The consensus with ``clear`` and ``rival`` judged on the final set ``inl`` at pose ``T``."""
    rival = _rival(cd, (inl, T, None), cons.ranked)
    return Consensus(T, inl, cons.cov, rival is None, None if rival is None else rival[0], cons.n_hypotheses,
                     None if rival is None else rival[1], cons.ranked)


def _ids(cd: CameraData, mask: np.ndarray) -> str:
    return ", ".join(c for c, m in zip(cd.capture_ids, mask) if m)


def no_consensus_phrase(cd: CameraData, cons: Consensus) -> str:
    """What to say when two different sets of captures each agree with a pose (one phrase, every shell)."""
    rival = cons.rival if cons.rival is not None else np.zeros(len(cd), bool)
    return (f"{cd.name}: {NO_CONSENSUS}: captures {_ids(cd, cons.inliers)} agree with one pose and "
            f"{_ids(cd, rival)} with another, about as many and as tightly; the pose shown uses the first and may "
            f"be wrong: check these detections (wrong sphere found?) or add captures")
