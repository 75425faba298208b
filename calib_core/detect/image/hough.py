"""The paper's baseline (Section V): Canny edges + Hough-voting circle, centre of the circle.

It works in raw (distorted) pixels and takes the circle centre as the sphere centre, so it
inherits the perspective bias of the ellipse centre (pixels, growing off axis) and the
elongation of the ellipse; kept as the baseline the benchmark compares against.
"""

from __future__ import annotations

import cv2
import numpy as np


def hough_circle(image_rgb: np.ndarray, centre_px: np.ndarray,
                 radius_px: float) -> tuple[np.ndarray, float, np.ndarray] | None:
    """Best Hough circle near a coarse candidate.

    Args:
        image_rgb: full image (H,W,3) uint8.
        centre_px, radius_px: coarse candidate (full-resolution raw px).

    Returns:
        (centre_px (2,), radius_px, cov_px2 (2,2)) or None when no circle is found. The
        covariance is the spread of the Canny edge points around the circle over their
        number (an approximation that ignores the method's bias).
    """
    H, W = image_rgb.shape[:2]
    m = int(np.ceil(1.5 * radius_px + 8))
    x0, y0 = max(0, int(centre_px[0]) - m), max(0, int(centre_px[1]) - m)
    x1, y1 = min(W, int(centre_px[0]) + m + 1), min(H, int(centre_px[1]) + m + 1)
    if x1 - x0 < 8 or y1 - y0 < 8:
        return None
    grey = cv2.cvtColor(np.ascontiguousarray(image_rgb[y0:y1, x0:x1]), cv2.COLOR_RGB2GRAY)
    grey = cv2.GaussianBlur(grey, (0, 0), 1.2)
    # Canny's high threshold from the grey contrast between the disc and a ring around it
    yy, xx = np.mgrid[y0:y1, x0:x1]
    rr = np.hypot(xx - centre_px[0], yy - centre_px[1])
    inner, ring = grey[rr < 0.7 * radius_px], grey[(rr > 1.15 * radius_px) & (rr < 1.45 * radius_px)]
    contrast = abs(float(np.median(inner)) - float(np.median(ring))) if inner.size and ring.size else 30.0
    canny_hi = float(np.clip(1.2 * contrast, 15, 200))
    rmin, rmax = max(3, int(0.75 * radius_px)), int(np.ceil(1.3 * radius_px)) + 2
    circles = None
    for frac in (0.5, 0.35, 0.22, 0.14, 0.09):
        votes = max(8, int(frac * np.pi * radius_px))
        circles = cv2.HoughCircles(grey, cv2.HOUGH_GRADIENT, dp=1, minDist=max(4, radius_px),
                                   param1=canny_hi, param2=votes, minRadius=rmin, maxRadius=rmax)
        if circles is not None and len(circles[0]):
            break
    if circles is None or not len(circles[0]):
        return None
    c = circles[0]
    local = np.array(centre_px) - [x0, y0]
    j = int(np.argmin(np.hypot(c[:, 0] - local[0], c[:, 1] - local[1])))
    cx, cy, r = (float(v) for v in c[j])
    edges = cv2.Canny(grey, canny_hi / 2, canny_hi)
    ys, xs = np.nonzero(edges)
    res = np.hypot(xs - cx, ys - cy) - r
    near = np.abs(res) < 3.0
    n = int(near.sum())
    sig2 = float(np.mean(res[near] ** 2)) if n > 5 else 1.0
    var = 2.0 * max(sig2, 0.25) / max(n, 1) + 0.25  # + quantisation of the accumulator (0.5 px)
    return np.array([cx + x0, cy + y0]), r, np.eye(2) * var
