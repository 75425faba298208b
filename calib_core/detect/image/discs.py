"""Disc candidates by colour distance in units of the local colour spread (no background).

The third candidate cue, for a ball whose outline the gradient votes miss and whose plain
colour contrast is outranked by bigger, crisper things: a red ball before red brick, a grey
ball half on a curtain and half on brick. Brick, tiles and foliage have a large colour spread
(mortar lines, grout); a ball's surface has a small one (smooth shading). So a disc is scored
by how far the mean colour (CIE Lab) of its inside lies from the mean colour just outside it,
in units of the colour spread there and inside:

    d_side = |mean_in - mean_side| / sqrt(var_in + var_side + NOISE_VAR)

over four boxes around the disc (left, right, above, below), and the response is the smallest
of them: a disc that stands out on every side responds; the edge of a large region (the same
on one side) or a patch of texture (its own mean and spread everywhere) does not. Means and
variances come from box sums (O(1) per pixel at any size), on a pyramid level where the
radius is 3-6 px; the variances use the squares averaged from the finest level, so texture
finer than the level's pixels still counts as spread.

It only proposes places (``source`` "discs"); the cone fit on the outline arcs verifies them.
"""

from __future__ import annotations

import cv2
import numpy as np

from calib_core.detect.image.region import (Candidate, box_sum, window_counts, disc_boxes, downscale, level_peaks, non_maximum,
                                           radius_ladder)

NOISE_VAR = 25.0  # (Lab units)^2: a spread under ~5 units is image noise, not texture
MIN_RESPONSE = 0.5  # smallest side distance (in spreads) that makes a candidate
RADIUS_STEP = 1.25
MIN_SIDES = 5  # of the 8 boxes around a disc, at least this many inside the image


def _level_stats(lab: np.ndarray, levels: int) -> list[tuple[list[np.ndarray], np.ndarray]]:
    """Per pyramid level: the Lab planes and the sum of their squares (averaged from the finest)."""
    out = []
    m, q = lab, np.einsum("ijk,ijk->ij", lab, lab)
    for L in range(levels + 1):
        if L:
            m, q = downscale(m, 2), downscale(q, 2)
        out.append(([np.ascontiguousarray(m[..., c]) for c in range(3)], np.ascontiguousarray(q)))
    return out


def _padded_box_sums(arrays, kx: int, ky: int, pad: int) -> list[np.ndarray]:
    """Box sums (zero outside the image) of each array, zero-padded by ``pad`` on every side:
    a shifted copy is then a view (see :func:`_at`)."""
    return [cv2.copyMakeBorder(box_sum(a, kx, ky), pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=0)
            for a in arrays]


def _at(padded: np.ndarray, dx: int, dy: int, pad: int, shape) -> np.ndarray:
    """View of a padded array: out[y, x] = original[y + dy, x + dx] (zero outside)."""
    h, w = shape
    return padded[pad + dy:pad + dy + h, pad + dx:pad + dx + w]


def disc_response(planes: list[np.ndarray], sq: np.ndarray, R: float) -> np.ndarray:
    """Smallest side distance (in colour spreads) of a disc of radius R at every pixel.

    ``planes``: Lab channels (float32 (h, w)) of one level; ``sq``: the sum of their squares.
    The eight boxes around the disc (four sides, four diagonals) count only where mostly inside
    the image; at least MIN_SIDES must be inside, else the response is 0.
    """
    h, w = planes[0].shape
    hi, hx, off = disc_boxes(R)
    n_in = np.outer(window_counts(h, hi), window_counts(w, hi))
    m_in = [box_sum(p, hi, hi) / n_in for p in planes]
    v_in = np.maximum(box_sum(sq, hi, hi) / n_in - sum(m * m for m in m_in), 0.0)
    D = np.full((h, w), np.inf, np.float32)
    n_sides = np.zeros((h, w), np.int32)
    diag = int(round(off / np.sqrt(2.0)))
    for kx, ky, shifts in ((hx, hi, ((-off, 0), (off, 0))), (hi, hx, ((0, -off), (0, off))),
                           (hx, hx, ((-diag, -diag), (diag, -diag), (-diag, diag), (diag, diag)))):
        N = np.outer(window_counts(h, ky), window_counts(w, kx))
        *S, Q, Np = _padded_box_sums(planes + [sq], kx, ky, off) + [
            cv2.copyMakeBorder(N, off, off, off, off, cv2.BORDER_CONSTANT, value=0)]
        full = (2 * kx + 1) * (2 * ky + 1)
        for dx, dy in shifts:
            Ns = _at(Np, dx, dy, off, (h, w))
            inv = 1.0 / np.maximum(Ns, 1e-6)
            ms = [_at(Si, dx, dy, off, (h, w)) * inv for Si in S]
            vs = np.maximum(_at(Q, dx, dy, off, (h, w)) * inv - sum(m * m for m in ms), 0.0)
            d2 = sum((a - b) ** 2 for a, b in zip(m_in, ms)) / (v_in + vs + NOISE_VAR)
            ok = Ns > 0.4 * full
            np.minimum(D, np.where(ok, d2, np.inf), out=D)
            n_sides += ok
    D = np.sqrt(D)
    D[(n_sides < MIN_SIDES) | ~np.isfinite(D)] = 0
    return D


def candidates_by_discs(small_rgb: np.ndarray, s: int, r_bounds_px: tuple[float, float],
                        max_candidates: int = 6, min_response: float = MIN_RESPONSE) -> list[Candidate]:
    """Discs whose colour stands out from all around them, best first.

    Args:
        small_rgb: downscaled RGB image; s: its downscale factor (full px = small px * s).
        r_bounds_px: plausible full-resolution radius range.
        max_candidates: most candidates returned.
        min_response: smallest response (colour distance in spreads) that counts.

    Returns:
        :class:`Candidate` list (``source`` "discs", ``strength`` = response x 100).
    """
    h, w = small_rgb.shape[:2]
    radii = radius_ladder((h, w), s, r_bounds_px, 2.5, 1.3, RADIUS_STEP)
    if not len(radii):
        return []
    lab = cv2.cvtColor(np.ascontiguousarray(small_rgb), cv2.COLOR_RGB2LAB).astype(np.float32)
    stats = _level_stats(lab, max(0, int(np.floor(np.log2(radii[-1] / 3.0)))))
    peaks = []
    for R in radii:
        L = max(0, int(np.floor(np.log2(R / 3.0))))
        D = disc_response(*stats[L], R / 2 ** L)
        peaks += level_peaks(D, R / 2 ** L, L, min_response, R)
    # a mild preference for larger discs: a uniform patch between grout lines (a tile, a
    # brick) stands out as much as a ball, but only at a small radius
    return non_maximum(peaks, s, (h, w), max_candidates, "discs", min_sep=0.9)
