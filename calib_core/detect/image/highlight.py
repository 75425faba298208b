"""A specular highlight is not the sphere: the clipped, round bright spot a key light makes on a
glossy ball is itself a clean round outline (often the cleanest in the image), and a detector
that takes it reports a sphere several times too far away, at the wrong place.

:func:`is_clipped_spot` tells such an outline (most of its inside at the sensor's top code in
some channel); :func:`host_candidates` places candidates for the ball around it: the highlight
lies inside the ball's disc, within ~0.7 of its radius from the centre towards the light, so
the ball's centre is looked for on a small grid around the highlight at a few sizes.
"""

from __future__ import annotations

import numpy as np

from calib_core.detect.image.region import Candidate

CLIPPED_DN = 250  # 8-bit code counted as clipped (JPEG and noise keep a clipped area below 255)
CLIPPED_SHARE = 0.6  # share of the disc's inside that is clipped for a highlight
HOST_SIZES = (2.5, 4.0, 6.0)  # ball radius / highlight radius looked at
HOST_SHIFT = 0.45  # ball centre offsets from the highlight, in ball radii


def is_clipped_spot(image: np.ndarray, centre_px, radius_px: float) -> bool:
    """True when most of the disc (0.8 of ``radius_px``) is clipped in its brightest channel."""
    H, W = image.shape[:2]
    r = max(1.0, 0.8 * radius_px)
    x0, x1 = max(0, int(centre_px[0] - r)), min(W, int(centre_px[0] + r) + 1)
    y0, y1 = max(0, int(centre_px[1] - r)), min(H, int(centre_px[1] + r) + 1)
    if x1 <= x0 or y1 <= y0:
        return False
    yy, xx = np.mgrid[y0:y1, x0:x1]
    inside = (xx - centre_px[0]) ** 2 + (yy - centre_px[1]) ** 2 <= r * r
    top = image[y0:y1, x0:x1].max(axis=2)[inside]
    return top.size > 0 and float(np.mean(top >= CLIPPED_DN)) >= CLIPPED_SHARE


def host_candidates(centre_px, radius_px: float, shape) -> list[Candidate]:
    """Candidates for a ball carrying a highlight of ``radius_px`` at ``centre_px``."""
    H, W = shape[:2]
    out = []
    for k in HOST_SIZES:
        R = k * radius_px
        for dx, dy in ((0, 0), (1, 0), (-1, 0), (0, 1), (0, -1)):
            c = np.asarray(centre_px, float) + HOST_SHIFT * R * np.array([dx, dy], float)
            border = c[0] - R < 0 or c[1] - R < 0 or c[0] + R > W - 1 or c[1] + R > H - 1
            out.append(Candidate(c, R, (R, R), 0.0, bool(border), 0.0, "votes"))
    return out
