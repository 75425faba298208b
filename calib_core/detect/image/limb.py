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

LOPSIDED_ORDERS = (2, 3)
LOPSIDED_HARMONIC_FACTOR = 1.0


def harmonic_power_px2(residuals_px: np.ndarray, angles_rad: np.ndarray, orders=LOPSIDED_ORDERS) -> float:
    """Mean power per component (px^2) of the outline residuals' harmonics ``orders`` (least
    squares over the points seen, with the constant and the first harmonic, which the cone fit
    took into its radius and centre, fitted alongside); 0 with too few points."""
    r = np.asarray(residuals_px, float)
    th = np.asarray(angles_rad, float)
    ok = np.isfinite(r) & np.isfinite(th)
    cols = [np.ones(ok.sum()), np.cos(th[ok]), np.sin(th[ok])]
    for k in orders:
        cols += [np.cos(k * th[ok]), np.sin(k * th[ok])]
    if ok.sum() < 2 * len(cols):
        return 0.0
    coef, *_ = np.linalg.lstsq(np.column_stack(cols), r[ok], rcond=None)
    return float(np.mean(coef[3:] ** 2))


def lopsided_floor_px2(residuals_px: np.ndarray, angles_rad: np.ndarray, edge_rms_px: float,
                       corr_points: float) -> float:
    """Variance (px^2) per image axis of the centre from a lopsided limb: the outline residuals'
    (px, inliers) harmonics LOPSIDED_ORDERS at the edges' angles around the outline (rad), less
    the power the edges' own scatter (``edge_rms_px``, correlated over ``corr_points``
    neighbours) puts in one component (2 sigma^2 c / N), x LOPSIDED_HARMONIC_FACTOR^2."""
    n = int(np.isfinite(np.asarray(residuals_px, float)).sum())
    if n == 0:
        return 0.0
    noise = 2.0 * edge_rms_px ** 2 * max(corr_points, 1.0) / n
    return float(LOPSIDED_HARMONIC_FACTOR ** 2 * max(0.0, harmonic_power_px2(residuals_px, angles_rad) - noise))
