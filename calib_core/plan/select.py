"""Choose the next sphere positions: greedy sequential optimal design over the candidates.

Criteria (both in the solver's covariance model, per camera, cameras solved independently):
- ``"worst"`` (the default): minimise the worst axis 1-sigma over all cameras relative to the
  target (max of rotation sigma / target deg and translation sigma / target mm), ties broken by
  the D-gain. It aims straight at the stop rule and needs fewer captures (bench_plan.py).
- ``"d"`` (D-optimal): maximise the sum over cameras of the gain in log det of the 6x6 pose
  information (units do not matter: rotation and translation are weighed by the data).

The first suggestion is the best single next capture; the k-th is the best given the captures
taken *and* suggestions 1..k-1 (so "after" sigmas are cumulative), at least ``min_separation_m``
from all of them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib_core.camera import CameraModel
from calib_core.plan.candidates import Candidates
from calib_core.plan.information import capture_terms, logdet_gain, sigmas_deg_mm, updated_cov
from calib_core.plan.noise import NoiseModel
from calib_core.plan.target import Target

CRITERIA = ("d", "worst")
DEFAULT_CRITERION = "worst"  # fewer captures to the target in bench_plan.py (14.1 vs 16.2 on 60 rigs)


@dataclass
class CameraState:
    """One camera in the planner: intrinsics, current pose estimate and pose covariance (6x6,
    rotation vector rad then translation m, already multiplied by ``inflate``)."""

    name: str
    cam: CameraModel
    T_cam_sonar: np.ndarray
    cov: np.ndarray
    inflate: float = 1.0
    n_captures: int = 0


@dataclass
class Suggestion:
    """A suggested sphere centre and what it is predicted to give.

    uv_px / radius_px: {camera: centre pixel (2,), outline radius px} for the cameras that see it.
    sigma_after: {camera: (rotation deg (3,), translation mm (3,))} after this and the earlier suggestions.
    ratio_after: worst axis sigma / target over all cameras after it (<= 1: target met).
    """

    X_sonar_m: np.ndarray
    uv_px: dict
    radius_px: dict
    sigma_after: dict
    ratio_after: float
    gain: float


@dataclass
class Plan:
    """The planner's answer. ``current``: {camera: (rotation deg (3,), translation mm (3,))};
    ``ratio_now``: worst axis sigma / target now; ``met``: target met now."""

    criterion: str
    target: Target
    current: dict
    ratio_now: float
    met: bool
    suggestions: list = field(default_factory=list)
    n_candidates: int = 0
    notes: list = field(default_factory=list)


def _score(criterion: str, target: Target, covs: list, terms: list, vis: np.ndarray, alive: np.ndarray):
    """(score to maximise (N,), d-gain (N,)) for every candidate."""
    n = len(vis)
    gain = np.zeros(n)
    worst = np.zeros(n)
    for j, (C, (D, S)) in enumerate(zip(covs, terms)):
        g = np.where(vis[:, j], logdet_gain(C, D, S), 0.0)
        gain += g
        if criterion == "worst":
            after = np.where(vis[:, j], target.ratio(updated_cov(C, D, S)), target.ratio(C))
            worst = np.maximum(worst, after)
    score = gain if criterion == "d" else -worst + 1e-6 * gain
    return np.where(alive, score, -np.inf), gain


def _describe(states: list, covs: list, X: np.ndarray, vis_row: np.ndarray, radius_m: float,
              target: Target, gain: float) -> Suggestion:
    uv, rad, after = {}, {}, {}
    ratios = []
    for j, (st, C) in enumerate(zip(states, covs)):
        r, t = sigmas_deg_mm(C)
        after[st.name] = (r, t)
        ratios.append(float(target.ratio(C)))
        if vis_row[j]:
            P = st.T_cam_sonar[:3, :3] @ X + st.T_cam_sonar[:3, 3]
            uv[st.name] = st.cam.project(P[None])[0]
            rad[st.name] = float(st.cam.fx * radius_m / np.sqrt(max(P @ P - radius_m**2, 1e-12)))
    return Suggestion(X.copy(), uv, rad, after, max(ratios), float(gain))


def plan_next(states: list[CameraState], cands: Candidates, noise: NoiseModel, radius_m: float,
              target: Target = Target(), count: int = 3, criterion: str = DEFAULT_CRITERION,
              min_separation_m: float = 0.25) -> Plan:
    """Up to ``count`` suggestions (see the module doc) from the candidates."""
    if criterion not in CRITERIA:
        raise ValueError(f"criterion must be one of {CRITERIA}, got {criterion!r}")
    covs = [s.cov.copy() for s in states]
    current = {s.name: sigmas_deg_mm(s.cov) for s in states}
    ratio_now = max(float(target.ratio(s.cov)) for s in states)
    plan = Plan(criterion, target, current, ratio_now, ratio_now <= 1.0, n_candidates=len(cands.X_sonar_m))
    X = cands.X_sonar_m
    if len(X) == 0:
        plan.notes.append("no position both the sonar and a camera can see within the limits")
        return plan
    cov_X = noise.sonar_cov(X)
    terms = []
    for s in states:
        D, S = capture_terms(s.cam, s.T_cam_sonar, X, noise.cov_uv_px2, cov_X)
        terms.append((D, S * s.inflate))
    alive = np.ones(len(X), bool)
    for _ in range(count):
        score, gain = _score(criterion, target, covs, terms, cands.visible, alive)
        k = int(np.argmax(score))
        if not np.isfinite(score[k]):
            break
        for j, (D, S) in enumerate(terms):
            if cands.visible[k, j]:
                covs[j] = updated_cov(covs[j], D[k:k + 1], S[k:k + 1])[0]
        plan.suggestions.append(_describe(states, covs, X[k], cands.visible[k], radius_m, target, gain[k]))
        alive &= np.linalg.norm(X - X[k], axis=1) >= min_separation_m
    return plan
