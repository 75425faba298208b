"""Image cues of an accepted round outline that its fit does not see (score round 3, issue 11;
measured by score_samples.py, not used by the detector: see BENCHMARKS.md "Score round 3").

The outline fit reads edge points; these cues read the image around the fitted circle, on
rays at ``N_RAYS`` angles: the colour just inside (0.80-0.92 R) and just outside (1.08-1.20 R)
the circle, and the interior. A fit dragged by a ball's own markings (beach-ball gores), a
texture arc on brick or a shadow's edge leaves the circle where the inside/outside colour step
is weak or comes from one side only:

- ``rim_step_share``: share of the rays whose inside/outside colour step is at least a third of
  the median step (a whole, right outline: most rays);
- ``rim_side_balance``: length of the step-weighted mean of the rays' unit vectors (0: steps
  all around; 1: all from one side);
- ``interior_spread``: the interior's colour spread (0.0-0.7 R, median absolute deviation of
  the colour distance to its median) over the median rim step.

Colour distances are Euclidean in RGB (grey images: the grey level), in DN.
"""

from __future__ import annotations

import numpy as np

N_RAYS = 72
CUE_NAMES = ("rim_step_share", "rim_side_balance", "interior_spread")


def _sample(img: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Nearest-pixel colours (N, C) at (u, v), clamped to the image."""
    h, w = img.shape[:2]
    ui = np.clip(np.rint(u).astype(int), 0, w - 1)
    vi = np.clip(np.rint(v).astype(int), 0, h - 1)
    px = img[vi, ui].astype(float)
    return px.reshape(len(u), -1)


def _ring_mean(img, centre, radius, angles, lo, hi, steps=3):
    """Mean colour (N_RAYS, C) of each ray between lo and hi radii."""
    acc = 0.0
    for f in np.linspace(lo, hi, steps):
        acc = acc + _sample(img, centre[0] + f * radius * np.cos(angles), centre[1] + f * radius * np.sin(angles))
    return acc / steps


def outline_cues(img: np.ndarray, centre_uv_px, radius_px: float) -> dict:
    """The cues of CUE_NAMES for the circle (centre, radius) in ``img`` (see the module doc)."""
    c = np.asarray(centre_uv_px, float)
    r = max(float(radius_px), 2.0)
    ang = np.linspace(0.0, 2 * np.pi, N_RAYS, endpoint=False)
    inside = _ring_mean(img, c, r, ang, 0.80, 0.92)
    outside = _ring_mean(img, c, r, ang, 1.08, 1.20)
    step = np.linalg.norm(inside - outside, axis=1)
    med = max(float(np.median(step)), 1.0)
    share = float(np.mean(step >= med / 3.0))
    w = step / max(step.sum(), 1e-9)
    balance = float(np.hypot(np.sum(w * np.cos(ang)), np.sum(w * np.sin(ang))))
    rr = r * np.sqrt(np.linspace(0.0, 0.49, 8))[:, None]
    uu = (c[0] + rr * np.cos(ang[::3])).ravel()
    vv = (c[1] + rr * np.sin(ang[::3])).ravel()
    px = _sample(img, uu, vv)
    d = np.linalg.norm(px - np.median(px, axis=0), axis=1)
    spread = float(np.median(d) / med)
    return {"rim_step_share": share, "rim_side_balance": balance, "interior_spread": spread}
