"""Round-outline candidates by radial gradient voting (no background, any colour).

Every pixel with a strong colour gradient votes for the points one radius away along its
gradient, on both sides (the sphere may be darker or brighter than what is around it, and
that may change around the outline). A round outline of radius ``R`` puts all its votes on
its centre; texture and straight edges spread theirs. Per radius, the vote map is smoothed
and divided by the outline length ``2 pi R``, so the response is roughly the fraction of the
outline that is there, whatever the size. Radii are visited on an image pyramid (each radius
is voted at the level where it is 4-8 px), so the cost stays bounded for any radius range.

The gradient is the colour gradient of the strongest channel among lightness and the two
colour-opponent channels (CIE Lab), so a yellow ball on a white board (little lightness
contrast, strong colour contrast) votes as well as a grey ball on a dark floor.
"""

from __future__ import annotations

import cv2
import numpy as np

from calib_core.detect.image.region import Candidate, downscale, level_peaks, non_maximum, radius_ladder

LEVEL_RADIUS_PX = (4.0, 8.0)
RADIUS_STEP = 1.2


def _colour_gradient(lab: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(gx, gy, magnitude) float32 of the strongest Lab channel per pixel (``lab`` float32)."""
    best = None
    for c in range(3):
        ch = cv2.GaussianBlur(np.ascontiguousarray(lab[..., c]), (0, 0), 0.8)
        gx = cv2.Sobel(ch, cv2.CV_32F, 1, 0, ksize=3)
        gy = cv2.Sobel(ch, cv2.CV_32F, 0, 1, ksize=3)
        m = gx * gx + gy * gy
        if best is None:
            best = [gx, gy, m]
        else:
            take = m > best[2]
            for b, v in zip(best, (gx, gy, m)):
                np.copyto(b, v, where=take)
    return best[0], best[1], np.sqrt(best[2])


def _vote_map(xs, ys, nx, ny, R: float, shape) -> np.ndarray:
    h, w = shape
    acc = np.zeros(h * w, np.float32)
    for sgn in (1.0, -1.0):
        vx = np.rint(xs + sgn * R * nx).astype(np.int64)
        vy = np.rint(ys + sgn * R * ny).astype(np.int64)
        ok = (vx >= 0) & (vx < w) & (vy >= 0) & (vy < h)
        acc += np.bincount(vy[ok] * w + vx[ok], minlength=h * w).astype(np.float32)
    return acc.reshape(h, w)


def candidates_by_votes(small_rgb: np.ndarray, s: int, r_bounds_px: tuple[float, float],
                        max_candidates: int = 6, min_fraction: float = 0.3) -> list[Candidate]:
    """Centres of round outlines, best first.

    Args:
        small_rgb: downscaled RGB image; s: its downscale factor (full px = small px * s).
        r_bounds_px: plausible full-resolution radius range.
        max_candidates: most candidates returned.
        min_fraction: smallest share of the outline that must vote.

    Returns:
        :class:`Candidate` list (``source`` "votes", ``strength`` = outline fraction x 100).
    """
    h0, w0 = small_rgb.shape[:2]
    radii = radius_ladder((h0, w0), s, r_bounds_px, 3.0, 1.25, RADIUS_STEP)
    if not len(radii):
        return []
    lab = cv2.cvtColor(np.ascontiguousarray(small_rgb), cv2.COLOR_RGB2LAB).astype(np.float32)
    levels: dict[int, tuple] = {}
    peaks = []
    for R in radii:
        L = max(0, int(np.floor(np.log2(R / LEVEL_RADIUS_PX[0]))))
        if L not in levels:
            levels[L] = _edge_pixels(downscale(lab, 2 ** L))
        xs, ys, nx, ny, shape = levels[L]
        if xs.size == 0:
            continue
        Rl = R / 2 ** L
        V = _vote_map(xs, ys, nx, ny, Rl, shape)
        sg = max(0.8, 0.12 * Rl)
        V = cv2.GaussianBlur(V, (0, 0), sg) * (2 * np.pi * sg * sg)
        V /= 2 * np.pi * Rl
        peaks += level_peaks(V, Rl, L, min_fraction, R)
    return non_maximum(peaks, s, (h0, w0), max_candidates, "votes", min_sep=0.5)


def _edge_pixels(lab: np.ndarray):
    gx, gy, mag = _colour_gradient(lab)
    h, w = mag.shape
    thr = max(4.0, float(np.percentile(mag[::2, ::2], 75)))
    ys, xs = np.nonzero(mag > thr)
    m = mag[ys, xs]
    return (xs.astype(np.float32), ys.astype(np.float32), gx[ys, xs] / m, gy[ys, xs] / m, (h, w))
