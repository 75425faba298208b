"""Coarse sphere candidates in a downscaled image (where to look at full resolution).

Two sources:
- with a background image: the per-pixel colour difference to the background, thresholded
  above its noise level; opening removes thin things (the chain), closing fills the open-mesh
  holes; connected blobs of plausible size are candidates;
- without a background: a colour centre-surround contrast (mean colour in a disc-sized box
  against the mean colour in a ring around it, over a range of radii) finds compact blobs darker
  or brighter than their surroundings, in any colour.

Sizes are bounded by the intrinsics and the known radius (:func:`radius_bounds_px`). All
coordinates returned are full-resolution raw pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from calib_core.camera import CameraModel


@dataclass
class Candidate:
    """A coarse sphere candidate (full-resolution raw pixels)."""

    centre_px: np.ndarray  # (2,) x, y
    radius_px: float  # mean radius
    axes_px: tuple[float, float]  # semi-axes (major, minor)
    angle_rad: float  # major axis direction
    touches_border: bool
    strength: float  # contrast (grey levels)
    source: str  # "background", "contrast", "hint"


def radius_bounds_px(cam: CameraModel, sphere_radius_m: float,
                     range_limits_m: tuple[float, float]) -> tuple[float, float]:
    """Plausible apparent radius range (px) of the sphere over the range limits.

    On the optical axis the silhouette radius is ``f tan(asin(r/d))``; off axis the ellipse
    grows (up to ``1/cos^2`` of the field angle along the radial direction) and barrel
    distortion shrinks it, so callers widen these bounds.
    """
    f = 0.5 * (cam.fx + cam.fy)
    d_min, d_max = range_limits_m
    a_max = np.arcsin(min(sphere_radius_m / max(d_min, sphere_radius_m * 1.0001), 0.999))
    a_min = np.arcsin(min(sphere_radius_m / d_max, 0.999))
    return float(f * np.tan(a_min)), float(f * np.tan(a_max))


def choose_scale(r_min_px: float, width_px: int) -> int:
    """Downscale factor (1, 2 or 4) so the smallest plausible sphere keeps >= ~2 px of radius."""
    s = 1
    while s < 4 and r_min_px / (2 * s) >= 2.0 and width_px / (2 * s) >= 240:
        s *= 2
    return s


def downscale(image: np.ndarray, s: int) -> np.ndarray:
    """Area-average downscale by a power of two (repeated 2x2 averaging, OpenCV's fast path)."""
    out = image
    while s > 1:
        h, w = out.shape[:2]
        out = cv2.resize(out, (w // 2, h // 2), interpolation=cv2.INTER_AREA)
        s //= 2
    return out


def _odd(k: float) -> int:
    k = max(3, int(round(k)))
    return k if k % 2 else k + 1


def _blob_ellipse(ys, xs):
    cx, cy = xs.mean(), ys.mean()
    cov = np.cov(np.vstack([xs - cx, ys - cy])) if len(xs) > 2 else np.eye(2)
    lam, vec = np.linalg.eigh(cov)
    lam = np.maximum(lam, 1e-6)
    major, minor = 2 * np.sqrt(lam[1]), 2 * np.sqrt(lam[0])  # filled ellipse: var = a^2/4
    return cx, cy, major, minor, float(np.arctan2(vec[1, 1], vec[0, 1]))


def _drop_thin_parts(blob: np.ndarray) -> np.ndarray:
    """Keep the thick core of a blob: an opening by a disc of ~1/3 of its inscribed radius
    removes lines attached to it (the chain) but not the round body."""
    dt = cv2.distanceTransform(np.pad(blob, 1), cv2.DIST_L2, 3)[1:-1, 1:-1]
    r_in = float(dt.max())
    k = int(2 * round(0.35 * r_in) + 1)
    if k < 3:
        return blob
    opened = cv2.morphologyEx(blob, cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)))
    n, lab = cv2.connectedComponents(opened, connectivity=8)
    if n <= 1:
        return blob
    yx = np.unravel_index(int(np.argmax(dt)), dt.shape)
    keep = lab[yx] if lab[yx] > 0 else 1 + int(np.argmax(np.bincount(lab.ravel())[1:]))
    return (lab == keep).astype(np.uint8)


def candidates_from_background(small: np.ndarray, bg_small: np.ndarray, s: int,
                               r_bounds_px: tuple[float, float],
                               min_contrast: float = 8.0) -> tuple[list[Candidate], np.ndarray]:
    """Blobs that differ from the background, of plausible size.

    Args:
        small: downscaled RGB image (uint8 or float); bg_small: same-size background (float).
        s: downscale factor (full px = small px * s).
        r_bounds_px: plausible full-resolution radius range.
        min_contrast: smallest colour difference (grey levels) that counts.

    Returns:
        (candidates sorted by strength, difference image D (small, float32, grey levels)).
    """
    diff = cv2.subtract(small.astype(np.float32), bg_small.astype(np.float32))
    # a global brightness change between the background and the capture is not the sphere
    diff -= np.median(diff[::4, ::4].reshape(-1, diff.shape[2]), axis=0).astype(np.float32)
    D = np.sqrt(np.einsum("ijk,ijk->ij", diff, diff))
    n, lab, stats = _difference_blobs(D, r_bounds_px[0] / s, min_contrast)
    out = []
    for i in range(1, n):
        c = _background_candidate(D, lab, stats[i], i, s, r_bounds_px)
        if c is not None:
            out.append(c)
    out.sort(key=lambda c: -c.strength * c.radius_px)
    return out, D


def _difference_blobs(D: np.ndarray, r_lo_s: float, min_contrast: float):
    """Connected regions (count, labels, stats) where the smoothed difference ``D`` stands out
    from its own noise, opened and closed at a fraction of the smallest radius (small px)."""
    Db = cv2.GaussianBlur(D, (0, 0), max(1.0, 0.12 * r_lo_s))
    sub = Db[::3, ::3]
    med = float(np.median(sub))
    mad = float(np.median(np.abs(sub - med))) * 1.4826
    thr = max(med + 6.0 * mad, med + min_contrast * 0.6, min_contrast * 0.6)
    mask = (Db > thr).astype(np.uint8)
    k = _odd(0.45 * r_lo_s)
    ker = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, ker)
    mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, ker)
    n, lab, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    return n, lab, stats


def _background_candidate(D, lab, stat, i: int, s: int, r_bounds_px) -> Candidate | None:
    """The candidate of difference blob ``i`` (its thin parts dropped), or None when it is too
    small, too large or too elongated (unless it touches the border)."""
    h, w = lab.shape
    r_min, r_max = r_bounds_px
    x, y, bw, bh, area = stat
    if np.sqrt(area / np.pi) * s < 0.45 * r_min:
        return None
    blob = _drop_thin_parts((lab[y:y + bh, x:x + bw] == i).astype(np.uint8))
    ys, xs = np.nonzero(blob)
    r_eq = np.sqrt(len(xs) / np.pi) * s
    if r_eq < 0.45 * r_min or r_eq > 2.2 * r_max:
        return None
    cx, cy, ma, mi, ang = _blob_ellipse(ys + y, xs + x)
    touches = xs.min() + x <= 1 or ys.min() + y <= 1 or xs.max() + x >= w - 2 or ys.max() + y >= h - 2
    if not touches and mi / ma < 0.4:
        return None
    strength = float(np.median(D[ys + y, xs + x]))
    # small px centre (pixel centres) -> full px: (p + 0.5) * s - 0.5
    c_full = (np.array([cx, cy]) + 0.5) * s - 0.5
    rad = np.sqrt(ma * mi) * s if not touches else max(ma * s, r_eq)
    return Candidate(c_full, float(rad), (float(ma * s), float(mi * s)), ang, bool(touches), strength,
                     "background")


def radius_ladder(shape, s: int, r_bounds_px: tuple[float, float], r_min: float, hi_factor: float,
                  step: float) -> np.ndarray:
    """Radii (px at 1/``s`` scale) a candidate search tries: geometric steps of ``step`` from 0.8 x
    the smallest expected radius (at least ``r_min``) to ``hi_factor`` x the largest (at most half
    the image ``shape``'s smaller side); empty when that range is empty."""
    r_lo = max(r_min, 0.8 * r_bounds_px[0] / s)
    r_hi = min(hi_factor * r_bounds_px[1] / s, 0.5 * min(shape))
    if r_hi < r_lo:
        return np.zeros(0)
    return np.exp(np.arange(np.log(r_lo), np.log(r_hi) + 1e-9, np.log(step)))


def disc_boxes(R: float) -> tuple[int, int, int]:
    """Box geometry of a disc test at radius ``R`` (px): the inner box's half side (0.7 R), and the
    half width and centre offset of the eight boxes around it (the ring 1.15-1.5 R)."""
    hi = max(1, int(round(0.7 * R)))
    ki = max(hi + 1, int(round(1.15 * R)))
    ko = max(ki + 1, int(round(1.5 * R)))
    return hi, max(1, (ko - ki) // 2), (ki + ko + 1) // 2


PEAKS_PER_RADIUS = 12  # the strongest few local maxima per radius are all that can rank


def level_peaks(M: np.ndarray, R_px: float, level: int, floor: float, radius_label: float) -> list:
    """``(value, R, x, y)`` of the local maxima of a response map ``M`` computed at pyramid
    ``level`` for a circle of ``R_px`` pixels there: maxima over a window of 0.6 R, at least
    ``floor``, the strongest PEAKS_PER_RADIUS of them; x, y in full-resolution pixels and R
    reported as ``radius_label``."""
    k = 2 * int(round(0.6 * R_px)) + 1
    dil = cv2.dilate(M, cv2.getStructuringElement(cv2.MORPH_RECT, (k, k)))
    ys, xs = np.nonzero((M >= dil) & (M >= floor))
    if len(ys) > PEAKS_PER_RADIUS:
        top = np.argpartition(-M[ys, xs], PEAKS_PER_RADIUS)[:PEAKS_PER_RADIUS]
        ys, xs = ys[top], xs[top]
    f = 2 ** level
    return list(zip(M[ys, xs].tolist(), [float(radius_label)] * len(ys), ((xs + 0.5) * f - 0.5).tolist(),
                    ((ys + 0.5) * f - 0.5).tolist()))


def non_maximum(peaks, s: int, shape, max_candidates: int, source: str, min_sep: float) -> list[Candidate]:
    """Best ``(value, R, x, y)`` peaks (at 1/``s`` scale, image ``shape`` there) as candidates, each
    object once: a peak within ``min_sep`` radii of a kept one at a similar size (0.6-1.7x) is
    dropped. Larger peaks rank higher at equal value (value x sqrt(R)): clutter makes small round
    responses far more often than large ones."""
    h, w = shape
    peaks = sorted(peaks, key=lambda p: -p[0] * np.sqrt(p[1]))
    out: list[Candidate] = []
    for v, R, x, y in peaks:
        c_full = (np.array([x, y], float) + 0.5) * s - 0.5
        if any(np.hypot(*(c.centre_px - c_full)) < min_sep * max(c.radius_px, R * s)
               and 0.6 < c.radius_px / (R * s) < 1.7 for c in out):
            continue
        touches = x - R < 1 or y - R < 1 or x + R > w - 2 or y + R > h - 2
        out.append(Candidate(c_full, R * s, (R * s, R * s), 0.0, bool(touches), 100.0 * v, source))
        if len(out) >= max_candidates:
            break
    return out


def box_sum(a: np.ndarray, half_x: int, half_y: int) -> np.ndarray:
    return cv2.boxFilter(a, -1, (2 * half_x + 1, 2 * half_y + 1), normalize=False,
                         borderType=cv2.BORDER_CONSTANT)


def _shift(a: np.ndarray, dx: int, dy: int) -> np.ndarray:
    """out[y, x] = a[y + dy, x + dx], zero outside."""
    out = np.zeros_like(a)
    h, w = a.shape[:2]
    ys, yd = (slice(dy, h), slice(0, h - dy)) if dy >= 0 else (slice(0, h + dy), slice(-dy, h))
    xs, xd = (slice(dx, w), slice(0, w - dx)) if dx >= 0 else (slice(0, w + dx), slice(-dx, w))
    out[yd, xd] = a[ys, xs]
    return out


def window_counts(n: int, half: int) -> np.ndarray:
    """In-image samples of a 1D window [i-half, i+half] at each i (zero outside)."""
    i = np.arange(n)
    return (np.minimum(i + half, n - 1) - np.maximum(i - half, 0) + 1).astype(np.float32)


def _centre_surround(planes: list[np.ndarray], R: float) -> np.ndarray:
    """Isotropic colour contrast of a disc of radius R (px of this level) at every pixel.

    The mean colour of the inscribed box is compared with four boxes just outside the disc
    (left, right, above, below); the response is the SMALLEST of the four colour differences,
    so a disc standing out on all sides responds and the edge or corner of a large object
    (same colour as the inside on one side) does not. Sums skip pixels outside the image.
    ``planes``: the colour channels as contiguous float32 (h, w) arrays.
    """
    h, w = planes[0].shape
    hi, hx, off = disc_boxes(R)
    n_in = np.outer(window_counts(h, hi), window_counts(w, hi))
    m_in = [box_sum(p, hi, hi) / n_in for p in planes]
    C = np.full((h, w), np.inf, np.float32)
    n_sides = np.zeros((h, w), np.int32)
    full = (2 * hx + 1) * (2 * hi + 1)
    for (kx, ky) in ((hx, hi), (hi, hx)):
        N = np.outer(window_counts(h, ky), window_counts(w, kx))
        S = [box_sum(p, kx, ky) for p in planes]
        for sgn in (-1, 1):
            dx, dy = (sgn * off, 0) if kx == hx else (0, sgn * off)
            Ns = _shift(N, dx, dy)
            ok = Ns > 0.4 * full
            inv = 1.0 / np.maximum(Ns, 1e-6)
            c2 = np.zeros((h, w), np.float32)
            for mi, Si in zip(m_in, S):
                d = mi - _shift(Si, dx, dy) * inv
                c2 += d * d
            np.minimum(C, np.where(ok, c2, np.inf), out=C)
            n_sides += ok
    C = np.sqrt(C)
    C[(n_sides < 2) | ~np.isfinite(C)] = 0
    return C


def candidates_single_frame(small: np.ndarray, s: int, r_bounds_px: tuple[float, float],
                            max_candidates: int = 6, min_contrast: float = 6.0) -> list[Candidate]:
    """Compact blobs darker or brighter than their surroundings (no background needed).

    Approximation: square boxes stand in for the disc and its surroundings (box filters are
    O(1) per pixel at any size); the radius found is good to ~20 %, enough to place the edge
    search.
    """
    I0 = small.astype(np.float32)
    h, w = I0.shape[:2]
    r_lo = max(2.5, 0.8 * r_bounds_px[0] / s)
    r_hi = min(1.3 * r_bounds_px[1] / s, 0.5 * min(h, w))
    if r_hi < r_lo:
        return []
    radii = np.exp(np.arange(np.log(r_lo), np.log(r_hi) + 1e-9, np.log(1.25)))
    pyramid = [[np.ascontiguousarray(I0[..., c]) for c in range(I0.shape[2])]]
    peaks = []
    for R in radii:
        # work where the radius is 3-6 px: a pyramid level 2^L smaller; local maxima there
        L = max(0, int(np.floor(np.log2(R / 3.0))))
        while len(pyramid) <= L:
            pyramid.append([downscale(p, 2) for p in pyramid[-1]])
        C = _centre_surround(pyramid[L], R / 2 ** L)
        k = _odd(1.2 * R / 2 ** L)
        dil = cv2.dilate(C, cv2.getStructuringElement(cv2.MORPH_RECT, (k, k)))
        ys, xs = np.nonzero((C >= dil) & (C >= min_contrast))
        f = 2 ** L
        peaks += [(float(C[y, x]), float(R), (x + 0.5) * f - 0.5, (y + 0.5) * f - 0.5) for y, x in zip(ys, xs)]
    if not peaks:
        return []
    # rank: contrast, with a mild preference for larger radii (the open-mesh holes of a near
    # sphere have more contrast than the sphere as a whole)
    peaks.sort(key=lambda p: -p[0] * p[1] ** 0.25)
    out: list[Candidate] = []
    later: list[Candidate] = []
    for C, R, x, y in peaks:
        c_full = (np.array([x, y], float) + 0.5) * s - 0.5
        touches = x - R < 1 or y - R < 1 or x + R > w - 2 or y + R > h - 2
        cand = Candidate(c_full, R * s, (R * s, R * s), 0.0, bool(touches), C, "contrast")
        near = [c for c in out if np.hypot(*(c.centre_px - c_full)) < 0.9 * max(c.radius_px, R * s)]
        if any(0.6 < c.radius_px / (R * s) < 1.7 for c in near):
            continue  # the same object at a neighbouring scale/position
        if near:
            later.append(cand)  # overlaps a stronger one (its texture, or a side response)
            continue
        out.append(cand)
        if len(out) >= max_candidates:
            break
    return (out + later)[:max_candidates]
