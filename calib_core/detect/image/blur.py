"""A blurred outline's systematic floor: one rule for every reading of an outline.

A motion-smeared or defocused edge has a wide gradient plateau; the sub-pixel peak lands
anywhere on it, and it is the same smear for neighbouring normals, so the scatter does not
average out over the outline. The roundness limit of :func:`outline_rms_limit_px`
carries that scatter beyond a sharp edge's ((w^2 - w0^2) / 12 for a median edge width w); the
same excess is the floor of the centre's covariance per axis and, since it moves the whole
outline in or out together, of the range (range / apparent radius). Zero for a sharp edge.

The roundness limits themselves (:func:`clean_rms_px`, :func:`outline_rms_limit_px`) live here
too. Used by the free search (:mod:`calib_core.detect.image.fit`: roundness and the centre's
floor; :mod:`calib_core.detect.image.detect`: the range's floor) and by the look at a predicted
place (:mod:`calib_core.detect.image.predicted`).
"""

from __future__ import annotations

import numpy as np

# Acceptance of an outline's roundness: an edge RMS a round outline of real (JPEG, blurred)
# photographs reaches: sub-pixel edges of a sharp outline scatter ~0.3-0.7 px.
CLEAN_RMS_PX = 0.9
CLEAN_RMS_FRAC = 0.012
# Below SMALL_RADIUS_PX (the smallest sphere the detector is meant for) the floor shrinks with
# the radius: 0.9 px on an 8 px circle is a tenth of it (a rounded icon, a screw head).
SMALL_RADIUS_PX = 15.0


def clean_rms_px(radius_px: float) -> float:
    """Largest edge RMS (px) of a round outline of this apparent radius."""
    return max(CLEAN_RMS_FRAC * radius_px, CLEAN_RMS_PX * min(1.0, radius_px / SMALL_RADIUS_PX))


# A blurred outline (a ball moving during the exposure, out of focus) has a wide edge whose
# gradient peak is a plateau rather than a point: the sub-pixel peak lands anywhere on it, so
# the edge points scatter by the plateau width / sqrt(12) (a uniform spread) on top of what a
# sharp edge gives. SHARP_EDGE_WIDTH_PX is the full width at half maximum of the gradient of a
# sharp photograph's edge after the SMOOTH_SIGMA_PX smoothing: 2.355 sqrt(1.0^2 + 1.4^2) px,
# i.e. an optics and JPEG blur of 1.4 px (the renders' sharp edges measure 2.7-2.9 px, so
# they get no allowance); only the width beyond it widens the roundness limit.
SHARP_EDGE_WIDTH_PX = 4.0
BLUR_MAX_RADIUS_FRACTION = 0.25


def outline_rms_limit_px(radius_px: float, edge_width_px: float) -> float:
    """Largest edge RMS (px) of a round outline of this apparent radius whose edges have this
    median width (FWHM of the gradient, px): :func:`clean_rms_px` and, in quadrature, the
    scatter of a peak's position over the width beyond a sharp edge's. Not below
    SMALL_RADIUS_PX (a small blob with a soft edge is as likely a smudge or a shadow as a
    blurred ball), and the width counts up to BLUR_MAX_RADIUS_FRACTION of the radius (a ball
    blurred over more than that is a streak, not an outline)."""
    if radius_px < SMALL_RADIUS_PX or not np.isfinite(edge_width_px):
        return clean_rms_px(radius_px)
    w = min(float(edge_width_px), BLUR_MAX_RADIUS_FRACTION * radius_px)
    excess2 = max(0.0, w ** 2 - SHARP_EDGE_WIDTH_PX ** 2)
    return float(np.sqrt(clean_rms_px(radius_px) ** 2 + excess2 / 12.0))


def blur_floor_px2(radius_px: float, edge_width_px: float) -> float:
    """Variance (px^2) per image axis that a blurred outline's plateau adds to its centre; 0 for
    a sharp edge (width <= SHARP_EDGE_WIDTH_PX) or an unknown width (NaN)."""
    return float(max(0.0, outline_rms_limit_px(radius_px, edge_width_px) ** 2 - clean_rms_px(radius_px) ** 2))


def blur_range_floor_m(range_m: float, apparent_radius_px: float, edge_width_px: float) -> float:
    """The same floor's share of the range (m): the whole outline moved in or out by it."""
    floor2 = blur_floor_px2(apparent_radius_px, edge_width_px)
    if not floor2 > 0 or not apparent_radius_px > 0:
        return 0.0
    return float(range_m * np.sqrt(floor2) / apparent_radius_px)


def is_blurred(edge_width_px: float) -> bool:
    """An outline whose median edge is wider than a sharp photograph's."""
    return bool(np.isfinite(edge_width_px) and edge_width_px > SHARP_EDGE_WIDTH_PX)
