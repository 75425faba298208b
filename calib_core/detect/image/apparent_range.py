"""The sigma of an image range read from the sphere's apparent size (range = R / sin(half-angle)).

The cone fit's covariance gives the half-angle's error from the scatter of the edge points
alone, as if each point's error were independent. An outline also has an error shared by all
its points: shading at the limb, the renderer's or the lens's anti-aliasing, JPEG and the
sub-pixel edge locator move the whole outline in or out together. The centre carries that
shared error as a floor of SYS_FRACTION x the edge RMS per axis (fit.py); the outline's
radial mode, the apparent radius, is the third such mode and gets the same floor. The range,
inversely proportional to the radius, carries it relatively: range x floor / radius.
Measured against the synthetic truth (benchmarks/bench_range_sigma.py, BENCHMARKS.md "Eleventh
round (helper rangesig)"): without it the stated range sigma was 2.4x too small (z^2 5.6 after
each camera's outline bias, median 1.6); with it z^2 1.6, median 0.43 (0.45 for a Gaussian).
"""

from __future__ import annotations

import numpy as np

from calib_core.detect.image.fit import SYS_FRACTION


def outline_range_floor_m(range_m: float, radius_px: float, edge_rms_px: float) -> float:
    """The range's share (m) of the error the whole outline shares: SYS_FRACTION x the edge RMS
    (px) on the apparent radius (px), relative. 0 when a value is missing or not positive."""
    if not (range_m > 0 and radius_px > 0 and edge_rms_px >= 0):
        return 0.0
    return float(range_m * SYS_FRACTION * edge_rms_px / radius_px)


def cone_range_sigma_m(sphere_radius_m: float, a_rad: float, var_a_rad2: float) -> float:
    """The range's sigma (m) from the cone fit's half-angle variance alone: d(R / sin a) / da."""
    return float(sphere_radius_m * np.cos(a_rad) / np.sin(a_rad) ** 2 * np.sqrt(max(var_a_rad2, 0.0)))
