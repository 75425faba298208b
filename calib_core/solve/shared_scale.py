"""One sonar range scale shared by several cameras that see it through the sphere's diameter.

Cameras without a stereo transform between them each observe the scale ``s`` only through the
sphere's apparent size (image ranges, see :mod:`calib_core.solve.scale`). The scale is one
parameter of the sonar, so it is estimated from all of them together:

- each camera c is fitted with ranges, once with ``s`` free (``s_c``, statistical variance
  ``V_cc``, ``chi2_free_c``) and once with ``s = 1``; when the session's range model says so,
  each camera's outline bias is a parameter of its fits (:mod:`calib_core.solve.outline`);
- the cameras' estimates are correlated: they use the same sonar centres, whose noise moves
  them all. ``V_cd = sum over shared captures of g_c^T C_X g_d`` with ``g_c = d s_c / d X`` (first
  order, from each fit's Jacobian);
- to first order the fit with one shared ``s`` is the generalised least-squares mean
  ``s = 1^T V^-1 s_c / 1^T V^-1 1``, ``chi2_shared = sum chi2_free_c + (s_c - s)^T V^-1 (s_c - s)``;
- the stated test is the same likelihood-ratio F test as one camera's
  (``F = (s - 1)^2 1^T V^-1 1 / v`` with ``v = chi2_shared / dof``), deflated by the diameter's
  tolerance, which is a systematic common to all cameras (every range is proportional to the one
  assumed diameter), so it does not average down with more cameras;
- sigma of ``s``: ``sqrt(v_+ / 1^T V^-1 1 + (diameter_sigma / diameter)^2)`` with ``v_+ = max(1, v)``;
- the cameras' agreement is tested too (``b = (s_c - s)^T V^-1 (s_c - s) / (n - 1)``,
  ``b / v ~ F(n-1, dof)``); when they disagree at the same level, ``v`` is replaced by ``b`` in
  the test and the sigma (the scatter between cameras is then the scale's noise level) and the
  note says so.

When the scaled model is chosen every camera's pose is refitted with ranges at the shared ``s``;
its covariance adds the uncertainty of ``s`` through the pose's correlation with it, and the
diameter's systematic through a finite-difference rerun with every range lengthened.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from calib_core.solve.model import CameraData, RigState, log_so3
from calib_core.solve.outline import OutlineRangeProblem, RangeModel, outline_phrase, outline_summary, with_outline
from calib_core.solve.refine import RigProblem, jacobian, refine, weights_for
from calib_core.solve.scale import MAX_SCALE_SIGMA, SCALE_TEST_ALPHA, scale_observability


@dataclass
class CameraScaleFit:
    """One camera's fits with ranges: free scale (value, statistical variance, pose-scale gain) and s = 1."""

    name: str
    cd: CameraData
    used: np.ndarray
    state: RigState
    s: float
    var: float
    gain: np.ndarray  # d pose / d s at fixed data (cov_ps / cov_ss), rotation rad then translation m
    chi2_free: float
    dof_free: int
    chi2_fixed: float
    model: RangeModel | None = None  # estimates the camera's outline bias when it says so
    outline: dict | None = None  # the outline bias of the free-scale fit (outline_summary)
    sonar_gain: dict | None = None  # capture id -> d s / d (sonar centre) (3,), for cross-covariances


def _sonar_gains(prob: RigProblem, res, robust) -> dict:
    """d s_hat / d X_k for every used capture k (first order, weights held): the scale's row of
    -(J^T J)^-1 J^T times d r / d X_k, which is the translation columns of the capture's rows
    times R / s (a sonar centre enters only through R X / s + t)."""
    Ws, _ = weights_for(prob, res.state, robust, 2.5)
    J = jacobian(prob, res.state, Ws)
    h = -(res.cov @ J.T)[-1]
    A = res.state.T_ref_sonar[:3, :3] / res.state.scale
    out, row = {}, 0
    rows: dict[str, list[int]] = {}
    for g in prob.groups:
        width = 2 * len(g.cams)
        for i, cid in enumerate(g.ids):
            rows.setdefault(cid, []).extend(range(row + width * i, row + width * (i + 1)))
        row += width * len(g.ids)
    row += 6 * len(prob.free_links)
    cd = prob.cams[0]
    for i, r in enumerate(prob.range_rows):
        rows.setdefault(cd.capture_ids[r], []).append(row + i)
    for cid, rr in rows.items():
        out[cid] = (h[rr] @ J[rr, 3:6]) @ A
    return out


def _range_problem(cd: CameraData, used: np.ndarray, model: RangeModel | None, estimate_scale: bool) -> RigProblem:
    """The camera's problem with ranges: with an outline bias parameter when ``model`` estimates one."""
    if model is not None and model.estimates_outline:
        return OutlineRangeProblem(cd, used, model.sphere_radius_m, model.outline_sigma_px, estimate_scale)
    return RigProblem([cd], [used], estimate_scale=estimate_scale, use_ranges=True)


@dataclass
class SharedScale:
    """Outcome of :func:`shared_scale`: value, 1-sigma, chosen?, test, per-camera values, new poses."""

    value: float
    sigma: float
    estimated: bool
    test: dict
    per_camera: dict
    poses: dict  # cam -> (T_cam_sonar, 6x6 covariance) at the shared scale (only when estimated)
    note: str


def _fit_camera(name: str, cd: CameraData, used: np.ndarray, T_cam_sonar: np.ndarray, robust,
                model: RangeModel | None = None) -> CameraScaleFit | None:
    """Free-scale and s = 1 fits of one camera with ranges; None when it has no ranges or cannot see s."""
    if not cd.has_ranges(used):
        return None
    state0 = with_outline(RigState(T_cam_sonar, {name: np.eye(4)}), 0.0)
    fixed = refine(_range_problem(cd, used, model, False), state0, robust=robust)
    prob = _range_problem(cd, used, model, True)
    # a camera that sees the scale only weakly still adds to the others (the combined sigma decides)
    if not scale_observability(prob, fixed.state, max_sigma=math.inf)[0]:
        return None
    free = refine(prob, fixed.state, robust=robust)
    cov = free.cov
    o = outline_summary(prob, free) if isinstance(prob, OutlineRangeProblem) else None
    return CameraScaleFit(name, cd, used, free.state, free.state.scale, float(cov[-1, -1]), cov[:6, -1] / cov[-1, -1],
                          free.chi2, int(free.dof), fixed.chi2, model, o, _sonar_gains(prob, free, robust))


def _scale_covariance(fits: list[CameraScaleFit]) -> np.ndarray:
    """Covariance of the cameras' own scale estimates: each fit's variance on the diagonal, and
    off it what two cameras share, the sonar centres of the captures both used (their noise moves
    both estimates): sum over shared captures of g_1 C_X g_2."""
    V = np.diag([f.var for f in fits])
    for i, a in enumerate(fits):
        for j in range(i + 1, len(fits)):
            b = fits[j]
            if a.sonar_gain is None or b.sonar_gain is None:
                continue
            idx = {cid: k for k, cid in enumerate(a.cd.capture_ids)}
            c = sum(float(a.sonar_gain[cid] @ a.cd.cov_X_m2[idx[cid]] @ g) for cid, g in b.sonar_gain.items()
                    if cid in a.sonar_gain)
            V[i, j] = V[j, i] = c
    return V


def _combine(fits: list[CameraScaleFit], rel_sigma: float) -> tuple[float, float, dict]:
    """Weighted mean of the cameras' scales, its sigma and the F test of s = 1 (module doc)."""
    from scipy.special import fdtrc

    Vi = np.linalg.inv(_scale_covariance(fits))
    s_i = np.array([f.s for f in fits])
    w = Vi.sum(axis=1)
    s = float(w @ s_i / w.sum())
    var_stat = 1.0 / float(w.sum())
    spread = float((s_i - s) @ Vi @ (s_i - s))
    chi2_shared = sum(f.chi2_free for f in fits) + spread
    dof = sum(f.dof_free for f in fits) + len(fits) - 1
    v = chi2_shared / dof if dof > 0 else math.nan
    # cameras that disagree about s beyond their own noise (e.g. a bias of one camera's ranges):
    # the scatter between them, not the fits' noise, is then the noise level of s (Birge ratio)
    b = spread / (len(fits) - 1)
    p_spread = float(fdtrc(len(fits) - 1, dof, b / v)) if v > 0 else 1.0
    v_s = max(v, b) if p_spread < SCALE_TEST_ALPHA else v
    d = (s - 1.0) ** 2 / var_stat  # chi2 gained by freeing the shared scale (first order)
    F = d / v_s if v_s > 0 else math.inf
    if rel_sigma > 0 and math.isfinite(F):
        F *= v_s * var_stat / (v_s * var_stat + rel_sigma**2)
    p = float(fdtrc(1.0, dof, F)) if dof > 0 and math.isfinite(F) else 0.0
    sigma = math.sqrt(var_stat * max(1.0, v_s) + rel_sigma**2)
    test = {"name": "likelihood-ratio F test of scale = 1", "F": F, "dof": [1, int(dof)], "p_value": p,
            "level": SCALE_TEST_ALPHA, "max_sigma": MAX_SCALE_SIGMA,
            "scaled_model_chosen": p < SCALE_TEST_ALPHA and sigma <= MAX_SCALE_SIGMA,
            "cameras_agree_p_value": p_spread, "cameras_agree": p_spread >= SCALE_TEST_ALPHA}
    return s, sigma, test


def _pose_at(f: CameraScaleFit, s: float, robust, range_factor: float = 1.0):
    """Refit one camera with ranges (times ``range_factor``) at a fixed scale: (T_cam_sonar, 6x6 cov, vf)."""
    cd = f.cd if range_factor == 1.0 else dataclasses.replace(f.cd, range_m=f.cd.range_m * range_factor)
    st = with_outline(f.state)
    st.scale = s
    res = refine(_range_problem(cd, f.used, f.model, False), st, robust=robust)
    vf = res.variance_factor if res.dof > 0 else 1.0
    return res.state.T_ref_sonar, res.cov[:6, :6] * max(1.0, vf)


def _pose_shift(T0: np.ndarray, T1: np.ndarray) -> np.ndarray:
    return np.concatenate([log_so3(T1[:3, :3] @ T0[:3, :3].T), T1[:3, 3] - T0[:3, 3]])


def _poses(fits, s, sigma, rel_sigma, robust, eps=1e-3) -> dict:
    """Every camera's pose at the shared scale with the scale's and the diameter's uncertainty added."""
    var_stat = max(sigma**2 - rel_sigma**2, 0.0)
    fits_d = [_fit_camera(f.name, dataclasses.replace(f.cd, range_m=f.cd.range_m * (1 + eps)), f.used,
                          f.state.T_ref_sonar, robust, f.model) for f in fits] if rel_sigma > 0 else []
    s_d = _combine(fits_d, 0.0)[0] if fits_d and all(fits_d) else s
    out = {}
    for f in fits:
        T, cov = _pose_at(f, s, robust)
        cov = cov + np.outer(f.gain, f.gain) * var_stat
        if rel_sigma > 0:
            T_d, _ = _pose_at(f, s_d, robust, 1 + eps)
            g = _pose_shift(T, T_d) / eps
            cov = cov + np.outer(g, g) * rel_sigma**2
        out[f.name] = (T, cov)
    return out


def shared_scale(cams: dict, mode: str, rel_sigma: float, robust: str | None = None,
                 model: RangeModel | None = None) -> SharedScale | None:
    """One range scale from several cameras' diameter evidence (module doc).

    ``cams``: name -> (CameraData, used mask, T_cam_sonar of its s = 1 solve). ``mode``: "auto" or
    "always" (see :func:`calib_core.solve.scale.scale_mode`). ``rel_sigma``: the ranges' relative
    systematic common to all cameras. ``model``: when it estimates the outline bias, each camera
    fits its own (:mod:`calib_core.solve.outline`). None when fewer than two cameras carry ranges
    that see the scale (the one-camera route covers one)."""
    fits = [f for f in (_fit_camera(n, cd, u, T, robust, model) for n, (cd, u, T) in cams.items()) if f is not None]
    if len(fits) < 2:
        return None
    s, sigma, test = _combine(fits, rel_sigma)
    per = {f.name: {"value": f.s, "sigma": math.sqrt(f.var), **({"outline_bias": f.outline} if f.outline else {})}
           for f in fits}
    est = f"{s:.5f} ± {sigma:.5f}"
    names = " + ".join(f.name for f in fits)
    outlines = "; ".join(outline_phrase(f.name, f.outline) for f in fits if f.outline)
    if not test["cameras_agree"]:
        names += (" (they disagree: " + ", ".join(f"{f.name} {f.s:.4f}" for f in fits) +
                  f"; F test p = {test['cameras_agree_p_value']:.2g}; the sigma is widened to their scatter: check each "
                  f"camera's intrinsics and the sphere's apparent size)")
    estimated, note = _verdict(mode, test, names, est, sigma)
    note += f"; {outlines}" if outlines else ""
    if estimated:
        return SharedScale(s, sigma, True, test, per, _poses(fits, s, sigma, rel_sigma, robust), note)
    return SharedScale(1.0, sigma, False, test, per, {}, note)


def _verdict(mode: str, test: dict, names: str, est: str, sigma: float) -> tuple[bool, str]:
    """(scale applied?, the note saying why) from the F test and the mode."""
    if mode == "always" or test["scaled_model_chosen"]:
        why = "forced (--scale)" if not test["scaled_model_chosen"] else \
            f"the data show a scale error (F test p = {test['p_value']:.2g} < {SCALE_TEST_ALPHA:g})"
        return True, f"estimated from {names} together: {why}"
    if test["p_value"] < SCALE_TEST_ALPHA:  # a deviation, but known too poorly to apply
        return False, (f"kept at 1: {names} together put it at {est} (F test p = {test['p_value']:.2g}), but "
                       f"the sphere's apparent size gives the scale only to ±{100 * sigma:.1f} %, worse than the "
                       f"{100 * MAX_SCALE_SIGMA:g} % worth applying (--scale applies it)")
    return False, (f"kept at 1: {names} together show no scale error (free estimate {est}, F test p = "
                   f"{test['p_value']:.2g} >= {SCALE_TEST_ALPHA:g})")
