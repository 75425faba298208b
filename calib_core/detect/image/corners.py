"""Corners and flat sides of an outline: what a sphere's cone cannot absorb (issue 11, cause 7).

A sphere's silhouette is a conic: the cone fit absorbs its position (harmonic 1 of the radial
residuals about the outline) and its elongation (harmonic 2). What is left of a real ball's
outline is edge noise, and a ragged stretch where something touches it. A square tile bounded by
grout, a cell of a caustic network or of a ripple-warped reflection, fitted by the tight refit,
keeps its stretches near the tangent points inside the 1 px inlier band: it looks round and
mostly seen, and scored up to 0.97. Its inlier residuals still follow the shape around the
outline: a square puts about 0.16 of its half-side into harmonic 4 (and 8), a blob's lobes into
harmonics 2-8 (the cone absorbs only the elongation its direction implies).

The measure (:class:`Wobble`): harmonics 2-8 fitted by least squares (with 0-2) to the inlier
residuals against their angle around the outline; their amplitude (root sum of squares, px),
the amplitude that noise alone gives there (from the residuals left and the fit's covariance: a
gap in the outline makes the fit less sure, and this says by how much), and the excess of the
first over the second, relative to the apparent radius (a shape's deviation from a circle grows
with its size; a ball's noise does not). An outline has corners when the excess is over
MAX_WOBBLE_FRACTION of its radius and the amplitude over MIN_SIGNIFICANCE times the noise's.

A gap in the outline (a holder, a dark side merging with the background) makes the harmonics
less determined: their noise amplitude grows by ``inflation`` over a fully seen outline's, and a
ball's smooth systematic deviation on the seen arc (a lopsided limb) is extrapolated into the gap
as well. The limit grows with the square root of that inflation (a dim ball seen over 280 deg,
inflation 17, read 0.059 of its radius; a tile seen over 290 deg, inflation 8.5, read 0.45).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# the harmonics read: from the first a cone cannot absorb (it absorbs 1, the position, and of 2 only
# the elongation its direction implies) to the highest a corner makes that the edge spacing resolves
FIRST_HARMONIC, TOP_HARMONIC = 2, 8
# no reading when the inliers leave a gap wider than this around the outline (the harmonics of a
# part of an outline are not its shape's)
MAX_GAP_DEG = 90.0
# fewer inliers than this: no reading (17 parameters)
MIN_INLIERS = 24
# corners: the excess amplitude over this share of the radius, for a fully seen outline
# (development seeds 1000-1039: ball-free tiles and cells that scored 0.79-0.97 read 0.065-0.45,
# right balls <= 0.041 (a small printed ball), most <= 0.03; BENCHMARKS.md "Session 25: falsecirc")
MAX_WOBBLE_FRACTION = 0.05
# ... and the amplitude this many times what noise alone gives (a partly seen outline's fit is
# loose: its amplitude must stand out from its own uncertainty)
MIN_SIGNIFICANCE = 2.0


@dataclass(frozen=True)
class Wobble:
    """Harmonics 2-8 of an outline's inlier residuals: amplitude and noise's amplitude (px)."""

    amplitude_px: float
    noise_px: float
    radius_px: float
    inflation: float = 1.0  # the noise amplitude over a fully seen outline's with as many points

    @property
    def excess_fraction(self) -> float:
        """sqrt(amplitude^2 - noise^2) over the radius (0 when noise explains it)."""
        return float(np.sqrt(max(self.amplitude_px ** 2 - self.noise_px ** 2, 0.0)) / max(self.radius_px, 1e-6))

    @property
    def significance(self) -> float:
        return float(self.amplitude_px / max(self.noise_px, 1e-9))

    @property
    def limit_fraction(self) -> float:
        """MAX_WOBBLE_FRACTION, grown with the square root of the gap's inflation."""
        return float(MAX_WOBBLE_FRACTION * np.sqrt(max(self.inflation, 1.0)))

    @property
    def has_corners(self) -> bool:
        return bool(self.excess_fraction > self.limit_fraction and self.significance > MIN_SIGNIFICANCE)

    @property
    def reason(self) -> str:
        """The refusal an operator reads."""
        return f"outline has corners or flat sides (off round by {100 * self.excess_fraction:.0f} % of its radius)"


def _basis(phase_rad: np.ndarray) -> np.ndarray:
    ks = np.arange(1, TOP_HARMONIC + 1)
    return np.column_stack([np.ones_like(phase_rad), np.cos(np.outer(phase_rad, ks)), np.sin(np.outer(phase_rad, ks))])


def largest_gap_deg(phase_rad: np.ndarray) -> float:
    """The widest stretch of the outline (deg) with no point at angles ``phase_rad``."""
    p = np.sort(np.mod(np.asarray(phase_rad, float), 2.0 * np.pi))
    return float(np.degrees(np.diff(np.r_[p, p[:1] + 2.0 * np.pi]).max())) if len(p) else 360.0


def wobble(phase_rad: np.ndarray, residuals_px: np.ndarray, radius_px: float) -> Wobble | None:
    """:class:`Wobble` of residuals ``residuals_px`` (N,) at angles ``phase_rad`` (N,) around an
    outline of apparent radius ``radius_px``; None with fewer than MIN_INLIERS points."""
    phase_rad = np.asarray(phase_rad, float)
    residuals_px = np.asarray(residuals_px, float)
    if len(phase_rad) < MIN_INLIERS or largest_gap_deg(phase_rad) > MAX_GAP_DEG:
        return None
    A = _basis(phase_rad)
    coef, *_ = np.linalg.lstsq(A, residuals_px, rcond=None)
    left = residuals_px - A @ coef
    var_px2 = float(left @ left) / (len(left) - A.shape[1])
    ks = np.arange(FIRST_HARMONIC, TOP_HARMONIC + 1)
    cols = np.r_[ks, TOP_HARMONIC + ks]
    trace = float(np.trace(np.linalg.pinv(A.T @ A)[np.ix_(cols, cols)]))
    # a fully seen outline: each cos / sin coefficient's variance is 2 var / N
    inflation = float(np.sqrt(trace * len(residuals_px) / (2.0 * len(cols))))
    return Wobble(float(np.linalg.norm(coef[cols])), float(np.sqrt(var_px2 * trace)), float(radius_px), inflation)


def outline_wobble(inlier_index: np.ndarray, n_normals: int, residuals_px: np.ndarray,
                   radius_px: float) -> Wobble | None:
    """:func:`wobble` of an outline read on ``n_normals`` evenly spaced normals, of which the
    inliers are ``inlier_index`` (their residuals ``residuals_px``)."""
    phase = 2.0 * np.pi * np.asarray(inlier_index, float) / max(int(n_normals), 1)
    return wobble(phase, residuals_px, radius_px)
