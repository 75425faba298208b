"""Effective beam width of the range sensor, estimated from all sphere scans of a session.

The cone model (:mod:`calib_core.detect.sonar_fit`) needs the beam's half-angle. The nominal
width (BV5000: 1 deg) is where the beam pattern drops by 3 dB; what matters for blooming is
the angle out to which a strong target is still detected, which depends on the target's
strength and the detection threshold. And the "sonar" may be a LiDAR or an RGB-D camera with
(almost) no footprint at all. So it is estimated: for each candidate width, from 0 up to 1.6 x
the nominal one, every capture's sphere is refitted (known radius) and the width whose fits
explain the returns best (smallest total truncated-quadratic residual cost over all captures)
wins. One width is shared by the whole session, so a handful of captures pin it well while
one capture alone would not.

Approximation: the cone is taken circular and uniform (no beam pattern weighting).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib_core.detect.sonar import detect_sphere_in_cloud
from calib_core.detect.sonar_fit import cone_residuals, fit_sphere
from calib_core.detect.sonar_search import crop_ball

MIN_CAPTURES = 3
MAX_CAPTURES = 12  # spheres used (spread over the session): enough to pin one shared width
# multiples of the nominal width scanned: down to 0 (a LiDAR's or RGB-D camera's footprint)
DEFAULT_FACTORS = tuple(np.round(np.r_[0.0, 0.05, np.arange(0.1, 1.601, 0.1)], 3))
# the smallest width returned: a LiDAR's beam divergence; also keeps 0 from reading as "unset"
MIN_WIDTH_DEG = 0.001
# a footprint is adopted only when it explains the returns clearly better than none: the total
# cost must drop by more than this fraction (range scatter at a LiDAR's or RGB-D camera's
# limb, and things touching the ball, lower it by ~1 % at a few hundredths of a degree)
ZERO_WIDTH_MARGIN = 0.02


@dataclass
class BeamWidthEstimate:
    """beam_width_deg: the estimate (the nominal one when it cannot be estimated, then
    ``reason`` says why); n_captures used; factors and costs: the scanned multiples of the
    nominal width and their total cost (for plots and reports)."""

    beam_width_deg: float
    nominal_deg: float
    n_captures: int
    reason: str = ""
    factors: list = field(default_factory=list)
    costs: list = field(default_factory=list)


def estimate_beam_width_deg(clouds_sonar_m: list, sphere_radius_m: float,
                            nominal_deg: float = 1.0, centers_sonar_m: list | None = None,
                            factors=None, progress=None) -> BeamWidthEstimate:
    """Estimate the effective beam width (deg) from the sphere scans of one session.

    Args:
        clouds_sonar_m: list of (N_i,3) clouds (sonar frame, m), one per capture.
        sphere_radius_m: the sphere's radius (m).
        nominal_deg: the sonar's stated beam width.
        centers_sonar_m: optional sphere centres (m) per cloud (None entries: detect them);
            e.g. operator-validated detections.
        factors: multiples of the nominal width to scan (default 0, 0.05, 0.1 ... 1.6).
        progress: optional ``progress(done, total, label)``.
    """
    r = float(sphere_radius_m)
    factors = np.asarray(DEFAULT_FACTORS if factors is None else factors, float)
    h0 = np.radians(nominal_deg) / 2.0
    crops, sigmas = [], []
    n = len(clouds_sonar_m)
    for k, i in enumerate(_spread_order(n)):
        if len(crops) >= MAX_CAPTURES:
            break
        P = np.asarray(clouds_sonar_m[i], float).reshape(-1, 3)
        c = None if centers_sonar_m is None else centers_sonar_m[i]
        if c is None:
            det = _detect_any_width(P, r, nominal_deg)
            if det is None:
                continue
            c, sig = det.center_sonar_m, det.extras.get("sigma_range_m", 0.005)
        else:
            sig = 0.005
        X = P[crop_ball(P, np.asarray(c, float), 1.6 * r + np.linalg.norm(c) * np.tan(h0) + 0.05)]
        if len(X) >= 12:
            crops.append((X, np.asarray(c, float)))
            sigmas.append(float(sig))
        if progress is not None:
            progress(k + 1, n + len(factors), "beam width: captures")
    if len(crops) < MIN_CAPTURES:
        return BeamWidthEstimate(float(nominal_deg), float(nominal_deg), len(crops),
                                 f"needs at least {MIN_CAPTURES} detected spheres")
    scale = max(float(np.median(sigmas)), 1e-3)
    costs = []
    for k, f in enumerate(factors):
        h = h0 * f
        total = 0.0
        for j, (X, c) in enumerate(crops):
            fit = fit_sphere(X, c, r, model="cone", half_angle_rad=h, sigma0_m=scale)
            cc = fit.center_m if fit.ok else c
            R = np.linalg.norm(X, axis=1)
            a, b = cone_residuals(cc, r, R, X / R[:, None], h)
            total += float(np.sum(np.minimum(np.hypot(a, b) / scale, 3.0) ** 2))
        costs.append(total)
        if progress is not None:
            progress(n + k + 1, n + len(factors), "beam width: scan")
    costs = np.asarray(costs)
    b = int(np.argmin(costs))
    best = float(factors[b])
    if 0 < b < len(factors) - 1:  # parabola through the minimum and its neighbours
        best = _parabola_vertex(factors[b - 1:b + 2], costs[b - 1:b + 2])
    if factors[0] == 0 and costs[0] <= (1.0 + ZERO_WIDTH_MARGIN) * costs[b]:
        best = 0.0  # no footprint explains the returns as well: do not invent one
    reason = "" if b < len(factors) - 1 else "at the edge of the scanned range"
    best = max(best * float(nominal_deg), MIN_WIDTH_DEG)
    return BeamWidthEstimate(best, float(nominal_deg), len(crops), reason,
                             [float(f) for f in factors], [float(c) for c in costs])


def _detect_any_width(P: np.ndarray, r: float, nominal_deg: float):
    """The sphere found with the nominal width, else with none (an optical sensor), else None."""
    for width in (nominal_deg, 0.0):
        det = detect_sphere_in_cloud(P, r, width)
        if det.found:
            return det
    return None


def _parabola_vertex(x, y) -> float:
    """Abscissa of the vertex of the parabola through three points (x ascending, y[1]
    smallest), kept within [x[0], x[2]]."""
    (x0, x1, x2), (y0, y1, y2) = np.asarray(x, float), np.asarray(y, float)
    den = (x1 - x0) * (y1 - y2) - (x1 - x2) * (y1 - y0)
    if den == 0:
        return float(x1)
    v = x1 - 0.5 * ((x1 - x0) ** 2 * (y1 - y2) - (x1 - x2) ** 2 * (y1 - y0)) / den
    return float(np.clip(v, x0, x2))


def _spread_order(n: int) -> list[int]:
    """0 .. n-1 in an order that spreads any prefix over the whole range (0, n/2, n/4, 3n/4 ...)."""
    order, seen = [], set()
    step = 1
    while len(order) < n:
        for j in range(step):
            i = int((2 * j + 1) * n / (2 * step)) if step > 1 else 0
            if i < n and i not in seen:
                seen.add(i)
                order.append(i)
        step *= 2
        if step > 2 * n:
            order += [i for i in range(n) if i not in seen]
            break
    return order
