"""A lopsided limb's share of the image centre's covariance.

A ball lit from one side meets its background with a strong, sharp step on one side and a weak
step on a shading ramp on the other (or, against a background as bright as its shaded side, no
step at all where the two cross). The located edges there lie up to a few px off the limb, and
the offset changes slowly around the outline. Its first harmonic moves the fitted centre (towards
the light) and leaves nothing in the residuals: the cone fit takes it into the centre. Its next
harmonics do show in the residuals. Taken as a smooth random deviation of the outline, the
unseen first harmonic is about as large as the seen second and third: the floor is
LOPSIDED_HARMONIC_FACTOR^2 x their mean power per component, less what the edges' noise
alone puts there.

Measured against the truth on side-lit balls (benchmarks/bench_limb_shift.py): the shift moves
with neither the first harmonic of the edge strength nor of the edge width by one factor across
scenes (the factor differs 5x between the canal session and the rendered side-lit balls, and
the lit-on-black dim kind follows neither), so the centre is not corrected; its covariance says
how far it may be off.
"""

from __future__ import annotations

import numpy as np
from scipy.special import gammaincinv  # not scipy.stats: it takes 0.3 CPU-s to import on every detection run

LOPSIDED_ORDERS = (2, 3)
LOPSIDED_HARMONIC_FACTOR = 1.0
# the harmonics count when their chi-square against the edges' scatter passes this point (2 dof an order)
LOPSIDED_SIGNIFICANCE = 0.99
# the chi-square quantile as scipy.stats.chi2.ppf computes it (2 x the inverse regularised gamma)
LOPSIDED_SIGNIFICANCE_CHI2 = float(2.0 * gammaincinv(len(LOPSIDED_ORDERS), LOPSIDED_SIGNIFICANCE))


def harmonic_fit(residuals_px: np.ndarray, angles_rad: np.ndarray, orders=LOPSIDED_ORDERS):
    """(coefficients px (2 len(orders),), their covariance per unit residual variance) of the
    outline residuals' harmonics ``orders`` (least squares over the points seen, with the constant
    and the first harmonic, which the cone fit took into its radius and centre, fitted alongside);
    None with too few points. On an arc the columns are nearly collinear: the covariance says how
    much the fit amplifies the edges' noise there (2 / N per component on a whole outline)."""
    r = np.asarray(residuals_px, float)
    th = np.asarray(angles_rad, float)
    ok = np.isfinite(r) & np.isfinite(th)
    cols = [np.ones(ok.sum()), np.cos(th[ok]), np.sin(th[ok])]
    for k in orders:
        cols += [np.cos(k * th[ok]), np.sin(k * th[ok])]
    if ok.sum() < 2 * len(cols):
        return None
    A = np.column_stack(cols)
    coef, *_ = np.linalg.lstsq(A, r[ok], rcond=None)
    return coef[3:], np.linalg.pinv(A.T @ A)[3:, 3:]


def harmonic_power_px2(residuals_px: np.ndarray, angles_rad: np.ndarray, orders=LOPSIDED_ORDERS) -> float:
    """Mean power per component (px^2) of the outline residuals' harmonics ``orders``
    (:func:`harmonic_fit`); 0 with too few points."""
    fit = harmonic_fit(residuals_px, angles_rad, orders)
    return 0.0 if fit is None else float(np.mean(fit[0] ** 2))


def lopsided_floor_px2(residuals_px: np.ndarray, angles_rad: np.ndarray, edge_rms_px: float,
                       corr_points: float) -> float:
    """Variance (px^2) per image axis of the centre from a lopsided limb: the outline residuals'
    (px, inliers) harmonics LOPSIDED_ORDERS at the edges' angles around the outline (rad), less
    the power the edges' own scatter (``edge_rms_px``, correlated over ``corr_points``
    neighbours) puts in one component (2 sigma^2 c / N on a whole outline, more on an arc), x
    LOPSIDED_HARMONIC_FACTOR^2; 0 unless the harmonics stand out from that scatter
    (LOPSIDED_SIGNIFICANCE_CHI2): on a partly hidden outline the noise alone, amplified by the
    nearly collinear harmonics, would otherwise leave a floor of px."""
    fit = harmonic_fit(residuals_px, angles_rad)
    if fit is None:
        return 0.0
    coef, unit_cov = fit
    noise_px2 = edge_rms_px ** 2 * max(corr_points, 1.0)
    if noise_px2 > 0.0 and float(coef @ np.linalg.pinv(unit_cov) @ coef) < LOPSIDED_SIGNIFICANCE_CHI2 * noise_px2:
        return 0.0
    noise = noise_px2 * float(np.mean(np.diag(unit_cov)))
    return float(LOPSIDED_HARMONIC_FACTOR ** 2 * max(0.0, float(np.mean(coef ** 2)) - noise))
