"""How many of the image edges at a fitted outline run along it.

A sphere's limb is one edge that runs along its outline: near the outline, the strong image
gradients point along the outline's normal. A round outline that a fit strung together from
unrelated things (the struts of a lattice, the threads of a net, the cells of a grid) lies where
many edges cross it: the lines run through the outline, and their gradients point along it.
:func:`along_share` measures, over the pixels within BAND_PX of the outline whose gradient is
strong, the share (weighted by gradient magnitude) whose gradient direction lies within
ALONG_MAX_DEG of the outline's normal (an edge within that angle of the outline runs along it).
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial import cKDTree

# pixels this far (px) from the outline are the outline's edges (a located edge is ~1 px off
# the fitted outline; the edge's own gradient is ~2 px wide after the signal's smoothing)
BAND_PX = 2.0
# an edge whose gradient lies within this angle of the outline's normal runs along the outline
# (the half-way split between along and across)
ALONG_MAX_DEG = 45.0
# strong: a gradient at least this share of the band's 90th-percentile gradient (the outline's
# own edge where there is one) ...
STRONG_OF_P90 = 0.5
# ... and this many times the region's lower-quartile gradient (the noise of its flat parts, ~0.75
# sigma of a noise-only gradient: ~3 sigma; not the median, which a lattice's lines, spread over
# most of a region, raise to their own level)
NOISE_QUANTILE = 0.25
STRONG_OF_NOISE = 4.0
# fewer strong pixels than this, or fewer outline points inside the image: nothing to judge
MIN_PIXELS = 16
MIN_POINTS = 8
# the outline is densified to at most this spacing (px) for the nearest-normal look-up
DENSE_STEP_PX = 0.5


def along_share(image: np.ndarray | None, origin_px, outline_px: np.ndarray | None,
                band_px: float = BAND_PX) -> float:
    """Share (0-1, gradient-magnitude weighted) of the strong image edges within ``band_px`` of
    a closed outline whose gradient direction is normal to it (edges that run along it).

    Args:
        image: (h,w) or (h,w,c) float image region (a smoothed crop: grey levels, or the
            |image - background| signal); None -> 1.0.
        origin_px: (x, y) px of the region's top-left pixel in the full image.
        outline_px: (K,2) closed outline, full-image px (a fitted silhouette).
        band_px: half-width (px) of the band around the outline looked at.

    Returns:
        The share; 1.0 when there is nothing to look at (no image, fewer than MIN_POINTS outline
        points inside the region, fewer than MIN_PIXELS strong edge pixels near it).
    """
    if image is None or outline_px is None or len(outline_px) < MIN_POINTS:
        return 1.0
    img = np.asarray(image, np.float32)
    img = img[:, :, None] if img.ndim == 2 else img
    pts, nrm = _dense_outline(np.asarray(outline_px, float) - np.asarray(origin_px, float))
    h, w = img.shape[:2]
    inside = (pts[:, 0] >= 0) & (pts[:, 0] <= w - 1) & (pts[:, 1] >= 0) & (pts[:, 1] <= h - 1)
    if inside.sum() < MIN_POINTS * len(pts) / max(len(outline_px), 1):
        return 1.0
    ys, xs = _band_pixels(pts[inside], (h, w), band_px)
    if len(xs) < MIN_PIXELS:
        return 1.0
    gx, gy, mag = _strongest_gradient(img)
    d, k = cKDTree(pts[inside]).query(np.column_stack([xs, ys]), distance_upper_bound=band_px + 0.5)
    near = np.isfinite(d)
    ys, xs, k = ys[near], xs[near], k[near]
    m = mag[ys, xs]
    if len(m) < MIN_PIXELS:
        return 1.0
    strong = m >= max(STRONG_OF_P90 * float(np.quantile(m, 0.9)), STRONG_OF_NOISE * float(np.quantile(mag, NOISE_QUANTILE)), 1e-6)
    if strong.sum() < MIN_PIXELS:
        return 1.0
    n = nrm[inside][k[strong]]
    g = np.column_stack([gx[ys, xs][strong], gy[ys, xs][strong]])
    cos = np.abs((g * n).sum(axis=1)) / np.maximum(m[strong], 1e-12)
    along = cos >= np.cos(np.radians(ALONG_MAX_DEG))
    return float(m[strong][along].sum() / m[strong].sum())


def _dense_outline(sil: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A closed polyline (K,2 px) resampled at <= DENSE_STEP_PX, with unit normals (sign free)."""
    nxt = np.roll(sil, -1, axis=0)
    seg = np.linalg.norm(nxt - sil, axis=1)
    n_sub = np.maximum(1, np.ceil(seg / DENSE_STEP_PX).astype(int))
    i = np.repeat(np.arange(len(sil)), n_sub)
    f = np.concatenate([np.arange(n) / n for n in n_sub])[:, None]
    pts = sil[i] + f * (nxt[i] - sil[i])
    tang = (nxt - sil)[i]
    nrm = np.column_stack([tang[:, 1], -tang[:, 0]])
    return pts, nrm / np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-12)


def _band_pixels(pts: np.ndarray, shape, band_px: float) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols) of the pixels within ~``band_px`` of the outline points (a thick polyline)."""
    mask = np.zeros(shape, np.uint8)
    for p in np.round(pts).astype(np.int32):  # (dense points: a disc at each, no closing segment)
        cv2.circle(mask, (int(p[0]), int(p[1])), int(np.ceil(band_px)), 1, -1)
    return np.nonzero(mask)


def _strongest_gradient(img: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per pixel the gradient (gx, gy, magnitude; grey levels / px) of the channel where it is
    strongest (a colour edge of equal brightness counts)."""
    gx = np.stack([cv2.Sobel(img[:, :, c], cv2.CV_32F, 1, 0, ksize=3) / 8 for c in range(img.shape[2])], axis=2)
    gy = np.stack([cv2.Sobel(img[:, :, c], cv2.CV_32F, 0, 1, ksize=3) / 8 for c in range(img.shape[2])], axis=2)
    mag2 = gx ** 2 + gy ** 2
    best = np.argmax(mag2, axis=2)[..., None]
    gx1, gy1 = np.take_along_axis(gx, best, 2)[..., 0], np.take_along_axis(gy, best, 2)[..., 0]
    return gx1, gy1, np.sqrt(gx1 ** 2 + gy1 ** 2)
