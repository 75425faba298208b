"""Effective beam width of the range sensor, estimated from all sphere scans of a session.

The cone model (:mod:`calib_core.detect.sonar.fit`) needs the beam's half-angle. The nominal
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

from calib_core.detect.sonar.detect import detect_sphere_in_cloud
from calib_core.detect.sonar.fit import cone_residuals, fit_sphere
from calib_core.detect.sonar.outline import free_outline_mask
from calib_core.detect.sonar.search import crop_ball

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
                            factors=None, progress=None, prepared: list | None = None) -> BeamWidthEstimate:
    """Estimate the effective beam width (deg) from the sphere scans of one session.

    Args:
        clouds_sonar_m: list of (N_i,3) clouds (sonar frame, m), one per capture.
        sphere_radius_m: the sphere's radius (m).
        nominal_deg: the sonar's stated beam width.
        centers_sonar_m: optional sphere centres (m) per cloud (None entries: detect them);
            e.g. operator-validated detections.
        factors: multiples of the nominal width to scan (default 0, 0.05, 0.1 ... 1.6).
        progress: optional ``progress(done, total, label)``.
        prepared: optional :func:`calib_core.detect.sonar.search.prepare_search` of each cloud
            (None entries: computed when needed), to share with the clouds' later detections.
    """
    r = float(sphere_radius_m)
    crops = []
    n = len(clouds_sonar_m)
    n_f = len(DEFAULT_FACTORS if factors is None else factors)
    for k, i in enumerate(spread_order(n)):
        if len(crops) >= MAX_CAPTURES:
            break
        crop = beam_crop(clouds_sonar_m[i], r, nominal_deg, None if centers_sonar_m is None else centers_sonar_m[i],
                         None if prepared is None else prepared[i])
        if crop is not None:
            crops.append(crop)
        if progress is not None:
            progress(k + 1, n + n_f, "beam width: captures")
    return estimate_from_crops(crops, r, nominal_deg, factors, progress, n)


def beam_crop(cloud_sonar_m, sphere_radius_m: float, nominal_deg: float = 1.0, center_sonar_m=None,
              prepared=None):
    """One capture's share of the estimate: (points around the sphere, its centre, range sigma),
    or None when no sphere is found there. ``center_sonar_m``: a known centre (else detected);
    ``prepared``: the cloud's :func:`calib_core.detect.sonar.search.prepare_search` (optional)."""
    r = float(sphere_radius_m)
    h0 = np.radians(nominal_deg) / 2.0
    P = np.asarray(cloud_sonar_m, float).reshape(-1, 3)
    c, sig = center_sonar_m, 0.005
    if c is None:
        det = _detect_any_width(P, r, nominal_deg, prepared)
        if det is None:
            return None
        c, sig = det.center_sonar_m, det.extras.get("sigma_range_m", 0.005)
    c = np.asarray(c, float)
    X = P[crop_ball(P, c, 1.6 * r + np.linalg.norm(c) * np.tan(h0) + 0.05)]
    # what holds the ball (a block, a seat, a stick) continues the outline on one side; under a
    # wide cone its returns pass for blooming: only the free part of the outline is used
    free = free_outline_mask(X, c, r, h0 * max(DEFAULT_FACTORS))
    if free is None:
        return None
    X = X[free]
    return (X, c, float(sig)) if len(X) >= 12 else None


def estimate_from_crops(crops: list, sphere_radius_m: float, nominal_deg: float = 1.0, factors=None,
                        progress=None, n: int = 0, search: str = "coarse-to-fine") -> BeamWidthEstimate:
    """The width scan over the captures' crops (:func:`beam_crop`; None entries are skipped).

    ``search``: "coarse-to-fine" (default, see :func:`_search_order`) or "grid" (every factor,
    every fit cold from the detected centre: the reference it is benchmarked against)."""
    r = float(sphere_radius_m)
    factors = np.asarray(DEFAULT_FACTORS if factors is None else factors, float)
    h0 = np.radians(nominal_deg) / 2.0
    crops = [c for c in crops if c is not None][:MAX_CAPTURES]
    sigmas = [c[2] for c in crops]
    crops = [(X, c) for X, c, _ in crops]
    if len(crops) < MIN_CAPTURES:
        return BeamWidthEstimate(float(nominal_deg), float(nominal_deg), len(crops),
                                 f"needs at least {MIN_CAPTURES} detected spheres")
    scale = max(float(np.median(sigmas)), 1e-3)
    scan = _WidthScan(crops, r, h0, scale, warm=search != "grid")
    order = _search_order(scan, factors) if search != "grid" else _grid_order(scan, factors)
    for k, f in enumerate(order):
        if progress is not None:
            progress(n + k + 1, n + len(factors), "beam width: scan")
    factors = np.asarray(sorted(scan.costs), float)
    costs = [scan.costs[f] for f in factors]
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


class _WidthScan:
    """Total truncated-quadratic cost of the captures' cone fits at a width (memoised); each fit
    starts warm from the same capture's fit at the nearest width already scanned."""

    def __init__(self, crops, r, h0, scale, warm: bool = True):
        self.crops, self.r, self.h0, self.scale, self.warm = crops, r, h0, scale, warm
        self.costs: dict[float, float] = {}
        self.centers: dict[float, list] = {}

    def cost(self, f: float) -> float:
        f = float(f)
        if f in self.costs:
            return self.costs[f]
        near = min(self.centers, key=lambda g: abs(g - f)) if self.centers and self.warm else None
        h, total, centers = self.h0 * f, 0.0, []
        for j, (X, c) in enumerate(self.crops):
            start = c if near is None else self.centers[near][j]
            fit = fit_sphere(X, start, self.r, model="cone", half_angle_rad=h, sigma0_m=self.scale,
                             warm=near is not None)
            cc = fit.center_m if fit.ok else c
            centers.append(cc)
            R = np.linalg.norm(X, axis=1)
            a, b = cone_residuals(cc, self.r, R, X / R[:, None], h)
            total += float(np.sum(np.minimum(np.hypot(a, b) / self.scale, 3.0) ** 2))
        self.costs[f], self.centers[f] = total, centers
        return total


def _grid_order(scan: _WidthScan, factors):
    """Every factor in turn (the reference search)."""
    for f in factors:
        scan.cost(f)
        yield float(f)


def _search_order(scan: _WidthScan, factors: np.ndarray):
    """Coarse to fine over ``factors`` (sorted): every other factor first, then the neighbours of
    the best one, until the best has both its grid neighbours scanned (the costs are smooth in
    the width, so the full grid's minimum and its parabola are found with about half the fits).
    Yields each factor as it is scanned."""
    fs = [float(f) for f in np.sort(np.asarray(factors, float))]
    for i in range(0, len(fs), 2):
        scan.cost(fs[i])
        yield fs[i]
    if (len(fs) - 1) % 2:
        scan.cost(fs[-1])
        yield fs[-1]
    while True:
        b = fs.index(min(scan.costs, key=scan.costs.get))
        todo = [fs[j] for j in (b - 1, b + 1) if 0 <= j < len(fs) and fs[j] not in scan.costs]
        if not todo:
            return
        for f in todo:
            scan.cost(f)
            yield f


def _detect_any_width(P: np.ndarray, r: float, nominal_deg: float, prepared=None):
    """The sphere found with the nominal width, else with none (an optical sensor), else None."""
    for width in (nominal_deg, 0.0):
        det = detect_sphere_in_cloud(P, r, width, prepared=prepared)
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


def spread_order(n: int) -> list[int]:
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
