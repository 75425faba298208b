"""The sphere centre a range detection states, and its covariance: what one cone fit misses.

A cone fit's covariance (:func:`calib_core.detect.sonar.fit.fit_sphere`) is that of its model
with the beam width taken as known. The width is the session's estimate
(:mod:`calib_core.detect.sonar.beam`), one number for every capture, and what holds the ball
(a seat, a table, a hand next to its outline) can make it read a small footprint where the
sensor has none (an RGB-D camera or a LiDAR estimated at 0.05-0.12 deg). A footprint that is not
there moves the centre by 1-4 mm along the ray and across it, many times the fit's stated sigma
(`benchmarks/bench_range_cov.py`: squared Mahalanobis 30-80 on those captures).

So the capture's own returns are asked: the cone fit with the session's footprint and one
without any are both made on the returns the detection uses, and weighed by how well each
explains them (Bayesian model averaging over the two: weights ``exp(-cost / 2)`` of the
truncated quadratic cost in units of the fit's range noise, the width scan's cost). The
centre is the weighted mean, the covariance the weighted covariances plus the spread of the
two centres. A sonar's metre-wide blooming is explained only by its footprint (cost without it
several hundred higher: weight 1, nothing changes); a footprint the ball's returns do not
show gives way to none; where the two explain the returns about equally, the covariance
carries the difference between them.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from calib_core.detect.sonar.fit import FitResult, cone_residuals, fit_sphere

TRUNCATE_SIGMAS = 3.0  # the cost's truncation, as in the width scan (sonar.beam._WidthScan)
QUICK_POINTS = 300  # returns of the first look (every k-th of the fit's inliers)
NO_WEIGHT = 1e-9  # a weight under this on the first look ends the comparison


def truncated_cost(X: np.ndarray, center_m, radius_m: float, h: float, scale_m: float) -> float:
    """Sum over the returns ``X`` of min(|cone residual| / scale, 3)^2 (the width scan's cost)."""
    R = np.linalg.norm(X, axis=1)
    a, b = cone_residuals(center_m, radius_m, R, X / R[:, None], h)
    return float(np.sum(np.minimum(np.hypot(a, b) / scale_m, TRUNCATE_SIGMAS) ** 2))


def footprint_averaged(X: np.ndarray, fit: FitResult, h: float, free_radius: bool) -> FitResult:
    """``fit`` (a cone fit with half-angle ``h`` to the crop ``X``) with its centre and
    covariance averaged with those of the fit without a footprint on the same returns (module
    doc). Unchanged when ``h`` is 0, or when the fit without a footprint fails, or when a first
    look on at most QUICK_POINTS of the returns already gives it no weight (a sonar's blooming:
    the full comparison is then not needed; it would only make the footprint's weight surer)."""
    if h <= 0 or not fit.ok or fit.inliers.sum() < 5:
        return fit
    Xi = X[fit.inliers]
    if len(Xi) > QUICK_POINTS:
        quick = _weighed(Xi[::int(np.ceil(len(Xi) / QUICK_POINTS))], fit, h, free_radius)
        if quick is None or quick[0][1] < NO_WEIGHT:
            return fit
    both = _weighed(Xi, fit, h, free_radius)
    if both is None:
        return fit
    w, zero = both
    C = np.stack([fit.center_m, zero.center_m])
    mean = w @ C
    dev = C - mean
    cov = w[0] * fit.cov_center_m2 + w[1] * zero.cov_center_m2 + np.einsum("k,ki,kj->ij", w, dev, dev)
    return replace(fit, center_m=mean, cov_center_m2=cov)


def _weighed(Xi: np.ndarray, fit: FitResult, h: float, free_radius: bool):
    """(weights (2,) of the footprint's fit and of the fit without one on the returns ``Xi``, the
    latter fit), or None when it fails."""
    scale = max(float(fit.sigma_m), 1e-4)
    zero = fit_sphere(Xi, fit.center_m, fit.radius_m, model="cone", half_angle_rad=0.0,
                      free_radius=free_radius, sigma0_m=scale, n_rounds=3, warm=True)
    if not zero.ok:
        return None
    cost = np.array([truncated_cost(Xi, fit.center_m, fit.radius_m, h, scale),
                     truncated_cost(Xi, zero.center_m, zero.radius_m, 0.0, scale)])
    w = np.exp(-0.5 * (cost - cost.min()))
    return w / w.sum(), zero
