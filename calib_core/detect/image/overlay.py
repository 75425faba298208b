"""A round line drawn over the scene told from a ball's outline.

An on-screen display burns a circle reticle into the video (and a painted ring, a hoop or a
porthole's thin rim look the same): a thin line, the same scene on both sides of it. A ball's
outline is an edge between two things: the colour just inside it is the ball's, just outside
the surroundings'. Across an outline point, with the mean colours c_in just inside and c_out
just outside (3 samples each, 8 px or 5 % of the radius away: past a drawn line of up to ~6 px whose
edge, not its middle, the fit may have taken, and the profiles' smoothing) and the line's own
colour (the sample within 4 px of the outline farthest from their midpoint m = (c_in + c_out) / 2):

- a step edge (even sharp, after the profiles' 1 px smoothing) has |c_in - c_out| about twice
  the largest |c(t) - m| within 2 px (about 4 times for a blurred edge): ratio >= ~2;
- a drawn line has |c_in - c_out| near 0 and a large |c(t) - m|: ratio near 0.

A point is "on a drawn line" when the line stands out (LINE_MIN_PEAK_DN) and the ratio is below
LINE_MAX_STEP_RATIO; an outline with at least LINE_MIN_SHARE of its points so is a drawn line,
not a sphere. The ratio's threshold sits far from both (0.6 between ~0 and >= 2); a ball whose
inside matches its surroundings all along its outline has no step and so no outline at all.
"""

from __future__ import annotations

import cv2
import numpy as np

from calib_core.detect.image.edges import outward_normals, sample_profiles

LINE_MAX_STEP_RATIO = 0.6
LINE_MIN_PEAK_DN = 10.0
LINE_MIN_SHARE = 0.6
LINE_CORE_PX = 4.0


def drawn_line_share(img: np.ndarray, origin_px: tuple, outline_px: np.ndarray, radius_px: float,
                     use: np.ndarray | None = None) -> float:
    """Share of the outline's points (K,2 raw px, a closed curve) that lie on a thin line drawn
    over one surface (see the module doc); only the points ``use`` (K, bool; all when None:
    e.g. where the outline was seen) are counted. ``img`` the (smoothed) colour region whose
    pixel (0,0) is the full image's ``origin_px``."""
    use = np.ones(len(outline_px), bool) if use is None else np.asarray(use, bool)
    if use.sum() < 8:
        return 0.0
    # (normals of the whole closed curve: a subset's gaps would bend them)
    nrm = outward_normals(outline_px, outline_px.mean(axis=0))[use]
    pts = outline_px[use]
    gap = max(8.0, 0.05 * radius_px)
    t_side = gap + np.arange(3.0)
    t_core = np.arange(-LINE_CORE_PX, LINE_CORE_PX + 0.01, 1.0)
    c_in = sample_profiles(img, origin_px, pts, nrm, -t_side).mean(axis=1)
    c_out = sample_profiles(img, origin_px, pts, nrm, t_side).mean(axis=1)
    core = sample_profiles(img, origin_px, pts, nrm, t_core)
    mid = 0.5 * (c_in + c_out)
    peak = np.linalg.norm(core - mid[:, None, :], axis=2).max(axis=1)
    step = np.linalg.norm(c_in - c_out, axis=1)
    on_line = (peak > LINE_MIN_PEAK_DN) & (step < LINE_MAX_STEP_RATIO * peak)
    return float(on_line.mean())


def is_drawn_line(img: np.ndarray, origin_px: tuple, outline_px: np.ndarray, radius_px: float,
                  use: np.ndarray | None = None) -> bool:
    """True when the outline (its points ``use``) is a drawn line rather than an edge
    (LINE_MIN_SHARE of them)."""
    return drawn_line_share(img, origin_px, outline_px, radius_px, use) >= LINE_MIN_SHARE


def drawn_in_image(image_rgb: np.ndarray, outline_px: np.ndarray, smooth_sigma_px: float,
                   use: np.ndarray | None = None) -> bool:
    """:func:`is_drawn_line` on the raw image (H,W,3) smoothed by ``smooth_sigma_px`` around the
    outline (for a fit made on another view of the image, e.g. a closed one: a line drawn over
    the scene is in the image itself); only the points ``use`` (K, bool) counted."""
    H, W = image_rgb.shape[:2]
    r = float(np.mean(np.linalg.norm(outline_px - outline_px.mean(axis=0), axis=1)))
    m = max(8.0, 0.05 * r) + 3.0 + 3.0 * smooth_sigma_px
    lo = np.maximum(np.floor(outline_px.min(axis=0) - m), 0).astype(int)
    hi = np.minimum(np.ceil(outline_px.max(axis=0) + m), [W, H]).astype(int)
    keep = ((outline_px >= lo + m - 3.0 * smooth_sigma_px) & (outline_px <= hi - 1 - m + 3.0 * smooth_sigma_px)).all(axis=1)
    if use is not None:
        keep &= np.asarray(use, bool)
    if keep.sum() < 8 or (hi - lo).min() < 4:
        return False
    crop = cv2.GaussianBlur(image_rgb[lo[1]:hi[1], lo[0]:hi[0]].astype(np.float32), (0, 0), smooth_sigma_px)
    return is_drawn_line(crop, (float(lo[0]), float(lo[1])), outline_px, r, keep)
