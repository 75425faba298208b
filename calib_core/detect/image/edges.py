"""Sub-pixel silhouette edge points sampled along normals (raw pixel coordinates).

Profiles of a (smoothed) signal image are read with bilinear interpolation along short
segments crossing the expected silhouette; the edge on each segment is the sub-pixel peak
(parabola through three samples) of the profile's gradient magnitude. The signal is either
the colour image itself or its per-pixel distance to a background colour, so a sphere darker
or brighter than its surroundings gives the same kind of peak.
"""

from __future__ import annotations

import cv2
import numpy as np


def sample_profiles(signal: np.ndarray, origin_px: tuple[float, float], points_px: np.ndarray,
                    normals: np.ndarray, t_px: np.ndarray) -> np.ndarray:
    """Bilinear samples of ``signal`` (h,w[,c]) along ``points + t * normals``.

    Args:
        signal: float32 image of a region of interest whose pixel (0,0) is the full image's
            ``origin_px`` (x, y).
        points_px: (K,2) segment centres, full-image raw pixels.
        normals: (K,2) unit directions.
        t_px: (M,) offsets along the normals (px).

    Returns:
        (K, M, c) profiles (c = 1 for a single-channel signal).
    """
    pts = points_px[:, None, :] + t_px[None, :, None] * normals[:, None, :]
    mx = (pts[..., 0] - origin_px[0]).astype(np.float32)
    my = (pts[..., 1] - origin_px[1]).astype(np.float32)
    prof = cv2.remap(signal, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    if prof.ndim == 2:
        prof = prof[..., None]
    return prof


def gradient_magnitude(profiles: np.ndarray, step_px: float) -> np.ndarray:
    """|d profile / dt| summed over channels in quadrature, (K, M) (central differences)."""
    d = np.zeros_like(profiles)
    d[:, 1:-1] = (profiles[:, 2:] - profiles[:, :-2]) / (2 * step_px)
    return np.sqrt((d * d).sum(axis=2))


def pick_edges(t_px: np.ndarray, g: np.ndarray, rule: str, min_strength: float,
               target_px: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """One sub-pixel edge per profile.

    Args:
        t_px: (M,) offsets, evenly spaced.
        g: (K, M) gradient magnitude.
        rule: "outermost" (the last local maximum above ``min_strength``; for the first pass,
            where texture inside the sphere also makes edges), "strongest" (the highest local
            maximum; for a candidate whose size is known roughly, in clutter) or "nearest" (the local maximum
            above ``min_strength`` closest to ``target_px``; for the refinement pass).
        min_strength: scalar or (K,) threshold.
        target_px: (K,) expected offsets for "nearest" (default 0).

    Returns:
        (t_edge (K,), strength (K,)); t_edge is NaN where no edge qualifies.
    """
    K, M = g.shape
    step = float(t_px[1] - t_px[0])
    thr = np.broadcast_to(np.asarray(min_strength, float), (K,))[:, None]
    peak = np.zeros_like(g, dtype=bool)
    peak[:, 1:-1] = (g[:, 1:-1] >= g[:, :-2]) & (g[:, 1:-1] > g[:, 2:]) & (g[:, 1:-1] >= thr)
    if rule == "outermost":
        idx = np.where(peak, np.arange(M)[None, :], -1).max(axis=1)
    elif rule == "strongest":
        gp = np.where(peak, g, -1.0)
        idx = np.where(peak.any(axis=1), gp.argmax(axis=1), -1)
    else:
        tgt = np.zeros(K) if target_px is None else np.asarray(target_px, float)
        dist = np.where(peak, np.abs(t_px[None, :] - tgt[:, None]), np.inf)
        idx = np.where(np.isfinite(dist).any(axis=1), dist.argmin(axis=1), -1)
    ok = idx > 0
    i = np.clip(idx, 1, M - 2)
    rows = np.arange(K)
    gm, g0, gp = g[rows, i - 1], g[rows, i], g[rows, i + 1]
    den = gm - 2 * g0 + gp
    off = np.where(np.abs(den) > 1e-12, 0.5 * (gm - gp) / np.where(den == 0, 1, den), 0.0)
    off = np.clip(off, -0.5, 0.5)
    t_edge = np.where(ok, t_px[i] + off * step, np.nan)
    return t_edge, np.where(ok, g0, 0.0)


def smooth_roi(image: np.ndarray, x0: int, y0: int, x1: int, y1: int, sigma_px: float) -> np.ndarray:
    """float32 Gaussian-smoothed crop [y0:y1, x0:x1] of an image (any channel count)."""
    roi = np.ascontiguousarray(image[y0:y1, x0:x1]).astype(np.float32)
    if sigma_px > 0:
        roi = cv2.GaussianBlur(roi, (0, 0), sigma_px)
    return roi


def ray_directions(n: int) -> np.ndarray:
    """(n,2) unit vectors evenly spread over the circle."""
    th = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.column_stack([np.cos(th), np.sin(th)])


def outward_normals(closed_curve_px: np.ndarray, centre_px: np.ndarray) -> np.ndarray:
    """Unit normals (n,2) of a closed polyline, oriented away from ``centre_px``."""
    tang = np.roll(closed_curve_px, -1, axis=0) - np.roll(closed_curve_px, 1, axis=0)
    nrm = np.column_stack([tang[:, 1], -tang[:, 0]])
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-12)
    flip = ((closed_curve_px - centre_px) * nrm).sum(axis=1) < 0
    nrm[flip] *= -1
    return nrm


def edge_peaks(t_px: np.ndarray, g: np.ndarray, min_strength: float, k: int) -> np.ndarray:
    """The ``k`` strongest sub-pixel gradient peaks of each profile, (K, k) offsets (px), NaN
    where a profile has fewer peaks above ``min_strength``.

    For a first look where one edge per profile is not enough: a dark ball before a dark
    backrest has a weak outline between the backrest's strong edge outside it and nothing
    inside; which peak on each ray is the ball's is left to a fit over all of them.
    """
    K, M = g.shape
    step = float(t_px[1] - t_px[0])
    peak = np.zeros_like(g, dtype=bool)
    peak[:, 1:-1] = (g[:, 1:-1] >= g[:, :-2]) & (g[:, 1:-1] > g[:, 2:]) & (g[:, 1:-1] >= min_strength)
    gp = np.where(peak, g, -1.0)
    idx = np.argsort(-gp, axis=1)[:, :k]  # (K, k) strongest first
    ok = np.take_along_axis(gp, idx, axis=1) > 0
    i = np.clip(idx, 1, M - 2)
    gm = np.take_along_axis(g, i - 1, axis=1)
    g0 = np.take_along_axis(g, i, axis=1)
    gq = np.take_along_axis(g, i + 1, axis=1)
    den = gm - 2 * g0 + gq
    off = np.where(np.abs(den) > 1e-12, 0.5 * (gm - gq) / np.where(den == 0, 1, den), 0.0)
    return np.where(ok, t_px[i] + np.clip(off, -0.5, 0.5) * step, np.nan)


def edge_widths(t_px: np.ndarray, g: np.ndarray, t_edge: np.ndarray) -> np.ndarray:
    """Full width at half maximum (px) of each profile's gradient peak at ``t_edge`` (K,), NaN
    where there is no edge.

    The half-maximum crossings on either side of the peak are interpolated linearly; a side
    that does not fall to half within the profile is counted to the profile's end (a lower
    bound). A step blurred by a Gaussian of sigma s has a width of 2.355 s; one smeared by a
    motion of length L across it, about max(L, 2.355 s).
    """
    K, M = g.shape
    step = float(t_px[1] - t_px[0])
    ok = np.isfinite(t_edge)
    i0 = np.clip(np.rint((np.where(ok, t_edge, t_px[0]) - t_px[0]) / step).astype(int), 0, M - 1)
    rows = np.arange(K)
    half = 0.5 * g[rows, i0]
    below = g < half[:, None]
    j = np.arange(M)[None, :]
    right = np.where(below & (j > i0[:, None]), j, M).min(axis=1)  # first sample below, past the peak
    left = np.where(below & (j < i0[:, None]), j, -1).max(axis=1)
    x_r = _crossing(g, rows, right, right - 1, half, M)
    x_l = _crossing(g, rows, left, left + 1, half, M)
    return np.where(ok, (x_r - x_l) * step, np.nan)


def _crossing(g, rows, j_below, j_above, half, M) -> np.ndarray:
    """Fractional sample index where the profile crosses ``half`` between ``j_above`` (at or
    above it) and ``j_below`` (below it); the profile's end where it never falls below."""
    inside = (j_below >= 0) & (j_below < M)
    jb, ja = np.clip(j_below, 0, M - 1), np.clip(j_above, 0, M - 1)
    gb, ga = g[rows, jb], g[rows, ja]
    frac = np.clip((ga - half) / np.maximum(ga - gb, 1e-12), 0.0, 1.0)
    x = ja + frac * (jb - ja)
    return np.where(inside, x, np.where(j_below < 0, 0.0, M - 1.0))
