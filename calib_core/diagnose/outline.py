"""Is there a round outline of a given size at a given pixel? (robust to partial occlusion)

The diagnosis asks this where the sonar says the sphere must be. The image detector proper
(calib_core.detect.image.detect) wants most of the silhouette; a target half hidden behind
something still shows half of its outline, which is enough to say "the sphere is here".
Support = the share of directions around the circle along which the image has a strong edge
running across the radius (gradient along the radius), searched over a small neighbourhood
of centres and radii.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

N_ANGLES = 90
MIN_SUPPORT = 0.35  # share of the circle with an outline edge: a half-hidden sphere gives ~0.45


@dataclass
class Outline:
    center_uv_px: np.ndarray
    radius_px: float
    support: float

    @property
    def found(self) -> bool:
        return self.support >= MIN_SUPPORT


def _gradients(image_rgb: np.ndarray, x0: int, y0: int, x1: int, y1: int):
    grey = cv2.cvtColor(np.ascontiguousarray(image_rgb[y0:y1, x0:x1]), cv2.COLOR_RGB2GRAY).astype(np.float32)
    grey = cv2.GaussianBlur(grey, (0, 0), 1.0)
    return cv2.Sobel(grey, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(grey, cv2.CV_32F, 0, 1, ksize=3)


def _support(gx, gy, thr, cx, cy, r, cos_t, sin_t) -> float:
    best = np.zeros(len(cos_t), bool)
    for rr in (0.9 * r, r, 1.1 * r):  # the rim of a mesh sphere is a band, not a line
        x = np.rint(cx + rr * cos_t).astype(int)
        y = np.rint(cy + rr * sin_t).astype(int)
        ok = (x >= 0) & (y >= 0) & (x < gx.shape[1]) & (y < gx.shape[0])
        radial = np.zeros(len(x), np.float32)
        radial[ok] = np.abs(gx[y[ok], x[ok]] * cos_t[ok] + gy[y[ok], x[ok]] * sin_t[ok])
        best |= radial > thr
    return float(best.mean())


def find_outline(image_rgb: np.ndarray, uv_px, radius_px: float, search: float = 0.35) -> Outline:
    """Best round outline of about ``radius_px`` within ``search * radius_px`` of ``uv_px``."""
    H, W = image_rgb.shape[:2]
    u, v, r = float(uv_px[0]), float(uv_px[1]), max(float(radius_px), 3.0)
    m = int(np.ceil(r * (1.5 + search))) + 3
    x0, y0, x1, y1 = max(int(u) - m, 0), max(int(v) - m, 0), min(int(u) + m + 1, W), min(int(v) + m + 1, H)
    if x1 - x0 < 5 or y1 - y0 < 5:
        return Outline(np.array([u, v]), r, 0.0)
    gx, gy = _gradients(image_rgb, x0, y0, x1, y1)
    mag = np.hypot(gx, gy)
    thr = max(float(np.percentile(mag, 85)), 8.0)  # a clear edge for this crop (8: noise floor, 8-bit)
    t = np.linspace(0, 2 * np.pi, N_ANGLES, endpoint=False)
    cos_t, sin_t = np.cos(t), np.sin(t)
    best = Outline(np.array([u, v]), r, 0.0)
    steps = np.linspace(-search, search, 7) * r
    for du in steps:
        for dv in steps:
            for rr in (0.85 * r, r, 1.15 * r):
                s = _support(gx, gy, thr, u + du - x0, v + dv - y0, rr, cos_t, sin_t)
                if s > best.support:
                    best = Outline(np.array([u + du, v + dv]), rr, s)
    return best
