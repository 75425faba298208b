"""A blurred outline's systematic floor: one rule for every reading of an outline.

A motion-smeared or defocused edge has a wide gradient plateau; the sub-pixel peak lands
anywhere on it, and it is the same smear for neighbouring normals, so the scatter does not
average out over the outline. The roundness limit of :func:`calib_core.detect.image.fit.outline_rms_limit_px`
carries that scatter beyond a sharp edge's ((w^2 - w0^2) / 12 for a median edge width w); the
same excess is the floor of the centre's covariance per axis and, since it moves the whole
outline in or out together, of the range (range / apparent radius). Zero for a sharp edge.

Used by the free search's pass 2 (:mod:`calib_core.detect.image.fit`, whose formula this is)
and by the look at a predicted place (:mod:`calib_core.detect.image.predicted`).
"""

from __future__ import annotations

import numpy as np

from calib_core.detect.image.fit import SHARP_EDGE_WIDTH_PX, clean_rms_px, outline_rms_limit_px


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
