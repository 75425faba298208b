"""Sphere fits to sonar points: the beam-cone (blooming) model and two naive baselines.

Everything is in the sonar frame, metres, with the beams starting at the frame origin.

The cone model (derived in the module docs of :mod:`calib_core.detect.sonar.detect`): a beam with
centre-line direction ``d`` and half-angle ``h`` reports the first sphere return inside its
cone, placed along ``d``. With ``theta`` the angle between ``d`` and the sphere centre
direction and ``phi = max(theta - h, 0)`` the smallest angle inside the cone, the reported
range is ``rho(phi) = |c| cos(phi) - sqrt(r^2 - |c|^2 sin^2(phi))`` while
``|c| sin(phi) <= r`` (no return beyond that).

Residuals used by the fits (per point, range ``R`` and direction ``d`` measured):
- range residual ``R - rho(min(phi, phi_t))`` (``phi_t = asin(r/|c|)``, the limb), and
- angular residual ``R * max(phi - phi_t, 0)``: how far (metres, across the beam) a point lies
  outside the cone-widened silhouette, where the model predicts no return at all.
The naive baselines use the Euclidean distance to the sphere surface.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

MAD_TO_SIGMA = 1.4826
# the mean of the inner 80 % of |x| is 0.5586 sigma for Gaussian x
INNER_FRACTION = 0.8
INNER_MEAN_TO_SIGMA = 1.0 / 0.5586
STEPPED = 0.5  # MAD under this fraction of the trimmed spread: the ranges come in steps
# a return outside the (cone-widened) silhouette is kept as an inlier only within this many
# range-noise sigmas of it: the beam directions are exact, so what lies further out (a seat,
# a table, a stick under the ball) is not the sphere
OUTSIDE_SIGMAS = 1.0


def robust_sigma(dev: np.ndarray) -> float:
    """Gaussian-equivalent noise scale of deviations ``dev`` about zero: the MAD's, unless it is
    under STEPPED times the (scaled) mean of the inner 80 % of ``|dev|``, then that mean. The MAD
    collapses to 0 when the ranges come in steps (a stereo camera's quantised disparity puts most
    neighbours on the same step as their median); the trimmed mean sees the returns one step off.
    The two agree for Gaussian or heavy-tailed noise (Laplace: 1.03 vs 1.07 x its scale), so a
    sonar's or a LiDAR's noise stays the MAD's; NaN for no deviations."""
    a = np.abs(np.asarray(dev, float))
    if not len(a):
        return float("nan")
    inner = a[a <= np.quantile(a, INNER_FRACTION)]
    mad, trimmed = MAD_TO_SIGMA * float(np.median(a)), INNER_MEAN_TO_SIGMA * float(inner.mean())
    return mad if mad >= STEPPED * trimmed else trimmed


def _unit_rows(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    R = np.sqrt(np.einsum("ij,ij->i", P, P))
    return R, P / np.maximum(R, 1e-12)[:, None]


def angle_to_axis_rad(dirs: np.ndarray, axis_unit: np.ndarray) -> np.ndarray:
    """Angle (rad) between unit rows of ``dirs`` and a unit axis, accurate near zero."""
    cosv = dirs @ axis_unit
    perp = dirs - cosv[:, None] * axis_unit
    return np.arctan2(np.sqrt(np.einsum("ij,ij->i", perp, perp)), cosv)


def cone_first_return_range_m(dirs: np.ndarray, center_sonar_m, radius_m: float,
                              half_angle_rad: float) -> np.ndarray:
    """Range (m) a beam of centre-line direction ``dirs`` (N,3 unit) reports for a sphere.

    The first sphere return inside the beam's cone of half-angle ``half_angle_rad``; NaN
    where the cone misses the sphere. Sonar at the origin, outside the sphere.
    """
    c = np.asarray(center_sonar_m, float).reshape(3)
    cn = float(np.linalg.norm(c))
    theta = angle_to_axis_rad(np.asarray(dirs, float).reshape(-1, 3), c / cn)
    phi = np.maximum(theta - half_angle_rad, 0.0)
    s = cn * np.sin(phi)
    with np.errstate(invalid="ignore"):
        rho = cn * np.cos(phi) - np.sqrt(radius_m**2 - s**2)
    return np.where((s <= radius_m) & (phi < np.pi / 2), rho, np.nan)


def cone_residuals(center_sonar_m, radius_m: float, ranges_m: np.ndarray, dirs: np.ndarray,
                   half_angle_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """(range residual, angular residual) in metres for each point, see module docs."""
    a, b, _ = _cone_terms(np.asarray(center_sonar_m, float).reshape(3), radius_m, ranges_m, dirs,
                          half_angle_rad, False)
    return a, b


@dataclass
class FitResult:
    """One refined sphere fit (sonar frame, metres).

    center_m (3,), radius_m (the fixed or fitted radius), cov_center_m2 (3,3) from the
    Jacobian and the inlier residual variance, sigma_m (robust residual scale), inliers
    (bool over the points given), rms_m (inlier residual RMS), ok (solver converged to a
    finite answer), cov_radius_m2 (variance of a fitted radius, else 0).
    """

    center_m: np.ndarray
    radius_m: float
    cov_center_m2: np.ndarray
    sigma_m: float
    inliers: np.ndarray
    rms_m: float
    ok: bool
    cov_radius_m2: float = 0.0


def _cone_terms(x, radius_m, R, D, h, want_jac, chord_floor_m: float | None = None):
    """Cone-model residuals and, if asked, their Jacobian w.r.t. (c[, r]) (see module docs).

    ``chord_floor_m``: the half-chord ``S`` (how far the return lies in front of the sphere's
    plane through the centre, along the ray) enters the Jacobian as ``sqrt(S^2 + floor^2)``:
    the fit uses none (``S`` only kept off 0), its covariance the range noise (:func:`_cov_jacobian`)."""
    free = len(x) == 4
    c = np.asarray(x[:3], float)
    cn = max(float(np.linalg.norm(c)), 1e-9)
    r = min(abs(float(x[3] if free else radius_m)), 0.999 * cn)
    ch = c / cn
    cosv = D @ ch
    perp = D - cosv[:, None] * ch
    sinv = np.sqrt(np.einsum("ij,ij->i", perp, perp))
    theta = np.arctan2(sinv, cosv)
    phi = np.maximum(theta - h, 0.0)
    phi_t = float(np.arcsin(r / cn))
    L = float(np.sqrt(cn * cn - r * r))
    phc = np.minimum(phi, phi_t)
    S = np.sqrt(np.maximum(r * r - (cn * np.sin(phc)) ** 2, 0.0))
    rho = cn * np.cos(phc) - S
    ra = R - rho
    rb = R * np.maximum(phi - phi_t, 0.0)
    if not want_jac:
        return ra, rb, None
    n = len(R)
    # d theta / d c = -(d - cos(theta) ch) / (cn sin(theta)); irrelevant where phi == 0
    dth = -perp / (cn * np.maximum(sinv, 1e-12))[:, None]
    mid = (phi > 0) & (phi < phi_t)
    out = phi >= phi_t
    Ss = np.maximum(S, 1e-6) if chord_floor_m is None else np.sqrt(S * S + chord_floor_m**2)
    sp, cp = np.sin(phc), np.cos(phc)
    drho_dcn = np.where(mid, cp + cn * sp**2 / Ss, np.where(out, cn / L, 1.0))
    drho_dphi = np.where(mid, -cn * sp + cn * cn * sp * cp / Ss, 0.0)
    drho_dr = np.where(mid, -r / Ss, np.where(out, -r / L, -1.0))
    Ja = -(drho_dcn[:, None] * ch + drho_dphi[:, None] * dth)
    dpt_dcn = -r / (cn * L)
    Jb = np.where(out[:, None], R[:, None] * (dth - dpt_dcn * ch), 0.0)
    if free:
        Ja = np.c_[Ja, -drho_dr]
        Jb = np.c_[Jb, np.where(out, -R / L, 0.0)]
    return ra, rb, np.vstack([Ja, Jb]).reshape(2 * n, len(x))


def _resid_fn(model: str, P, R, D, h, radius_m):
    """(residual function, Jacobian function) of the parameters x = c or (c, r)."""
    if model == "cone":
        def f(x):
            a, b, _ = _cone_terms(x, radius_m, R, D, h, False)
            return np.concatenate([a, b])

        def jac(x):
            return _cone_terms(x, radius_m, R, D, h, True)[2]
    else:
        def f(x):
            rr = x[3] if len(x) == 4 else radius_m
            v = P - x[:3]
            return np.sqrt(np.einsum("ij,ij->i", v, v)) - rr

        def jac(x):
            v = P - x[:3]
            J = -v / np.maximum(np.sqrt(np.einsum("ij,ij->i", v, v)), 1e-12)[:, None]
            return np.c_[J, -np.ones(len(P))] if len(x) == 4 else J
    return f, jac


def _split(model: str, res: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    if model == "cone":
        return res[:n], res[n:]
    return res, np.zeros(n)


def fit_sphere(points_m: np.ndarray, center0_m, radius_m: float, model: str = "cone",
               free_radius: bool = False, half_angle_rad: float = 0.0,
               sigma0_m: float = 0.01, n_rounds: int = 3, warm: bool = False,
               loss: str = "soft_l1") -> FitResult:
    """Robust sphere fit to sonar points (sonar frame, metres).

    model: "cone" (beam-cone first-return model, see module docs) or "euclid" (distance to
    the sphere surface: the naive fit that ignores the beam width).
    free_radius: also fit the radius (``radius_m`` is then the start value).
    Rounds: a soft-L1 fit at scale ``sigma0_m``, then re-estimate the residual scale (MAD) and
    refit with a plain L2 loss on the points within 3 sigma (an approximation of the ML fit
    under Gaussian range noise with outliers removed). The covariance is
    ``sigma^2 (J^T J)^-1`` over the inliers.
    warm: the start is already good (e.g. a fit on a subset): skip the soft-L1 round and take
    the points within 3 ``sigma0_m`` of the start as the first inliers.
    loss: of the first round ("cauchy" rejects a large minority of outliers, such as the face
    of a block under the ball, more firmly than "soft_l1").
    """
    P = np.asarray(points_m, float).reshape(-1, 3)
    n = len(P)
    R, D = _unit_rows(P)
    x0 = np.r_[np.asarray(center0_m, float).reshape(3), radius_m] if free_radius else \
        np.asarray(center0_m, float).reshape(3).copy()
    npar = len(x0)
    if n < npar + 2:
        return FitResult(x0[:3], float(radius_m), np.full((3, 3), np.nan), np.nan,
                         np.zeros(n, bool), np.nan, False)
    f_all, j_all = _resid_fn(model, P, R, D, half_angle_rad, radius_m)
    sub = _Subset(model, P, R, D, half_angle_rad, radius_m, j_all)
    inl, first = np.ones(n, bool), 0
    if warm:  # the points within 3 sigma of the start are the first inliers
        ra, rb = _split(model, f_all(x0), n)
        inl = (np.abs(ra) <= 3 * sigma0_m) & (rb <= OUTSIDE_SIGMAS * sigma0_m)
        first = 1
        if inl.sum() < npar + 2:
            inl, first = np.ones(n, bool), 0
    x, sigma, inl, ok = _rounds(f_all, sub, x0, float(sigma0_m), inl, range(first, n_rounds), loss, n)
    return _result(f_all, sub, x, sigma, inl, ok, model, free_radius, radius_m, n)


class _Subset:
    """Residual functions of the fit restricted to a mask of the points."""

    def __init__(self, model, P, R, D, h, radius_m, j_all):
        self.args = (model, P, R, D, h, radius_m)
        self.j_all = j_all  # the Jacobian function over every point

    def __call__(self, mask):
        model, P, R, D, h, radius_m = self.args
        return _resid_fn(model, P[mask], R[mask], D[mask], h, radius_m)


def _rounds(f_all, sub: _Subset, x, sigma: float, inl, rounds, loss: str, n: int):
    """The fit's rounds (see fit_sphere): (x, sigma, inliers, ok)."""
    model = sub.args[0]
    npar = len(x)
    for k in rounds:
        if k == 0:
            sol = least_squares(f_all, x, jac=sub.j_all, loss=loss, f_scale=sigma,
                                x_scale=0.05, xtol=1e-6, ftol=1e-6, max_nfev=20)
        else:
            fs, js = sub(inl)
            sol = least_squares(fs, x, jac=js, x_scale=0.05, xtol=1e-6, ftol=1e-6, max_nfev=12)
        if not np.all(np.isfinite(sol.x)):
            return x, sigma, inl, False
        x = sol.x
        ra, rb = _split(model, f_all(x), n)
        core = rb == 0.0
        base = ra[core] if core.sum() >= npar + 2 else ra
        sigma = float(np.clip(MAD_TO_SIGMA * np.median(np.abs(base - np.median(base))), 5e-4, 0.1))
        thr = max(3.0 * sigma, 1e-3)
        new = (np.abs(ra) <= thr) & (rb <= max(OUTSIDE_SIGMAS * sigma, 1e-3))
        if new.sum() < npar + 2:
            return x, sigma, inl, False
        if k > 0 and np.array_equal(new, inl):
            break
        inl = new
    return x, sigma, inl, True


def _result(f_all, sub: _Subset, x, sigma, inl, ok, model, free_radius, radius_m, n) -> FitResult:
    """The FitResult of parameters ``x``: inlier RMS, covariance ``sigma^2 (J^T J)^-1``."""
    npar = len(x)
    ra, rb = _split(model, f_all(x), n)
    r_in = np.concatenate([ra[inl], rb[inl]]) if model == "cone" else ra[inl]
    m = int(inl.sum())
    rms = float(np.sqrt(np.mean(ra[inl] ** 2 + rb[inl] ** 2))) if m else np.nan
    cov = np.full((npar, npar), np.nan)
    if m >= npar + 2:
        J = _cov_jacobian(sub, inl, x, sigma)
        s2 = float(np.sum(r_in**2)) / max(m - npar, 1)
        try:
            cov = s2 * np.linalg.inv(J.T @ J)
        except np.linalg.LinAlgError:
            ok = False
    radius = float(x[3]) if free_radius else float(radius_m)
    return FitResult(x[:3].copy(), radius, cov[:3, :3], sigma, inl, rms,
                     ok and bool(np.all(np.isfinite(cov))),
                     float(cov[3, 3]) if free_radius else 0.0)


def _cov_jacobian(sub: _Subset, inl, x, sigma: float) -> np.ndarray:
    """The inliers' Jacobian the covariance is built from. For the cone model the half-chord
    ``S`` is floored by the range noise ``sigma`` (:func:`_cone_terms`): near the limb the
    range's sensitivity to the centre across the ray, ``|c| sin(phi) / S``, grows without bound
    as ``S`` -> 0, so a return grazing the fitted sphere would pin the centre across the ray
    far more tightly than its noise allows; the linearisation holds only where ``S`` is well
    above the noise. Monte Carlo on a clean sphere scanned by 16 rings (tests/test_sonar_cov.py):
    the spread across the ray was up to 1.4x (in variance) what the unfloored covariance
    stated, and within a few % of the floored one."""
    model, P, R, D, h, radius_m = sub.args
    if model != "cone":
        return sub(inl)[1](x)
    return _cone_terms(x, radius_m, R[inl], D[inl], h, True, chord_floor_m=float(sigma))[2]


def algebraic_sphere(points_m: np.ndarray) -> tuple[np.ndarray, float]:
    """Linear least-squares sphere through points: (centre (3,), radius); radius NaN if degenerate."""
    P = np.asarray(points_m, float)
    A = np.c_[2 * P, np.ones(len(P))]
    b = np.einsum("ij,ij->i", P, P)
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    c = sol[:3]
    r2 = sol[3] + c @ c
    return c, float(np.sqrt(r2)) if r2 > 0 else float("nan")


