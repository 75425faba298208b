"""A look for the sphere where another sensor predicts it: centre and apparent size known roughly.

When the session's rough rig registration (:mod:`calib_core.disambiguate.image`) says where the sphere
must be in an image and how large it must look, a half-visible, low-contrast outline (a ball the
shade of the chair behind it, its top fading into the wall) is enough: the size is no longer a
free parameter, so a short arc fixes the centre. Steps:

1. edges along the normals of the predicted outline, in a band as wide as the prediction's
   uncertainty: every gradient peak above the region's noise, not one per normal (the edge of a
   backrest a few px outside the ball must not hide the ball's own edge);
2. RANSAC over circles of the predicted radius through two edge points (the circle through most
   edge points, centre within the band of the prediction);
3. a cone fit on the points near that circle with the predicted half-angle as a prior
   (:func:`fit_cone_with_prior`): the centre's covariance includes the size's uncertainty;
4. a verdict with the reason an operator reads: found, "outline 62 % hidden near the sonar's
   prediction", "no round outline near the sonar's prediction".

A found outline has no probability (``score`` None: no calibration of the look exists yet);
it records ``outline_seen`` (the share of the outline seen, discounted by its spread), shown
under that name (:func:`calib_core.detect.reasons.score_text`), and ``range_prior_rel_sigma``:
its size, hence its range, follows the prediction's (the circle search of step 2 picks the edge
points that fit the predicted radius; the prior of step 3 adds little: ``bench_predicted_look.py
--range-bias``), so the one-camera apparent-size scale leaves its range out
(:func:`calib_core.pipeline.correspondences`).

The caller (:func:`calib_core.pipeline._resolve_ambiguous_images`) checks the result against the
registration before keeping it; this module only looks.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.ndimage import gaussian_filter1d

from calib_core.camera import CameraModel
from calib_core.detect.image import smear
from calib_core.detect.image.blur import blur_range_floor_m, is_blurred
from calib_core.detect.image.cone import (ConeFit, centre_uv_and_cov, normalize_near, orthonormal_basis,
                                          px_per_rad, rays_from_xy, silhouette_uv, silhouette_xy)
from calib_core.detect.image.detect import CUT, NO_OUTLINE, prepare_background
from calib_core.detect.image.apparent_range import cone_range_sigma_m, outline_range_floor_m
from calib_core.detect.image.edges import edge_widths, gradient_magnitude, outward_normals
from calib_core.detect.image.limb import lopsided_floor_px2
from calib_core.detect.image.fit import (BLUR_MAX_RADIUS_FRACTION, BLUR_SCALES_PX, CORR_LENGTH_PX, EDGE_NOISE_FACTOR,
                                         EDGE_SPACING_PX, SMALL_RADIUS_PX, SMOOTH_SIGMA_PX, Signal, centre_floor_px2,
                                         clean_rms_px)
from calib_core.detect.reasons import OUTLINE_SEEN_KEY, RANGE_PRIOR_KEY
from calib_core.detect.types import ImageDetection

WHERE = "near the sonar's prediction"
NO_OUTLINE_HERE = f"{NO_OUTLINE} {WHERE}"  # the free search's phrases, said of the predicted place
CUT_HERE = f"{CUT} {WHERE}"
# least share of the outline that must be seen on the fitted circle (about half may be hidden
# by the chair, a hand, low contrast; a third still fixes the centre when the size is known)
MIN_SUPPORT = 0.35
# the predicted half-angle's relative 1-sigma (the registration's range error, a few per cent)
PRIOR_REL_SIGMA = 0.03
INLIER_PX = 1.5
# the null test (see _null_support): outlines moved by this many radii, and the margin by which
# the sphere's outline must meet edges on more normals than any of them
NULL_SHIFT = 0.25
NULL_MARGIN = 0.2


def predicted_cone(cam: CameraModel, uv_px, radius_px: float) -> tuple[np.ndarray, float]:
    """(axis w, half-angle a) of the sphere's cone predicted at ``uv_px`` with apparent radius
    ``radius_px`` (sin a = r / range = radius_px / fx)."""
    w = cam.rays(np.asarray(uv_px, float).reshape(1, 2))[0]
    return w / np.linalg.norm(w), float(np.arcsin(min(radius_px / cam.fx, 0.99)))


def edge_points(cam: CameraModel, sig: Signal, w: np.ndarray, a: float, band_px: float, smooth_px: float = 0.0):
    """All gradient peaks above the noise along the normals of the predicted outline, on profiles
    smoothed along the normals by ``smooth_px`` (Gaussian sigma; 0: as sampled): (points (N,2)
    raw px, normal index (N,), number of normals K, gradient strengths (N,), edge widths (N,):
    FWHM of each peak, px, the smoothing's share taken out in quadrature)."""
    R = cam.fx * np.tan(a)
    k = int(np.clip(2 * np.pi * R / 2.0, 64, 360))
    sil = cam.distort(silhouette_xy(w, a, k))
    nrm = outward_normals(sil, sil.mean(axis=0))
    t = np.arange(-band_px, band_px + 0.25, 0.5)
    inside = cam.in_image(sil + band_px * nrm, margin_px=1.0) & cam.in_image(sil - band_px * nrm, margin_px=1.0)
    prof = sig.colour_profiles(sil, nrm, t)
    if smooth_px > 0:
        prof = gaussian_filter1d(prof, smooth_px / 0.5, axis=1, mode="nearest")
    g = gradient_magnitude(prof, 0.5)
    # the region's noise smoothed alike (per px of gradient, white noise falls as s^1.5; as pass 2)
    thr = EDGE_NOISE_FACTOR * sig.noise * min(1.0, (SMOOTH_SIGMA_PX / np.hypot(SMOOTH_SIGMA_PX, smooth_px)) ** 1.5)
    peak = np.zeros_like(g, dtype=bool)
    peak[:, 1:-1] = (g[:, 1:-1] >= g[:, :-2]) & (g[:, 1:-1] > g[:, 2:]) & (g[:, 1:-1] >= thr)
    peak &= inside[:, None]
    ki, mi = np.nonzero(peak)
    # sub-pixel: parabola through the peak and its neighbours
    g0, g1, g2 = g[ki, mi - 1], g[ki, mi], g[ki, mi + 1]
    den = g0 - 2 * g1 + g2
    off = np.where(np.abs(den) > 1e-12, 0.5 * (g0 - g2) / np.where(np.abs(den) > 1e-12, den, 1.0), 0.0)
    tt = t[mi] + 0.5 * np.clip(off, -0.5, 0.5)
    widths = np.sqrt(np.maximum(edge_widths(t, g[ki], tt) ** 2 - (2.3548 * smooth_px) ** 2, 0.0))
    return sil[ki] + tt[:, None] * nrm[ki], ki, int(inside.sum()), g1, widths


def ramp_points(cam: CameraModel, sig: Signal, w: np.ndarray, a: float, band_px: float):
    """One edge per normal of the predicted outline, read as a motion smear's ramp
    (:func:`calib_core.detect.image.smear.read`): the same return as :func:`edge_points` (the
    widths being the smear model's), and the measured :class:`~calib_core.detect.image.smear.Smear`."""
    R = cam.fx * np.tan(a)
    k = int(np.clip(2 * np.pi * R / 2.0, 64, 360))
    sil = cam.distort(silhouette_xy(w, a, k))
    nrm = outward_normals(sil, sil.mean(axis=0))
    reach = smear.window_px(R)
    t = np.arange(-band_px - reach, band_px + reach + 0.25, smear.STEP_PX)
    use = cam.in_image(sil + (band_px + reach) * nrm, margin_px=1.0) & cam.in_image(sil - (band_px + reach) * nrm, margin_px=1.0)
    use &= sig.covers(sil, band_px + reach + 1.0)
    if use.sum() < 12:
        return None
    theta = np.arctan2(nrm[use, 1], nrm[use, 0])
    min_step = EDGE_NOISE_FACTOR * sig.noise * np.sqrt(2 * np.pi) * SMOOTH_SIGMA_PX
    te, step, w_k, sm = smear.read(sig.colour_profiles(sil[use], nrm[use], t), t, np.abs(t) <= band_px, theta, R,
                                   CORR_LENGTH_PX / EDGE_SPACING_PX, min_step)
    keep = step >= min_step
    ki = np.flatnonzero(use)[keep]
    return (sil[ki] + te[keep, None] * nrm[ki], ki, int(use.sum()), step[keep], w_k[keep]), sm


def best_circle(pts: np.ndarray, centre0: np.ndarray, r: float, max_shift: float,
                rng: np.random.Generator, n_hyp: int = 400) -> tuple[np.ndarray, int] | None:
    """Centre of the circle of radius ``r`` through the most points (within INLIER_PX), among
    circles through two random points whose centre is within ``max_shift`` of ``centre0``."""
    n = len(pts)
    if n < 6:
        return None
    i, j = rng.integers(0, n, (2, n_hyp))
    p, q = pts[i], pts[j]
    m, d = 0.5 * (p + q), q - p
    L = np.linalg.norm(d, axis=1)
    ok = (L > 0.3 * r) & (L < 2 * r)
    h = np.sqrt(np.maximum(r * r - (0.5 * L) ** 2, 0.0))
    perp = np.column_stack([-d[:, 1], d[:, 0]]) / np.maximum(L, 1e-9)[:, None]
    cands = np.vstack([(m + h[:, None] * perp)[ok], (m - h[:, None] * perp)[ok]])
    cands = cands[np.linalg.norm(cands - centre0, axis=1) <= max_shift]
    if not len(cands):
        return None
    res = np.abs(np.linalg.norm(pts[None, :, :] - cands[:, None, :], axis=2) - r)
    cost = np.minimum(res, INLIER_PX) ** 2
    b = int(np.argmin(cost.sum(axis=1)))
    return cands[b], int((res[b] < INLIER_PX).sum())


def fit_cone_with_prior(cam: CameraModel, xy: np.ndarray, w: np.ndarray, a0: float,
                        corr_points: float, iterations: int = 8) -> ConeFit | None:
    """Robust (Huber) Gauss-Newton fit of (axis, half-angle) to edge points ``xy`` (normalised),
    with the prior a ~ N(a0, (PRIOR_REL_SIGMA a0)^2); the covariance holds the prior."""
    v = rays_from_xy(xy)
    a, sig_a, band = a0, PRIOR_REL_SIGMA * a0, 2.0 * INLIER_PX
    for it in range(iterations):
        scale = px_per_rad(cam, v, w)
        ang = np.arccos(np.clip(v @ w, -1.0, 1.0))
        r = scale * (ang - a)
        inl = np.abs(r) < band
        if inl.sum() < 6:
            return None
        sig = 1.2533 * float(np.abs(r[inl] - r[inl].mean()).mean())
        band = min(band, max(1.0, 3.5 * sig)) if it >= 2 else band  # only narrows
        k = 1.345 * max(sig, 0.1)
        wt = np.where(inl, np.minimum(1.0, k / np.maximum(np.abs(r), 1e-12)), 0.0)
        e1, e2 = orthonormal_basis(w)
        s = np.maximum(np.sin(ang), 1e-9)
        J = np.column_stack([-scale * (v @ e1) / s, -scale * (v @ e2) / s, -scale])
        s2 = max(float((wt * r * r).sum() / max(wt.sum() - 3, 1)), 1e-4)
        A = (J * wt[:, None]).T @ J / s2 + np.diag([0.0, 0.0, 1.0 / sig_a ** 2])
        b = -(J * wt[:, None]).T @ r / s2 - np.array([0.0, 0.0, (a - a0) / sig_a ** 2])
        step = np.linalg.solve(A + 1e-12 * np.eye(3), b)
        w = w + step[0] * e1 + step[1] * e2
        w, a = w / np.linalg.norm(w), a + step[2]
    scale = px_per_rad(cam, v, w)
    r = scale * (np.arccos(np.clip(v @ w, -1.0, 1.0)) - a)
    inl = np.abs(r) < band
    if inl.sum() < 6 or w[2] <= 0:
        return None
    cov = np.linalg.inv(A) * max(corr_points, 1.0)  # information of the last step, correlated points
    e1, e2 = orthonormal_basis(w)
    sig_rob = 1.4826 * float(np.median(np.abs(r[inl] - np.median(r[inl]))))
    return ConeFit(w=w, a_rad=float(a), inliers=inl, residuals_px=r, sigma_px=sig_rob, cov_params=cov,
                   basis=np.vstack([w, e1, e2]))


def _tangent_plane(cam: CameraModel, xy: np.ndarray, w0: np.ndarray):
    """Points (normalised ``xy``) in the plane tangent to the unit sphere at ``w0``, in units of
    fx (px near the axis); and that plane's basis (e1, e2)."""
    v = rays_from_xy(xy)
    e1, e2 = orthonormal_basis(w0)
    z = v @ w0
    return cam.fx * np.column_stack([v @ e1, v @ e2]) / z[:, None], e1, e2


def _nearest_per_normal(pts: np.ndarray, normal_of: np.ndarray, c: np.ndarray, R: float) -> np.ndarray:
    """Indices of the edge points within INLIER_PX of the circle (c, R), one per normal (the
    nearest): several peaks along one normal are the ball's edge and a thing just beside it."""
    d = np.abs(np.linalg.norm(pts - c, axis=1) - R)
    order = np.lexsort((d, normal_of))
    first = np.ones(len(order), bool)
    first[1:] = normal_of[order][1:] != normal_of[order][:-1]
    idx = order[first]
    return idx[d[idx] < INLIER_PX]


def _not_found(reason: str, **extras) -> ImageDetection:
    return ImageDetection(found=False, score=None, reason=reason, method="ellipse-exact", extras=extras)


@dataclass
class _Reading:
    """One reading of the edges around the prediction and the cone fitted to it."""

    fit: ConeFit
    support: float  # share of the K normals on the fitted outline
    k: int
    q: np.ndarray  # the edge points in the plane tangent to the predicted axis (px)
    normal_of: np.ndarray
    basis: tuple  # (e1, e2) of that plane
    edge_width_px: float  # median FWHM of the outline's edges (smoothing taken out)
    smooth_px: float
    smear: object | None = None  # the motion smear measured, when read as one (image.smear.Smear)
    lopsided_px2: float = 0.0  # the lopsided limb's floor (image.limb), from the fit's residuals


def _read(cam, sig: Signal, w0, a0: float, band: float, max_shift_q: float, seed: int,
          smooth_px: float, ramps: bool = False) -> _Reading | None:
    """Edges along the predicted outline's normals (smoothed by ``smooth_px``; with ``ramps``
    one per normal, read as a motion smear's ramps, and only when that smear is real), the
    circle of the predicted size through most of them, and the cone fitted with the size prior;
    None when no such circle or fit."""
    sm = None
    if ramps:
        got = ramp_points(cam, sig, w0, a0, band)
        if got is None or not got[1].real:
            return None
        (pts, normal_of, k, _, widths), sm = got
    else:
        pts, normal_of, k, _, widths = edge_points(cam, sig, w0, a0, band, smooth_px)
    # in the plane tangent to the predicted axis the outline is a circle of radius fx tan(a)
    # (in raw pixels an off-axis sphere is an ellipse, stretched by the lens)
    xy_all = normalize_near(cam, pts)
    q, e1, e2 = _tangent_plane(cam, xy_all, w0)
    Rq = cam.fx * np.tan(a0)
    circ = best_circle(q, np.zeros(2), Rq, max_shift_q, np.random.default_rng(seed))
    if circ is None or circ[1] < 0.15 * k:
        return None
    keep = _nearest_per_normal(q, normal_of, circ[0], Rq)
    w1 = w0 + (circ[0][0] * e1 + circ[0][1] * e2) / cam.fx
    fit = fit_cone_with_prior(cam, xy_all[keep], w1 / np.linalg.norm(w1), a0,
                              corr_points=CORR_LENGTH_PX / EDGE_SPACING_PX)
    if fit is None:
        return None
    width = float(np.median(widths[keep][fit.inliers])) if fit.inliers.any() else float("nan")
    around = q[keep][fit.inliers] - circ[0]
    limb = lopsided_floor_px2(fit.residuals_px[fit.inliers], np.arctan2(around[:, 1], around[:, 0]),
                              float(fit.sigma_px), CORR_LENGTH_PX / EDGE_SPACING_PX)
    return _Reading(fit, float(fit.inliers.sum()) / max(k, 1), k, q, normal_of, (e1, e2), width, smooth_px, sm, limb)


def _smoothed(cam, sig: Signal, w0, a0: float, band: float, max_shift_q: float, seed: int, R: float,
              raw: _Reading) -> _Reading:
    """The reading of a blurred outline at the smear's middle, or ``raw`` for a sharp one.

    A motion-smeared edge is a ramp whose gradient is a low plateau studded with the sharp edges
    of the still scene seen through it: with the size fixed, a circle through the studs can sit
    anywhere across the plateau, and the studs' own narrow peaks hide the blur from the raw
    reading's edge widths. On profiles smoothed along the normals (fit.BLUR_SCALES_PX, as
    pass 2 reads a smear) the gradient peaks at the ramp's middle, where the outline is, and the
    edge width (the smoothing taken out) measures the smear. Blurred when the first smoothed
    reading's edges are wider than a sharp photograph's; then the smoothest reading that still
    lies on MIN_SUPPORT of the outline is kept (none: the raw one). Its edge width, for the floor,
    is the widest the readings measured (taking the smoothing out in quadrature undershoots when
    the smoothing is as wide as the smear)."""
    best, widths = raw, [raw.edge_width_px]
    for s in BLUR_SCALES_PX:
        if 2.3548 * s > BLUR_MAX_RADIUS_FRACTION * R:
            break  # (no smoothing wider than a quarter radius: as fit's pass 2)
        alt = _read(cam, sig, w0, a0, band, max_shift_q, seed, s)
        if alt is None or not (len(widths) > 1 or is_blurred(alt.edge_width_px)):
            break
        widths.append(alt.edge_width_px)
        if alt.support >= MIN_SUPPORT and alt.fit.sigma_px <= clean_rms_px(R):
            best = alt
    return raw if len(widths) == 1 else replace(best, edge_width_px=float(np.nanmax(widths)))


def _ramped(cam, sig: Signal, w0, a0: float, band: float, max_shift_q: float, seed: int, R: float,
            peaks: _Reading) -> _Reading:
    """A motion smear read around the outline (smear.py), when it is real and its ramps lie on
    MIN_SUPPORT of the outline, round: its edge width (the smear model's median) is the floor's
    when wider than the peaks' (the studs of the still scene seen through a smear hide it from
    the peaks' widths: motion s1000, 9 px of smear, every peak reading's median width 3.7-3.8 px,
    2.28 px off with a stated 0.13 px). The edges are the ramps' middles when the peaks' own
    edges are blurred; a sharp peak reading keeps its edges (a short smear measured on an
    outline whose touching edges vary in width, chair s1002, is no reason to read it otherwise)."""
    alt = _read(cam, sig, w0, a0, band, max_shift_q, seed, 0.0, ramps=True)
    if alt is None or alt.support < MIN_SUPPORT or alt.fit.sigma_px > clean_rms_px(R):
        return peaks
    width = float(np.nanmax([alt.edge_width_px, peaks.edge_width_px]))
    return replace(alt if is_blurred(peaks.edge_width_px) else peaks, edge_width_px=width, smear=alt.smear)


def detect_at_prediction(image: np.ndarray, cam: CameraModel, sphere_radius_m: float, uv_px, radius_px: float,
                         background: np.ndarray | None = None, shift_frac: float = 0.3,
                         seed: int = 0) -> ImageDetection:
    """Look for the sphere's outline where it is predicted (raw px ``uv_px``, apparent radius
    ``radius_px``), the centre within ``shift_frac`` radii of the prediction; found, or why not."""
    H, W = image.shape[:2]
    w0, a0 = predicted_cone(cam, uv_px, radius_px)
    # nothing found where the predicted outline crosses the border: the ball is cut, not missing
    nothing = NO_OUTLINE_HERE if cam.in_image(silhouette_uv(cam, w0, a0, n=64), margin_px=1.0).all() else CUT_HERE
    R = float(radius_px)
    shift = max(3.0, shift_frac * R)
    band = shift + NULL_SHIFT * R + 2.0  # the edges of the outline and of the null circles
    m = int(R + 2 * band + 8)
    box = (max(0, int(uv_px[0]) - m), max(0, int(uv_px[1]) - m), min(W, int(uv_px[0]) + m + 1),
           min(H, int(uv_px[1]) + m + 1))
    if box[2] - box[0] < 8 or box[3] - box[1] < 8:
        return _not_found(nothing)
    sig = Signal(image, None if background is None else prepare_background(background).image, box)
    look = (cam, sig, w0, a0, band, shift * cam.fx * np.tan(a0) / R, seed)
    reading = _read(*look, 0.0)
    if reading is None:
        return _not_found(nothing, looked_at=[round(float(x), 1) for x in uv_px])
    peaks = reading
    if R >= SMALL_RADIUS_PX:  # (no smear on a small blob: as fit.outline_rms_limit_px)
        peaks = reading = _smoothed(*look, R, reading)
        reading = _ramped(*look, R, reading)
    det = _verdict(cam, reading, R, sphere_radius_m, uv_px)
    # (against every peak: one ramp per normal would meet the moved outlines less often)
    null = _null_support(cam, peaks.q, peaks.normal_of, peaks.k, reading.fit, w0, *peaks.basis)
    det.extras["null_support"] = round(null[1], 4)
    if det.found and null[0] - null[1] < NULL_MARGIN:
        return _not_found(f"no outline standing out from the texture {WHERE}", **det.extras)
    return det


def _null_support(cam, q, normal_of, k: int, fit: ConeFit, w0, e1, e2) -> tuple[float, float]:
    """(share of the normals with an edge on the fitted outline, most such share of the same
    outline moved by NULL_SHIFT radii in 8 directions): in dense texture (brick, tiles) any circle
    meets edges on many normals; the sphere's outline must meet far more than its neighbours."""
    w = fit.w
    c = cam.fx * np.array([w @ e1, w @ e2]) / (w @ w0)
    Rq = cam.fx * np.tan(fit.a_rad)
    own = len(_nearest_per_normal(q, normal_of, c, Rq)) / max(k, 1)
    ang = np.arange(8) * np.pi / 4
    moved = c + NULL_SHIFT * Rq * np.column_stack([np.cos(ang), np.sin(ang)])
    return own, max(len(_nearest_per_normal(q, normal_of, m, Rq)) / max(k, 1) for m in moved)


def _verdict(cam, reading: _Reading, R: float, sphere_radius_m: float, uv_px) -> ImageDetection:
    """Found when enough of the outline lies on a round, clean fit; else why not."""
    fit, support, k = reading.fit, reading.support, reading.k
    centre, cov = centre_uv_and_cov(cam, fit)
    sil = silhouette_uv(cam, fit.w, fit.a_rad, n=k)
    where = f"at ({centre[0]:.0f}, {centre[1]:.0f})"
    extras = {"support": round(support, 4), "edge_rms_px": round(float(fit.sigma_px), 4),
              "edge_width_px": round(reading.edge_width_px, 3), "edge_smoothing_px": reading.smooth_px,
              "prediction_uv_px": [round(float(x), 2) for x in uv_px], "prediction_radius_px": round(R, 2)}
    if reading.smear is not None:  # (read as a motion smear: its measured length and direction)
        extras.update(smear_px=round(reading.smear.length_px, 2), smear_deg=round(float(np.degrees(reading.smear.angle_rad)), 1))
    if not cam.in_image(sil, margin_px=1.0).all():
        return _not_found(CUT_HERE, **extras)
    if fit.sigma_px > clean_rms_px(R):
        return _not_found(f"outline not round (edge RMS {fit.sigma_px:.1f} px) {WHERE} {where}", **extras)
    if support < MIN_SUPPORT:
        return _not_found(f"outline {100 * (1 - support):.0f} % hidden or too faint {WHERE} {where}", **extras)
    r_px = float(np.mean(np.linalg.norm(sil - sil.mean(axis=0), axis=1)))
    # a blurred outline's plateau: the free search's systematic floor (image.blur), same rule
    cov = cov + centre_floor_px2(fit.sigma_px, r_px, reading.edge_width_px, lopsided_px2=reading.lopsided_px2) * np.eye(2)
    range_m = float(sphere_radius_m / np.sin(fit.a_rad))
    rng_sigma = float(np.linalg.norm([cone_range_sigma_m(sphere_radius_m, fit.a_rad, fit.cov_params[2, 2]),
                                      blur_range_floor_m(range_m, r_px, reading.edge_width_px),
                                      outline_range_floor_m(range_m, r_px, float(fit.sigma_px))]))
    extras.update(range_sigma_m=round(rng_sigma, 5), angular_radius_deg=round(float(np.degrees(fit.a_rad)), 5),
                  outline_coverage=round(support, 3))
    # no probability (score None): the share of the outline seen, discounted by its spread (as the
    # free search's fit score), under its own name; and the range marked as following the prediction
    extras.update({OUTLINE_SEEN_KEY: round(float(support * np.exp(-max(0.0, fit.sigma_px - 0.3) / 0.7)), 4),
                   RANGE_PRIOR_KEY: PRIOR_REL_SIGMA})
    return ImageDetection(found=True, center_uv_px=centre, cov_uv_px2=cov, score=None,
                          ellipse_px=((float(centre[0]), float(centre[1])), (2 * r_px, 2 * r_px), 0.0),
                          radius_px=r_px, range_m=range_m, method="ellipse-exact", extras=extras)
