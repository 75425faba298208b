"""Choose between image candidates ("two candidates") with the sonar's sphere centres.

An image alone cannot tell the target from another round thing of another size (a near
small ball looks like a far big one). But each candidate, read with the target's known
radius, is a 3D point in the camera frame (direction from the pixel, range r / sin(a)),
and the true candidates of all captures must match the sonar's sphere centres through one
rigid transform. A RANSAC 3D-3D registration over the candidates finds that transform and,
with it, which candidate of each ambiguous capture is the target.

Approximation: the range from the apparent size is good to a few per cent, so the gate is
loose (``tol = 0.05 * range + 0.03 m``); it only has to separate candidates, not calibrate.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib_core.camera import CameraModel


def candidate_points_cam_m(cam: CameraModel, uvr: np.ndarray) -> np.ndarray:
    """(K,3) camera-frame centres of candidates given as rows (u_px, v_px, range_m)."""
    uvr = np.asarray(uvr, float).reshape(-1, 3)
    return cam.rays(uvr[:, :2]) * uvr[:, 2:3]


def rigid_fit(X_sonar_m: np.ndarray, P_cam_m: np.ndarray) -> np.ndarray | None:
    """T_cam_sonar (4x4) minimising |R X + t - P| over >= 3 point pairs (Kabsch)."""
    cx, cp = X_sonar_m.mean(axis=0), P_cam_m.mean(axis=0)
    if np.linalg.matrix_rank(X_sonar_m - cx, tol=1e-3) < 2:
        return None
    from scipy.spatial.transform import Rotation  # lazy: scipy.spatial costs ~0.2 s at every CLI start

    R, _ = Rotation.align_vectors(P_cam_m - cp, X_sonar_m - cx)
    T = np.eye(4)
    T[:3, :3] = R.as_matrix()
    T[:3, 3] = cp - T[:3, :3] @ cx
    return T


@dataclass
class Resolution:
    """What the registration decided.

    chosen: {capture_id: index of the target among its candidates} (ambiguous captures only).
    predicted_uvr: {capture_id: (u_px, v_px, range_m)} where the target must be for captures
        whose candidates all miss the registration or stay undecided: a place to look again.
    T_cam_sonar: the rough registration (4x4), or None.
    support: captures with one candidate (a plain detection) that agree with the registration.
    residual_px: RMS distance (px) between those detections and the registration's projection of
        their sonar centres: how far off a prediction may be (NaN without such captures).
    range_rel_rms: RMS of (registered range / image range - 1) over the same captures: how well
        the registration predicts the apparent size.
    checks_px: {capture_id: px} for the rough candidates (partly hidden outlines) that agree with
        a registration fitted on exactly 3 plain detections: the distance between each outline's
        centre and the registration's projection (empty unless that case arises).
    sigma_px: {capture_id: px} for a registration on exactly 3 plain detections: how far its
        projection of that capture's sonar centre moves when each plain detection's range is off
        by RANGE_REL_SIGMA (root sum of squares), for the checks and the predicted places.
    rough_agree: rough candidates (partly hidden outlines) within the 3D tolerance of the
        registration: captures that agree with it without counting as ``support``.
    """

    chosen: dict = field(default_factory=dict)
    predicted_uvr: dict = field(default_factory=dict)
    T_cam_sonar: np.ndarray | None = None
    support: int = 0
    residual_px: float = float("nan")
    range_rel_rms: float = float("nan")
    checks_px: dict = field(default_factory=dict)
    sigma_px: dict = field(default_factory=dict)
    rough_agree: int = 0


def predict_places(out: Resolution, cam: CameraModel, T_cam_sonar: np.ndarray, centers_sonar_m: dict,
                    predict_for) -> None:
    """``out.predicted_uvr[c]`` = (u, v, range) where the registration puts capture ``c``'s
    sphere, for the captures in ``predict_for`` not yet predicted and inside the image."""
    for c in predict_for:
        if c in centers_sonar_m and c not in out.predicted_uvr:
            X_cam = T_cam_sonar[:3, :3] @ np.asarray(centers_sonar_m[c], float) + T_cam_sonar[:3, 3]
            uv = cam.project(X_cam[None])[0]
            if X_cam[2] > 0 and np.isfinite(uv).all() and cam.in_image(uv[None])[0]:
                out.predicted_uvr[c] = (float(uv[0]), float(uv[1]), float(np.linalg.norm(X_cam)))


def resolve_candidates(cam: CameraModel, centers_sonar_m: dict[str, np.ndarray],
                       candidates: dict[str, np.ndarray], iterations: int = 400,
                       seed: int = 0, predict_for=(), rough=(), range_free=()) -> Resolution:
    """Pick the target among each capture's image candidates.

    Args:
        cam: the camera's intrinsics.
        centers_sonar_m: {capture_id: (3,) sphere centre in the sonar frame, m}.
        candidates: {capture_id: (K,3) rows (u_px, v_px, range_m)}; K = 1 for a capture whose
            image detection was unambiguous.
        iterations: RANSAC hypotheses (3 captures, one candidate each).
        predict_for: capture ids (with a sonar centre) whose image gave no candidate at all:
            the registration predicts where to look again.
        rough: capture ids whose one candidate is rough (a partly hidden outline): it takes part
            in the consensus, but not in the refit of the registration nor in its ``support``.
        range_free: capture ids whose candidates' ranges are not measured (a look at the predicted
            place takes the predicted size: its range follows the registration that predicted
            it). Their uv is informative and their range is not: they agree when the registered
            centre lies near their ray (the same tolerance across it, none along it), enter the
            refit at the registered range along their ray, and stay out of ``range_rel_rms``.

    Returns:
        a :class:`Resolution`: the ambiguous captures (K > 1) that the registration decides
        clearly, and predicted places for those it cannot (an operator decides if a second
        look there finds nothing).
    """
    ids = [c for c in candidates if c in centers_sonar_m and len(candidates[c])]
    if len(ids) < 4:
        return Resolution()
    X = {c: np.asarray(centers_sonar_m[c], float) for c in ids}
    P = {c: candidate_points_cam_m(cam, candidates[c]) for c in ids}
    tol = {c: candidate_tolerances(candidates[c], c in set(range_free)) for c in ids}
    best_T, n_in = _ransac(ids, X, P, tol, iterations, seed)
    if best_T is None or n_in < 4:
        return Resolution()
    plain = [c for c in ids if c not in set(rough)]
    best_T = _refined(cam, best_T, plain, X, P, tol, candidates)
    best_T, checks_px = _checked_on_three(cam, best_T, plain, [c for c in ids if c in set(rough)], X, P, tol, candidates)
    out = Resolution(T_cam_sonar=best_T, checks_px=checks_px)
    fill_agreement(out, cam, plain, X, P, tol, candidates)
    out.rough_agree = len(single_inliers(best_T, [c for c in ids if c in set(rough)], X, P, tol))
    for c in ids:
        _decide(out, cam, c, best_T[:3, :3] @ X[c] + best_T[:3, 3], P[c], tol[c])
    predict_places(out, cam, best_T, centers_sonar_m, predict_for)
    if checks_px:
        targets = {c: np.asarray(centers_sonar_m[c], float) for c in {*checks_px, *out.predicted_uvr}}
        out.sigma_px = three_point_sigma_px(cam, best_T, single_inliers(best_T, plain, X, P, tol), X, P, targets)
    return out


def candidate_tolerances(uvr, range_free: bool) -> np.ndarray:
    """(K,2) per candidate: the tolerance across its ray and along it (m); along it none (inf)
    for a candidate whose range is not measured."""
    t = 0.05 * np.asarray(uvr, float).reshape(-1, 3)[:, 2] + 0.03
    return np.column_stack([t, np.full_like(t, np.inf) if range_free else t])


def _scaled(P_c: np.ndarray, X_cam: np.ndarray, tol_c: np.ndarray) -> np.ndarray:
    """(K,) distance of each candidate to the registered centre ``X_cam`` in units of its
    tolerance, across its ray and along it (isotropic when both tolerances are equal)."""
    diff = X_cam[None] - P_c
    ray = P_c / np.linalg.norm(P_c, axis=1, keepdims=True)
    along = np.sum(diff * ray, axis=1)
    across = np.linalg.norm(diff - along[:, None] * ray, axis=1)
    return np.sqrt((across / tol_c[:, 0]) ** 2 + (along / tol_c[:, 1]) ** 2)


def _fit_points(T: np.ndarray, inl, X, P, tol) -> np.ndarray:
    """The camera-frame points a refit on the plain detections ``inl`` aims at: each one's own
    candidate, or for a candidate whose range is not measured the point of its ray at the range
    of the registered centre (its uv counts, its range does not)."""
    out = []
    for c in inl:
        p = P[c][0]
        if np.isinf(tol[c][0, 1]):
            ray = p / np.linalg.norm(p)
            p = ray * float(ray @ (T[:3, :3] @ X[c] + T[:3, 3]))
        out.append(p)
    return np.array(out)


# how far off a plain detection's range (from the whole outline's apparent size) may be, 1 sigma:
# the registrations on kinectnet's real images agree with the image ranges to 1.1-2.3 % RMS, and
# that includes the registration's own error (BENCHMARKS.md, sixth round)
RANGE_REL_SIGMA = 0.015


def three_point_sigma_px(cam: CameraModel, T: np.ndarray, inl, X, P, targets: dict) -> dict:
    """{capture: px} how far the projection of each target's sonar centre moves when the refit on
    the 3 plain detections ``inl`` has one of their ranges RANGE_REL_SIGMA off (root sum of
    squares over the three)."""
    def project(T_):
        return {c: cam.project((T_[:3, :3] @ x + T_[:3, 3])[None])[0] for c, x in targets.items()}

    base, sq = project(T), {c: 0.0 for c in targets}
    for k in inl:
        T_k = rigid_fit(np.array([X[c] for c in inl]),
                         np.array([P[c][0] * (1 + RANGE_REL_SIGMA * (c == k)) for c in inl]))
        if T_k is None:
            return {c: float("inf") for c in targets}
        for c, uv in project(T_k).items():
            sq[c] += float(np.sum((uv - base[c]) ** 2))
    return {c: float(np.sqrt(v)) for c, v in sq.items()}


def single_inliers(T, ids, X, P, tol) -> list:
    """Captures with one candidate within tolerance of the registered sonar centre."""
    return [c for c in ids if len(P[c]) == 1 and _scaled(P[c], T[:3, :3] @ X[c] + T[:3, 3], tol[c])[0] <= 1.0]


def _refined(cam: CameraModel, T: np.ndarray, ids, X, P, tol, candidates) -> np.ndarray:
    """The registration refitted on every plain detection it agrees with (>= 4), else as given."""
    inl = single_inliers(T, ids, X, P, tol)
    if len(inl) < 4:
        return T
    T2 = rigid_fit(np.array([X[c] for c in inl]), _fit_points(T, inl, X, P, tol))
    return T if T2 is None else T2


def _checked_on_three(cam: CameraModel, T: np.ndarray, plain, rough, X, P, tol, candidates) -> tuple:
    """(T refitted on exactly 3 plain detections, {rough capture: px}) when the consensus ``T``
    agrees with exactly 3 plain detections and at least one rough candidate agrees with that
    refit; else (T, {}).

    A 3-point 3D-3D registration has no redundancy worth the name: its 3 residuals only check the
    3 pairwise distances, and a rotation about the line through two of the points (or a range
    error shared by all three) leaves them small while moving every other prediction. The partly
    hidden outlines are captures the refit never saw, at other places in the volume, so they test
    exactly what the prediction is used for: where a fourth sphere lands in the image. They stay
    out of the refit (their centres are rough; a refit on them put a 3.5 px centre into a solve).
    """
    inl = single_inliers(T, plain, X, P, tol)
    if len(inl) != 3 or not rough:
        return T, {}
    T3 = rigid_fit(np.array([X[c] for c in inl]), _fit_points(T, inl, X, P, tol))
    if T3 is None or len(single_inliers(T3, inl, X, P, tol)) != 3:
        return T, {}
    agree = single_inliers(T3, rough, X, P, tol)
    if not agree:
        return T, {}
    uv = cam.project(np.array([T3[:3, :3] @ X[c] + T3[:3, 3] for c in agree]))
    d = np.linalg.norm(uv - np.array([np.asarray(candidates[c], float)[0, :2] for c in agree]), axis=1)
    return T3, {c: float(v) for c, v in zip(agree, d)}


def fill_agreement(out: Resolution, cam: CameraModel, ids, X, P, tol, candidates) -> None:
    """Fill ``out.support`` and ``out.residual_px`` (see :class:`Resolution`)."""
    T = out.T_cam_sonar
    inl = single_inliers(T, ids, X, P, tol)
    out.support = len(inl)
    if inl:
        X_cam = np.array([T[:3, :3] @ X[c] + T[:3, 3] for c in inl])
        uv = cam.project(X_cam)
        d = np.linalg.norm(uv - np.array([np.asarray(candidates[c], float)[0, :2] for c in inl]), axis=1)
        out.residual_px = float(np.sqrt(np.mean(d ** 2)))
        measured = np.array([np.isfinite(tol[c][0, 1]) for c in inl])
        rel = np.linalg.norm(X_cam, axis=1) / np.array([float(np.asarray(candidates[c], float)[0, 2]) for c in inl]) - 1
        out.range_rel_rms = float(np.sqrt(np.mean(rel[measured] ** 2))) if measured.any() else float("nan")


def _ransac(ids: list, X: dict, P: dict, tol: dict, iterations: int, seed: int) -> tuple:
    """(best T_cam_sonar or None, its number of captures with a candidate within tolerance):
    hypotheses from 3 captures, one candidate each; ties broken by the lower summed distance."""
    rng = np.random.default_rng(seed)
    best_T, best_key = None, (-1, np.inf)
    tried = set()  # a hypothesis drawn again gives the same T and score: it cannot win (strict >)
    for _ in range(iterations):
        pick = rng.choice(len(ids), 3, replace=False)
        sel = [ids[i] for i in pick]
        choice = [rng.integers(len(P[c])) for c in sel]
        drawn = (*pick.tolist(), *(int(k) for k in choice))
        if drawn in tried:
            continue
        tried.add(drawn)
        T = rigid_fit(np.array([X[c] for c in sel]), np.array([P[c][k] for c, k in zip(sel, choice)]))
        if T is None:
            continue
        n_in, cost = 0, 0.0
        for c in ids:
            d = _scaled(P[c], T[:3, :3] @ X[c] + T[:3, 3], tol[c])
            n_in += bool(d.min() <= 1.0)
            cost += min(d.min(), 1.0)
        if (n_in, -cost) > (best_key[0], -best_key[1]):
            best_T, best_key = T, (n_in, cost)
    return best_T, best_key[0]


def _decide(out: Resolution, cam: CameraModel, c: str, X_cam: np.ndarray, P_c: np.ndarray, tol_c: np.ndarray) -> None:
    """Capture ``c``'s target among its candidates ``P_c`` given the registered sonar centre
    ``X_cam`` (into ``out.chosen``), or a place to look again (``out.predicted_uvr``)."""
    d = _scaled(P_c, X_cam, tol_c)
    order = np.argsort(d)
    if len(P_c) >= 2 and d[order[0]] <= 1.0 and d[order[1]] > 2.0:  # clearly one, clearly not the other
        out.chosen[c] = int(order[0])
    elif d[order[0]] > 1.0 or len(P_c) >= 2:
        uv = cam.project(X_cam[None])[0]
        if np.isfinite(uv).all() and cam.in_image(uv[None])[0]:
            out.predicted_uvr[c] = (float(uv[0]), float(uv[1]), float(np.linalg.norm(X_cam)))
