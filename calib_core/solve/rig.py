"""Two (or more) cameras: joint solve tied by the stereo transform, and the paper's Table I.

Joint solve: the reference camera's ``T_ref_sonar`` is free, every other camera's pose is
``T_cam_ref @ T_ref_sonar`` with ``T_cam_ref`` held at the measured stereo transform (no
covariance) or pulled to it by a prior with the given covariance. A capture seen by both
cameras is one 4-vector measurement, so the shared sonar noise is counted once. With the
stereo baseline known metrically the sonar range scale becomes observable.

Table I (paper, Section VI): per camera-sonar pair the estimated length ``|t|`` of the
independent solve against the tape-measured one; the associative translation ``t-hat`` from
chaining the other camera's solve with the stereo transform; ``|t - t-hat|`` and the angle
between them. Lengths in metres, angles in radians (the reports print mm and degrees).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from calib_core.geometry import invert_T
from calib_core.stereo.chain import compose_with_cov, invert_with_cov
from calib_core.solve.model import RigState, per_camera_stats
from calib_core.solve.refine import (Link, RigProblem, covariance_from_jacobian, jacobian, pose_covariance, refine,
                                     weights_for)
from calib_core.solve.systematic import systematic_term
from calib_core.solve.scale import choose_scale, scale_mode
from calib_core.solve.stereo_factor import stereo_factor, widened
from calib_core.solve.single import CameraSolution
# (the assumed stereo covariance lives with the stated one: the stereo vouching of detections uses it too,
# so it is part of the detector fingerprint; re-exported here for the solver's callers)
from calib_core.solve.stereo_cov import DEFAULT_STEREO_SIGMA_M, DEFAULT_STEREO_SIGMA_RAD, default_stereo_cov  # noqa: F401

def cov_of_inverse(T_a_b: np.ndarray, cov_ab: np.ndarray) -> np.ndarray:
    """6x6 covariance of ``T_b_a`` from that of ``T_a_b`` (the solver's perturbation; see
    :func:`calib_core.stereo.chain.invert_with_cov`)."""
    return invert_with_cov(T_a_b, cov_ab)[1]


@dataclass
class RigSolution:
    """Joint calibration of several cameras to the sonar.

    Attributes:
        reference: the reference camera; cameras: names in solve order.
        T_cam_sonar, cov: {cam: 4x4}, {cam: 6x6 (rotation vector rad, translation m)}; the covariances
            are multiplied by max(1, variance_factor).
        T_cam_ref: {cam: 4x4} stereo transforms after the solve.
        scale, scale_sigma, scale_note: range scale (1 and None when not estimated) and why.
        rms_px: {cam: RMS reprojection px}; chi2, dof, variance_factor.
        mahalanobis: {cam: {capture: distance}} at the joint solution.
        cov_with_scale: {cam: 7x7 (pose, then scale)} when the scale was estimated.
    """

    reference: str
    cameras: list[str]
    T_cam_sonar: dict
    cov: dict
    T_cam_ref: dict
    scale: float
    scale_sigma: float | None
    scale_note: str
    rms_px: dict
    chi2: float
    dof: int
    variance_factor: float
    mahalanobis: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    cov_with_scale: dict = field(default_factory=dict)
    scale_observable: bool = False
    scale_test: dict | None = None
    scale_sigma_detections: float | None = None  # the scale's sigma were the stereo transforms exact
    stereo_factor: dict = field(default_factory=dict)  # the stereo block's variance factor (stereo_factor.py)


def solve_rig(solutions: dict[str, CameraSolution], links: dict[str, Link], reference: str,
              estimate_scale: bool | str | None = None, robust: str | None = None) -> RigSolution:
    """Joint solve of ``reference`` and every camera in ``links`` (starting from the single solves).

    ``estimate_scale``: None / "auto" (default) estimates the range scale when the F test of
    :mod:`calib_core.solve.scale` asks for it, True / "always" whenever observable, False holds it at 1."""
    names = [reference] + [n for n in links if n != reference]
    cams = [solutions[n].data for n in names]
    masks = [solutions[n].used for n in names]
    state = RigState(solutions[reference].T_cam_sonar, {reference: np.eye(4), **{n: links[n].T_cam_ref for n in names[1:]}})
    prob = RigProblem(cams, masks, {n: links[n] for n in names[1:]})
    res = refine(prob, state, robust=robust)
    warnings: list[str] = []
    prob_s = RigProblem(cams, masks, {n: links[n] for n in names[1:]}, estimate_scale=True)
    # the stereo block judged by the data (calib_core.solve.stereo_factor): widened when worse than stated
    factor, s_info, prob_s, res_s = stereo_factor(prob_s, res.state, robust)
    s_info["scale_held"] = scale_mode(estimate_scale) == "never"  # (no scale test: the phrase says so)
    if factor != 1.0:  # both models of the scale's test with the same stereo covariance
        prob = widened(prob, factor)
        res = refine(prob, res.state, robust=robust)
    # the scale's share of the model errors common to all captures (systematic.py: a sonar range
    # offset, a shading offset of the image centres) is not evidence of a scale error: the test
    # counts only the deviation beyond it, as the reported sigma includes it
    sys_var = float(systematic_term(prob_s, res_s.state, robust)[-1, -1])
    ch = choose_scale(prob, res, prob_s, scale_mode(estimate_scale), robust, sys_var, res_free=res_s)
    res, prob = ch.res, ch.problem
    note = ch.note
    vf = res.variance_factor if res.dof > 0 else 1.0
    # the stated covariance scaled by the variance factor, plus the model errors common to all captures
    res_c = dataclasses.replace(res, cov=res.cov * max(1.0, vf) + systematic_term(prob, res.state, robust))
    scale_sigma = math.sqrt(res_c.cov[-1, -1]) if ch.estimated else None
    sigma_det = None
    if ch.estimated and prob.free_links:
        var_stereo = stereo_share_of_scale(prob, res.state, robust) * res.cov[-1, -1] * max(1.0, vf)
        sigma_det = math.sqrt(max(0.0, scale_sigma ** 2 - var_stereo))
    Ts = {n: res.state.T_cam_sonar(n) for n in names}
    covs = {n: pose_covariance(prob, res_c, n) for n in names}
    covs7 = {n: pose_covariance(prob, res_c, n, with_scale=True) for n in names} if prob.estimate_scale else {}
    rms, mah = {}, {}
    for n, cd, m in zip(names, cams, masks):
        r_px, _, _, m2, _ = per_camera_stats(cd, Ts[n], res.state.scale)
        rms[n] = float(np.sqrt(np.mean(np.sum(r_px[m] ** 2, axis=1))))
        mah[n] = {cid: float(math.sqrt(v)) if math.isfinite(v) else math.inf for cid, v in zip(cd.capture_ids, m2)}
    return RigSolution(reference, names, Ts, covs, dict(res.state.T_cam_ref), res.state.scale, scale_sigma, note,
                       rms, res.chi2, res.dof, vf, mah, warnings, covs7, ch.observable, ch.test, sigma_det, s_info)


def stereo_share_of_scale(problem: RigProblem, state: RigState, robust: str | None = None) -> float:
    """Share of the range scale's variance (0-1) that the stereo transforms' stated uncertainty
    causes: 1 - var(scale | stereo exact) / var(scale), both from the information at ``state``.

    The scale is fixed metrically by the stereo baseline, so an uncertain stereo vergence or
    baseline length can dominate it; this says when it does."""
    if not problem.estimate_scale or not problem.free_links:
        return 0.0
    held = {n: Link(link.T_cam_ref, None) for n, link in problem.links.items()}
    exact = RigProblem(problem.cams, problem.masks, held, estimate_scale=True, use_ranges=len(problem.range_rows) > 0)
    var = []
    for prob in (problem, exact):
        Ws, _ = weights_for(prob, state, robust, 2.5)
        var.append(float(covariance_from_jacobian(jacobian(prob, state, Ws))[0][-1, -1]))
    return float(np.clip(1.0 - var[1] / var[0], 0.0, 1.0)) if var[0] > 0 else 0.0


def cov_of_product(T_a_b: np.ndarray, T_b_c: np.ndarray, cov_ab: np.ndarray, cov_bc: np.ndarray) -> np.ndarray:
    """6x6 covariance of ``T_a_c = T_a_b T_b_c`` from those of two independent factors (see
    :func:`calib_core.stereo.chain.compose_with_cov`)."""
    return compose_with_cov(T_a_b, cov_ab, T_b_c, cov_bc)[1]


def find_stereo(stereo: dict, a: str, b: str) -> np.ndarray | None:
    """``T_b_a`` from a dict of stereo transforms keyed ``T_<target>_<source>`` (inverting if needed)."""
    if f"T_{b}_{a}" in stereo:
        return np.asarray(stereo[f"T_{b}_{a}"], float)
    if f"T_{a}_{b}" in stereo:
        return invert_T(np.asarray(stereo[f"T_{a}_{b}"], float))
    return None


def _measured(measured: dict, a: str, b: str):
    for k in (f"{a}-{b}", f"{b}-{a}"):
        if k in measured:
            return float(measured[k])
    return None


def _length_sigma(t: np.ndarray, cov_t: np.ndarray | None):
    if cov_t is None:
        return None
    u = t / max(np.linalg.norm(t), 1e-12)
    return float(math.sqrt(max(u @ cov_t @ u, 0.0)))


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    c = float(a @ b / max(np.linalg.norm(a) * np.linalg.norm(b), 1e-15))
    return float(math.acos(min(1.0, max(-1.0, c))))


def table_i(T_cam_sonar: dict, a: str, b: str, T_b_a: np.ndarray | None, measured: dict,
            cov: dict | None = None) -> dict:
    """The paper's Table I for cameras ``a`` and ``b`` from independent solves.

    ``T_b_a`` is the stereo transform (None: only the baseline chained from the two sonar
    solves is given). Returns {"pairs": {"a-sonar": {...}, "b-sonar": {...}, "a-b": {...}}}.
    """
    cov = cov or {}
    pairs = {}
    Ta, Tb = T_cam_sonar[a], T_cam_sonar[b]
    for c, T, T_hat in ((a, Ta, None if T_b_a is None else invert_T(T_b_a) @ Tb),
                        (b, Tb, None if T_b_a is None else T_b_a @ Ta)):
        t = T[:3, 3]
        est = float(np.linalg.norm(t))
        meas = _measured(measured, c, "sonar")
        row = {"estimated_m": est, "estimated_sigma_m": _length_sigma(t, None if c not in cov else np.asarray(cov[c])[3:, 3:]),
               "measured_m": meas, "error_pct": None if meas is None else 100.0 * (est - meas) / meas,
               "assoc_m": None, "assoc_error_pct": None, "error_length_m": None, "included_angle_rad": None}
        if T_hat is not None:
            th = T_hat[:3, 3]
            row.update(assoc_m=float(np.linalg.norm(th)), assoc_error_pct=100.0 * (np.linalg.norm(th) - est) / est,
                       error_length_m=float(np.linalg.norm(t - th)), included_angle_rad=_angle(t, th))
        pairs[f"{c}-sonar"] = row
    chained = Tb @ invert_T(Ta)
    t_st = T_b_a[:3, 3] if T_b_a is not None else chained[:3, 3]
    est = float(np.linalg.norm(t_st))
    meas = _measured(measured, a, b)
    pairs[f"{a}-{b}"] = {"estimated_m": est, "source": "stereo transform" if T_b_a is not None else "chained sonar solves",
                         "chained_m": float(np.linalg.norm(chained[:3, 3])), "measured_m": meas,
                         "error_pct": None if meas is None else 100.0 * (est - meas) / meas}
    return {"cameras": [a, b], "pairs": pairs}
