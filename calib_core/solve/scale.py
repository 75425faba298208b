"""Sonar range scale: is it observable, and does the data ask for it? (model selection)

Cloud ranges are ``s`` times the true ones (a sound-speed error). ``s`` is observable with two
cameras tied by a metric stereo transform, or with one camera whose detections give the
sphere's range from its apparent size (the known diameter). Whether to estimate it is decided
by a stated test, so a session without a scale error keeps the unscaled model's precision:

    F = (chi2_1 - chi2_s) / (chi2_s / dof_s)  ~  F(1, dof_s)   under "s = 1"

(the likelihood-ratio test of the nested models with the noise level taken from the data, so
stated sigmas that are too small or too large do not decide it). The scaled model is chosen
when ``p < SCALE_TEST_ALPHA``; ``mode="always"`` (the old ``--scale``) skips the test and
``mode="never"`` (``--no-scale``) holds ``s`` at 1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib_core.solve.refine import RigProblem, RefineResult, covariance_from_jacobian, jacobian, refine, weights_for

SCALE_TEST_ALPHA = 0.001
# Tolerance of the sphere's diameter when session.yaml gives no sphere.diameter_sigma: 1 mm
# (a float or ball measured with calipers or a tape to about a millimetre).
DEFAULT_DIAMETER_SIGMA_M = 0.001
# Tolerance of an outline's apparent radius on real photographs when session.yaml gives no
# sphere.outline_sigma_px: blur through the camera's gamma curve, JPEG and limb shading move a
# sphere's outline by a pixel or two (about +1.5 px on kinectnet-dev's k1), the same way on every
# capture of a camera. Each camera's outline bias is estimated with the scale
# (calib_core.solve.outline), this tolerance its prior: 2 px rather than 1 because a 1 px prior
# pulled a true 1.5 px bias measurably towards 0 (bench_scale, BENCHMARKS.md); held at 0
# (sphere.outline_sigma_px: 0) the ranges are taken as measured.
DEFAULT_OUTLINE_SIGMA_PX = 2.0
MAX_SCALE_SIGMA = 0.01  # a range scale known worse than 1 % is not worth estimating
MODES = ("auto", "always", "never")


def diameter_sigma(session) -> tuple[float, bool]:
    """(sphere.diameter_sigma in metres, assumed?) from session.yaml, else the default."""
    from calib_core.errors import SessionError

    v = ((session.raw or {}).get("sphere") or {}).get("diameter_sigma")
    if v is None:
        return DEFAULT_DIAMETER_SIGMA_M, True
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0 or \
            v > 0.5 * session.sphere_diameter_m:
        raise SessionError(session.manifest_path, f"sphere.diameter_sigma must be a tolerance in metres "
                                                  f"(0 to half the diameter), got {v!r}")
    return float(v), False


def outline_sigma_px(session) -> tuple[float, bool]:
    """(sphere.outline_sigma_px, assumed?) from session.yaml, else the default (see above)."""
    from calib_core.errors import SessionError

    v = ((session.raw or {}).get("sphere") or {}).get("outline_sigma_px")
    if v is None:
        return DEFAULT_OUTLINE_SIGMA_PX, True
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not 0 <= v <= 100:
        raise SessionError(session.manifest_path, f"sphere.outline_sigma_px must be a systematic outline error in "
                                                  f"pixels (0 to 100), got {v!r}")
    return float(v), False


def image_range_rel_sigma(diameter_m: float, diameter_sigma_m: float, outline_px: float, cd=None) -> float:
    """Relative systematic error of one camera's image ranges (sphere's apparent size): the
    diameter tolerance and the outline's systematic error (px) over the camera's median apparent
    radius (px), in quadrature. Without ranges (``cd`` None or no range_m), the diameter alone."""
    rel = diameter_sigma_m / diameter_m
    rng = None if cd is None or cd.range_m is None else np.asarray(cd.range_m, float)
    if rng is None or not np.isfinite(rng).any():
        return rel
    radius_px = cd.cam.fx * 0.5 * diameter_m / float(np.nanmedian(rng))
    return math.hypot(rel, outline_px / max(radius_px, 1e-6))


def range_rel_sigma(session, cd=None) -> float:
    """:func:`image_range_rel_sigma` with the session's diameter, tolerance and outline error."""
    return image_range_rel_sigma(session.sphere_diameter_m, diameter_sigma(session)[0], outline_sigma_px(session)[0], cd)


def range_model(session):
    """How the session's image ranges are modelled (:class:`calib_core.solve.outline.RangeModel`):
    the diameter's relative tolerance, the sphere's radius and the outline bias's tolerance."""
    from calib_core.solve.outline import RangeModel

    return RangeModel(diameter_sigma(session)[0] / session.sphere_diameter_m, session.sphere_radius_m,
                      outline_sigma_px(session)[0])


def scale_mode(estimate_scale) -> str:
    """Option value -> mode: None / "auto" -> auto, True / "always" -> always, False / "never" -> never."""
    if estimate_scale is None:
        return "auto"
    if isinstance(estimate_scale, bool):
        return "always" if estimate_scale else "never"
    if estimate_scale in MODES:
        return estimate_scale
    raise ValueError(f"estimate_scale must be one of {MODES}, True, False or None (got {estimate_scale!r})")


def scale_observability(problem: RigProblem, state, max_sigma: float = MAX_SCALE_SIGMA):
    """(observable, sigma of the scale, note) from the information matrix with the scale freed."""
    Ws, _ = weights_for(problem, state, None, 1.0)
    cov, eigmin = covariance_from_jacobian(jacobian(problem, state, Ws))
    sigma = math.sqrt(max(cov[-1, -1], 0.0))
    if eigmin < 1e-9:
        if len(problem.cams) == 1:
            return False, math.inf, ("not observable from one camera without ranges: scaling the sonar cloud about "
                                     "its origin looks the same to the camera as a longer or shorter camera-sonar "
                                     "translation (a second camera with its stereo transform, or image detections "
                                     "that record the sphere's range, make it observable)")
        return False, math.inf, "not observable from this data (the information matrix is singular)"
    if sigma > max_sigma:
        return False, sigma, (f"too weakly observable (1-sigma {100 * sigma:.2f} % > {100 * max_sigma:.1f} %): "
                              f"spread the sphere over a wider range of distances and the whole shared view")
    return True, sigma, f"observable (1-sigma {100 * sigma:.3f} %)"


@dataclass
class ScaleChoice:
    """Outcome of :func:`choose_scale`: the chosen fit and problem, and what to report."""

    res: RefineResult
    problem: RigProblem
    estimated: bool
    observable: bool
    note: str
    test: dict | None
    res_free: RefineResult | None = None  # the fit with the scale free, when one was made


# Sound-speed errors in water rarely exceed about 3 % (1450-1550 m/s against an assumed 1500 m/s)
SIZE_ROUTE_PLAUSIBLE = 0.03


def size_route_caution(value: float, estimated: bool) -> str:
    """"; a scale 6.1 % from 1 ..." when the sphere's apparent size puts the scale further from 1
    than a sound-speed error usually does: a camera's focal length off by as much reads the same."""
    if not estimated or abs(value - 1.0) <= SIZE_ROUTE_PLAUSIBLE:
        return ""
    return (f"; caution: a scale {100 * abs(value - 1.0):.1f} % from 1 is more than a sound-speed error usually "
            f"gives, and the apparent-size route reads a focal length off by as much the same way: check the "
            f"cameras' intrinsics, or hold it with --no-scale")


def stereo_limit_note(sigma: float | None, sigma_detections: float | None, assumed: bool) -> str:
    """"; the stereo transform limits it: ..." when the stereo transforms' uncertainty causes most
    of the scale's variance (the scale is tied to the stereo baseline), else ""."""
    if not sigma or sigma_detections is None or sigma_detections ** 2 > 0.5 * sigma ** 2:
        return ""
    how = ("its assumed uncertainty (no stereo_covariance in session.yaml)" if assumed else
           "its stated stereo_covariance")
    return (f"; the stereo transform limits it: ±{100 * sigma:.2f} % with {how}, ±{100 * sigma_detections:.2f} % "
            f"were it exact; a sharper stereo calibration, stated as stereo_covariance, sharpens the scale")


def lr_test(res_fixed: RefineResult, res_free: RefineResult, systematic_var: float = 0.0) -> dict:
    """F test of s = 1 against s free (see the module doc).

    ``systematic_var``: variance of the scale from a systematic the fit cannot see (the sphere
    diameter's tolerance, one camera; the model errors common to all captures, systematic.py, in
    a joint solve): the statistic is deflated by
    ``v sigma_s^2 / (v sigma_s^2 + systematic_var)``, so only a deviation beyond it counts."""
    from scipy.special import fdtrc  # scipy.stats takes seconds to import

    d = max(res_fixed.chi2 - res_free.chi2, 0.0)
    v = res_free.chi2 / res_free.dof if res_free.dof > 0 else math.nan
    F = d / v if v > 0 else math.inf
    if systematic_var > 0 and math.isfinite(F):
        stat = v * max(res_free.cov[-1, -1], 0.0)
        F *= stat / (stat + systematic_var)
    p = float(fdtrc(1.0, res_free.dof, F)) if res_free.dof > 0 and math.isfinite(F) else 0.0
    # a scale known worse than MAX_SCALE_SIGMA (its systematics included) is not applied on its own
    sigma = math.sqrt(max(v, 1.0) * max(res_free.cov[-1, -1], 0.0) + systematic_var) if math.isfinite(v) else math.inf
    return {"name": "likelihood-ratio F test of scale = 1", "F": F, "dof": [1, int(res_free.dof)], "p_value": p,
            "level": SCALE_TEST_ALPHA, "max_sigma": MAX_SCALE_SIGMA,
            "scaled_model_chosen": p < SCALE_TEST_ALPHA and sigma <= MAX_SCALE_SIGMA}


def choose_scale(prob_fixed: RigProblem, res_fixed: RefineResult, prob_free: RigProblem, mode: str,
                 robust: str | None = None, systematic_var: float = 0.0,
                 res_free: RefineResult | None = None) -> ScaleChoice:
    """Fit the scaled model when observable and pick between the two (see the module doc);
    ``res_free``: that fit when the caller has it already."""
    if mode == "never":
        return ScaleChoice(res_fixed, prob_fixed, False, False, "held at 1 (--no-scale)", None)
    ok, _, why = scale_observability(prob_free, res_fixed.state)
    if not ok:
        return ScaleChoice(res_fixed, prob_fixed, False, False, why, None)
    if res_free is None:
        res_free = refine(prob_free, res_fixed.state, robust=robust)
    test = lr_test(res_fixed, res_free, systematic_var)
    sig = math.sqrt(res_free.cov[-1, -1] * max(1.0, res_free.variance_factor) + systematic_var)
    est = f"{res_free.state.scale:.5f} ± {sig:.5f}"
    if mode == "always" or test["scaled_model_chosen"]:
        why = "forced (--scale)" if mode == "always" and not test["scaled_model_chosen"] else \
            f"the data show a scale error (F test p = {test['p_value']:.2g} < {SCALE_TEST_ALPHA:g})"
        return ScaleChoice(res_free, prob_free, True, True, f"estimated: {why}", test, res_free)
    if test["p_value"] < SCALE_TEST_ALPHA:  # a deviation, but known too poorly to apply
        return ScaleChoice(res_fixed, prob_fixed, False, True,
                           f"kept at 1: the data put it at {est} (F test p = {test['p_value']:.2g}), but only to "
                           f"±{100 * sig:.1f} %, worse than the {100 * MAX_SCALE_SIGMA:g} % worth applying "
                           f"(--scale applies it)", test, res_free)
    return ScaleChoice(res_fixed, prob_fixed, False, True,
                       f"kept at 1: the data show no scale error (free estimate {est}, F test p = "
                       f"{test['p_value']:.2g} >= {SCALE_TEST_ALPHA:g})", test, res_free)


def diameter_term(problem: RigProblem, res: RefineResult, rel_sigma: float, robust: str | None = None,
                  eps: float = 1e-3):
    """Covariance added to a fit that used camera ranges by the sphere diameter's tolerance.

    Every range is proportional to the assumed diameter, so a relative diameter error ``d``
    scales them all at once (a systematic, not averaged away): the fit is repeated with the
    ranges scaled by ``1 + eps`` and the parameter shift per unit ``d``, ``g``, gives
    ``g g^T rel_sigma^2`` (n x n, in the problem's parameter perturbation)."""
    import dataclasses

    import numpy as np

    from calib_core.solve.model import log_so3

    if hasattr(problem, "with_range_factor"):
        p2 = problem.with_range_factor(1.0 + eps)
    else:
        cd = problem.cams[0]
        cd2 = dataclasses.replace(cd, range_m=cd.range_m * (1.0 + eps))
        p2 = RigProblem([cd2], problem.masks, problem.links, estimate_scale=problem.estimate_scale,
                        use_ranges=len(problem.range_rows) > 0)
    r2 = refine(p2, res.state, robust=robust, max_outer=4)
    T0, T1 = res.state.T_ref_sonar, r2.state.T_ref_sonar
    d = np.concatenate([log_so3(T1[:3, :3] @ T0[:3, :3].T), T1[:3, 3] - T0[:3, 3]])
    if problem.estimate_scale:
        d = np.append(d, r2.state.scale - res.state.scale)
    g = d / eps
    return np.outer(g, g) * rel_sigma**2
