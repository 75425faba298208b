"""Full-resolution refinement of one candidate: edge points -> cone fit -> verdict.

Pass 1 casts rays from the coarse centre and takes the outermost strong edge of the
"differs from the background" signal (the open-mesh texture inside makes edges too; the
silhouette is the outermost). Pass 2 samples along the normals of the fitted silhouette, in a
narrow band, and keeps the outermost edge there (the outline's envelope); the cone is refitted
robustly, so the chain (a thin line attached at the top) and texture edges end up as outliers.
When that envelope is not clean, pass 2 is also read from the few strongest edges of every
normal in a wider band (the cone most of them agree on): a gore boundary just inside a beach
ball's limb is the outermost edge only over a stretch, the limb is round all the way.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy.ndimage import gaussian_filter1d

from calib_core.camera import CameraModel
from calib_core.detect.image.cone import (ConeFit, centre_uv_and_cov, fit_cone, normalize_near,
                                          silhouette_uv, silhouette_xy)
from calib_core.detect.image.edges import (edge_peaks, edge_widths, gradient_magnitude, outward_normals,
                                           pick_edges, ray_directions, sample_profiles, smooth_roi)
from calib_core.detect.image.blur import (BLUR_MAX_RADIUS_FRACTION, CLEAN_RMS_FRAC, CLEAN_RMS_PX,  # noqa: F401
                                          SHARP_EDGE_WIDTH_PX, SMALL_RADIUS_PX, blur_floor_px2, clean_rms_px, is_blurred,
                                          outline_rms_limit_px)
from calib_core.detect.image import smear
from calib_core.detect.image.corners import Wobble, outline_wobble
from calib_core.detect.image.limb import lopsided_floor_px2
from calib_core.detect.image.overlay import is_drawn_line
from calib_core.detect.image.region import Candidate
from calib_core.detect.image.tangent import along_share
from calib_core.detect.reasons import crossing_edges_reason

SMOOTH_SIGMA_PX = 1.0
# Neighbouring pass-2 edge samples are ~EDGE_SPACING_PX apart while the smoothing and the optics
# blur correlate their errors over ~CORR_LENGTH_PX: the residual-based covariance is inflated by
# the number of points per independent error. The residuals hold systematic parts too (texture at the limb,
# shading), so the result is a total-error estimate; the tests check it against the spread of
# errors over random synthetic scenes (mean Mahalanobis^2 ~ 2) and that it is not overconfident
# against pure-noise Monte Carlo.
EDGE_SPACING_PX = 2.0
CORR_LENGTH_PX = 2.25
SYS_FRACTION = 0.2
# A located edge moves by a fraction of its own width (FWHM of the gradient) where the limb's
# profile is lopsided: shading across the sphere, the renderer's or the lens's anti-aliasing, the
# background's brightness changing along the outline. The shift changes slowly along the outline,
# so it does not average out over the edge points: a floor per axis of EDGE_WIDTH_FRACTION x the
# edge width. Measured against the truth on every preset at seed 41 (191 right image centres,
# benchmarks/bench_centre_z2.py, BENCHMARKS.md "Twenty-fourth round"): without it the mean z^2
# per dof was 1.1-1.6 per radius bin (5.6 for 60-80 px); 0.01 x the width brings it to 0.7-1.0
# (4.0 for 60-80 px: one side-lit scene, canal, whose shading offset is shared by its captures:
# the pose covariance's systematic image offset, solve/systematic.py, carries that). It scales
# with the image's resolution, as the width does. What a strongly lopsided limb (a side-lit ball)
# adds on top, measured per image from the outline's residuals, is image.limb's floor.
EDGE_WIDTH_FRACTION = 0.01
# Acceptance: at least MIN_SUPPORT of the outline on the fitted cone (about half may be hidden
# by a holder, a hand or low contrast), and an edge RMS a round outline of real (JPEG, blurred)
# photographs reaches: sub-pixel edges of a sharp outline scatter ~0.3-0.7 px.
MIN_SUPPORT = 0.5
# Without a background image the "looks like the surroundings just outside" test compares the
# band outside the outline with the colour a little farther out, which clutter varies by
# itself: a looser limit there.
OUTSIDE_MISMATCH_CLUTTER = 0.35
# a fit that had to leave out the edges of things touching the sphere must be this much rounder
# than the clean limit on the edges it keeps
TIGHT_RMS_FRACTION = 0.5
# ... and still lie on most of the outline (a half circle in clutter is too easily had)
TIGHT_MIN_SUPPORT = 0.6
# an edge point's gradient must exceed this many times the region's median gradient (noise,
# texture); a median of a noise-only gradient magnitude is ~1.5 sigma, so this is ~4 sigma
EDGE_NOISE_FACTOR = 2.5
PASS1_MAX_RMS_PX = 2.5
PASS1_MAX_RMS_FRAC = 0.04


@dataclass
class CandidateFit:
    """Outcome of :func:`refine_candidate` (``ok`` False -> ``reason`` says why)."""

    ok: bool
    reason: str = ""
    fit: ConeFit | None = None
    centre_uv_px: np.ndarray | None = None
    cov_uv_px2: np.ndarray | None = None
    silhouette_px: np.ndarray | None = None
    support: float = 0.0
    score: float = 0.0
    contrast: float = 0.0
    range_m: float | None = None
    extras: dict = field(default_factory=dict)
    credible: bool = False
    wobble: Wobble | None = None  # harmonics 2-8 of the inlier residuals (corners.py)
    seen_idx: np.ndarray | None = None  # indices into silhouette_px where pass 2 found the outline (inliers)


def _polar_radius(cand: Candidate, dirs: np.ndarray) -> np.ndarray:
    a, b = cand.axes_px
    ca, sa = np.cos(cand.angle_rad), np.sin(cand.angle_rad)
    u = dirs[:, 0] * ca + dirs[:, 1] * sa
    v = -dirs[:, 0] * sa + dirs[:, 1] * ca
    return 1.0 / np.sqrt((u / max(a, 1e-6)) ** 2 + (v / max(b, 1e-6)) ** 2)


class Signal:
    """Samples the 'sphere vs surroundings' signal inside a region of interest."""

    def __init__(self, image: np.ndarray, background: np.ndarray | None, box):
        x0, y0, x1, y1 = box
        self.origin, self.box = (float(x0), float(y0)), box
        self._source = (image, background)  # (for :meth:`around`)
        self.diff = None
        if background is not None:
            d = cv2.subtract(image[y0:y1, x0:x1].astype(np.float32), background[y0:y1, x0:x1])
            d -= np.median(d.reshape(-1, d.shape[2])[::7], axis=0).astype(np.float32)
            # colour distance first, then one smoothing pass (same edge position as smoothing
            # the colours when the sphere's colour is locally uniform; 3x cheaper)
            self.diff = smooth_roi(np.sqrt(np.einsum("ijk,ijk->ij", d, d)), 0, 0, d.shape[1], d.shape[0],
                                   SMOOTH_SIGMA_PX)
        else:
            self.img = smooth_roi(image, x0, y0, x1, y1, SMOOTH_SIGMA_PX)
        self._noise = None

    def around(self, pts: np.ndarray, margin_px: float) -> "Signal":
        """This signal, or the same over a region widened to hold ``pts`` (K,2 px) and their
        ``margin_px`` neighbourhood (a reading that looks farther than the region was cut for:
        the smear's ramp windows; the region is sized from the candidate's coarse radius)."""
        if self.covers(pts, margin_px).all() or not np.isfinite(pts).all():
            return self
        image, background = self._source
        H, W = image.shape[:2]
        lo, hi = pts.min(axis=0) - margin_px - 2, pts.max(axis=0) + margin_px + 3
        x0, y0, x1, y1 = self.box
        box = (max(0, min(x0, int(lo[0]))), max(0, min(y0, int(lo[1]))),
               min(W, max(x1, int(hi[0]))), min(H, max(y1, int(hi[1]))))
        return Signal(image, background, box)

    def covers(self, pts: np.ndarray, margin_px: float) -> np.ndarray:
        """(K,) True where a point and its ``margin_px`` neighbourhood lie in the region (outside
        it the samples would be the region's replicated border, not the image)."""
        x0, y0, x1, y1 = self.box
        return ((pts[:, 0] - margin_px >= x0) & (pts[:, 0] + margin_px <= x1 - 1)
                & (pts[:, 1] - margin_px >= y0) & (pts[:, 1] + margin_px <= y1 - 1))

    @property
    def noise(self) -> float:
        """Median gradient magnitude of the region (computed once, when pass 2 needs it)."""
        if self._noise is None:
            self._noise = _typical_gradient(self.diff if self.diff is not None else self.img)
        return self._noise

    def profiles(self, pts, nrm, t, far_t_frac=0.15):
        """(K,M,c) signal: |image - background| with a background, else |image - local
        surroundings colour| with the surroundings taken per ray from its outer samples."""
        if self.diff is not None:
            return sample_profiles(self.diff, self.origin, pts, nrm, t)
        prof = sample_profiles(self.img, self.origin, pts, nrm, t)
        n_far = max(2, int(far_t_frac * len(t)))
        bgc = np.median(prof[:, -n_far:], axis=1, keepdims=True)
        return np.sqrt(((prof - bgc) ** 2).sum(axis=2, keepdims=True))

    def colour_profiles(self, pts, nrm, t):
        if self.diff is not None:
            return sample_profiles(self.diff, self.origin, pts, nrm, t)
        return sample_profiles(self.img, self.origin, pts, nrm, t)


def _typical_gradient(roi: np.ndarray) -> float:
    """Median gradient magnitude (per px) of a smoothed region, on every third row: the level
    of noise and texture an outline's edge has to stand out from."""
    r = roi[::3] if roi.ndim == 3 else roi[::3, :, None]
    if r.shape[1] < 3:
        return 0.0
    d = 0.5 * (r[:, 2:] - r[:, :-2])
    return float(np.median(np.sqrt((d * d).sum(axis=2))))


def refine_candidate(image: np.ndarray, cam: CameraModel, cand: Candidate, sphere_radius_m: float,
                     a_range_rad: tuple[float, float], background: np.ndarray | None = None,
                     rng: np.random.Generator | None = None, regrow: bool = True) -> CandidateFit:
    """Fit the sphere's silhouette cone near a candidate at full resolution.

    Args:
        image: (H,W,3) RGB uint8 raw image; background: same-size float32 background or None.
        cam: intrinsics; sphere_radius_m: known radius.
        a_range_rad: plausible cone half-angles (from the range limits).
        regrow: an outline that outgrew the region cut for the candidate is refined once more
            in a region cut for itself (:func:`_outgrew_region`).

    Returns:
        :class:`CandidateFit` with the centre (raw px), its covariance (px^2) and a score.
    """
    H, W = image.shape[:2]
    R = max(cand.axes_px[0], cand.radius_px)
    # the contrast detector's radius is good to ~30 %, the background blob's to ~10 %
    band = (-0.45, 0.8) if cand.source in ("contrast", "hint", "votes", "votes-stereo") or cand.source.startswith("closed") \
        else (-0.45, 0.5)
    m = int(np.ceil((1.1 + band[1]) * R + 8))
    box = (max(0, int(cand.centre_px[0]) - m), max(0, int(cand.centre_px[1]) - m),
           min(W, int(cand.centre_px[0]) + m + 1), min(H, int(cand.centre_px[1]) + m + 1))
    if box[2] - box[0] < 8 or box[3] - box[1] < 8:
        return CandidateFit(False, "no round outline")
    sig = Signal(image, background, box)
    starts = _first_pass(cam, sig, cand, R, band, a_range_rad, rng)
    if isinstance(starts, str):
        return CandidateFit(False, starts)
    for fit1 in starts:
        res = _grown(cam, sig, fit1, R, a_range_rad, rng, sphere_radius_m)
        if regrow and _outgrew_region(cam, sig, res, R):
            res = _regrown(image, cam, cand, res, sphere_radius_m, a_range_rad, background)
        # a rescued start is searched for (like the several reading): it must grow into a
        # credible outline (mostly seen, round, the surroundings just outside it); if not, the
        # next start is tried, and without one it counts as no start (the caller then looks
        # again near a candidate that found no outline, as it did before the rescue)
        if not _rescued(fit1) or (res.ok and res.credible):
            return res
    return CandidateFit(False, "no round outline")


# an outline fitted this much larger than the candidate it grew from (radius ratio), with part of
# it outside the region of interest cut for the candidate, is looked at again in a region cut for
# itself (a few tens of per cent are the coarse cues' own size error)
REGROWN_MIN_RATIO = 1.5


def _outgrew_region(cam, sig: Signal, res: CandidateFit, R: float) -> bool:
    """The fitted outline is much larger than the candidate's radius ``R`` (px) and more than a
    tenth of it, where it lies in the image, lies outside the region of interest cut for the
    candidate: pass 2 never read its normals there (it does not use a normal whose band leaves
    the region), so its support counts only the part the region holds. A small candidate on
    one arc of a large ball fits the whole ball's cone from that arc; how much of the outline
    is seen is a question for the image, not for the box."""
    sil = res.silhouette_px
    if res.fit is None or sil is None or not np.isfinite(sil).all():
        return False
    in_img = cam.in_image(sil, margin_px=1.0)
    return (_outline_radius(sil) >= REGROWN_MIN_RATIO * R
            and bool((in_img & ~sig.covers(sil, pass2_half_px(res.fit.sigma_px, R) + 1.0)).mean() > 0.1))


def _regrown(image, cam, cand: Candidate, res: CandidateFit, sphere_radius_m, a_range_rad, background) -> CandidateFit:
    """``res`` refined again from a candidate of its own centre and size (a region holding all of
    it), on its own random stream (the shared one draws as without this look); the better
    supported of the two."""
    sil = res.silhouette_px
    r = _outline_radius(sil)
    again = refine_candidate(image, cam, Candidate(sil.mean(axis=0), r, (r, r), 0.0, False, cand.strength, cand.source),
                             sphere_radius_m, a_range_rad, background, np.random.default_rng(len(sil)), regrow=False)
    if again.fit is None or again.support < res.support:
        return res
    again.extras["regrown_from_px"] = round(float(cand.radius_px), 1)
    return again


def _grown(cam, sig: Signal, fit1: ConeFit, R: float, a_range_rad, rng, sphere_radius_m: float) -> CandidateFit:
    """Pass 2 from one pass-1 start, judged."""
    # ---- pass 2: along the normals of the fitted silhouette, narrow band (twice when the
    # first pass-2 fit is still rough: clutter drew pass 1 off the outline)
    if fit1.reading in ("several",) + RESCUE_READINGS:
        rng = np.random.default_rng(len(fit1.inliers))  # (see _pass1_several: its own stream)
    p2 = _pass2(cam, sig, fit1, R, a_range_rad, rng)
    if p2 is not None and p2[0].sigma_px > clean_rms_px(R):
        again = _pass2(cam, sig, p2[0], R, a_range_rad, rng)
        if again is not None and _quality(again[0]) > _quality(p2[0]):
            p2 = again
    if p2 is None:
        return CandidateFit(False, "no round outline")
    res, outside_bad = _fitted(cam, sig, p2, R, sphere_radius_m)
    _judge(cam, res, R, outside_bad, sig.diff is not None)
    # (a refused outline too, when it would count: one cut by the border or partly hidden, a
    # broken reticle's arcs, is a rival of the ball or a partial find only if it is an edge)
    if (res.ok or res.credible) and sig.diff is None and _drawn_over(sig, res):
        res.ok, res.credible, res.reason = False, False, DRAWN_LINE
    if res.ok and fit1.reading == "several" and not _several_held(sig, res, R, outside_bad):
        res.ok, res.credible, res.reason = False, False, "no round outline"
    if res.ok:
        _edges_along(sig, res)
    return res


# an accepted outline with less than this share of the strong image edges at it running along
# it (tangent.along_share) is strung together from things that cross it (struts, threads)
MIN_EDGES_ALONG = 0.6
# (the extras key marking an outline refused so: detect._crossing_blocker)
EDGES_CROSS_KEY = "edges_cross"


def _edges_along(sig: Signal, res: CandidateFit) -> None:
    """The last check of an accepted outline: most edges at it run along it (tangent.py), or it
    is refused. A motion smear's outline is exempt (its ramps' gradients need not follow the
    ellipse fitted through their middles)."""
    if res.fit.smear is not None:
        return
    share = along_share(sig.diff if sig.diff is not None else sig.img, sig.origin, res.silhouette_px)
    res.extras["edges_along"] = round(share, 3)
    if share < MIN_EDGES_ALONG:
        res.ok, res.credible = False, False
        res.reason = crossing_edges_reason(share, res.centre_uv_px)
        res.extras[EDGES_CROSS_KEY] = True


DRAWN_LINE = "a round line drawn over the image (an overlay), not an outline"


def _drawn_over(sig: Signal, res: CandidateFit) -> bool:
    """The outline, where it was seen, is a thin line drawn over one surface (:mod:`.overlay`)."""
    sil = res.silhouette_px
    use = sig.covers(sil, max(8.0, 0.05 * _outline_radius(sil)) + 3.0) & seen_mask(res)
    if use.sum() < 8:
        return False
    return is_drawn_line(sig.img, sig.origin, sil, _outline_radius(sil), use)


def seen_mask(res: CandidateFit) -> np.ndarray:
    """(K,) bool over the fitted outline's points: where pass 2 found its edge (all without that
    record). A line drawn in broken arcs (a reticle with gaps) is a line where it is seen."""
    seen = np.zeros(len(res.silhouette_px), bool)
    if res.seen_idx is None or len(res.seen_idx) < 8:
        seen[:] = True
    else:
        seen[res.seen_idx] = True
    return seen


def _outline_radius(sil: np.ndarray) -> float:
    return float(np.mean(np.linalg.norm(sil - sil.mean(axis=0), axis=1)))


def _several_held(sig: Signal, res: CandidateFit, R: float, outside_bad: float) -> bool:
    """A fit that came through the several-edges reading, held to a higher standard: that
    reading chose its edge among several per ray, so a round outline is more easily had by
    chance (in a ball-free scene it found a round patch of one uniform thing 3 times in 240).
    It must meet the tight refit's standard (the other fit that is searched for rather than
    refined: TIGHT_MIN_SUPPORT, TIGHT_RMS_FRACTION of the clean limit), the credible outside
    limit (0.2) unless it is the very clean, mostly visible outline _judge lets stand in
    clutter, and without a background one hue inside all along the outline."""
    return _outline_held(sig, res.fit, res.support, res.extras.get("edge_width_px", np.nan),
                         res.silhouette_px, R, outside_bad)


def _outline_held(sig: Signal, fit: ConeFit, support: float, width_px: float, sil: np.ndarray,
                  R: float, outside_bad: float, need_step: bool = False) -> bool:
    """The standard of :func:`_several_held` on a fit's parts: its share of the outline, its
    edges' median width (px), its outline (K,2 px) and that outline's outside mismatch. With
    ``need_step`` the inside's hue must also step across the outline on every arc counted
    (:func:`_inside_colour_arcs` only; one hue all along is one arc)."""
    # (the tight standard relative to the roundness limit of the outline's edge width: a
    # blurred edge's midpoint scatters more than a sharp one's)
    limit = outline_rms_limit_px(R, width_px)
    if support < TIGHT_MIN_SUPPORT or fit.sigma_px > TIGHT_RMS_FRACTION * limit:
        return False
    # the edges it picked must be edges: any step, seen through the profiles' smoothing, has a
    # gradient at least MIN_EDGE_WIDTH_PX wide; narrower peaks are noise or JPEG ringing (a
    # circle inscribed in a defocused square of one colour found 69 % of its normals on those)
    if width_px < MIN_EDGE_WIDTH_PX:
        return False
    very_clean = support >= 0.7 and fit.sigma_px <= 0.35 * clean_rms_px(R)
    if outside_bad > 0.2 and not very_clean:
        return False
    # a circle picked from several edges per ray can run through unrelated things (a block's
    # corner, mortar lines): a sphere's inside has one hue all along its outline (shading
    # changes only the brightness)
    # (a painted ball: one hue per arc, between the few places where a gore meets the outline)
    if sig.diff is not None:
        return True
    arcs = _inside_colour_arcs(sig, sil, R)
    return (arcs if need_step else max(arcs, _inside_colour_agreement(sig, sil, R))) >= SEVERAL_MIN_INSIDE_AGREEMENT


def _first_pass(cam, sig: Signal, cand: Candidate, R: float, band, a_range_rad, rng) -> list[ConeFit] | str:
    """Pass 1: rays from the coarse centre, outermost strong edge (or, without a background,
    the strongest colour edge when that is rounder). The starts for pass 2, in the order to
    try them (more than one only with a rescued start, :data:`RESCUE_READINGS`), or why
    there is none."""
    k1 = int(np.clip(2 * np.pi * cand.radius_px / 2.5, 48, 180))
    dirs = ray_directions(k1)
    r_dir = _polar_radius(cand, dirs)
    step = max(0.5, R / 60)
    t = np.arange(band[0] * R, band[1] * R + step, step)
    pts = cand.centre_px[None, :] + r_dir[:, None] * dirs
    prof = sig.profiles(pts, dirs, t)
    g = gradient_magnitude(prof, step)
    # rays whose search segment leaves the image see no outline there (a cut sphere); for a
    # candidate at the border (whose coarse size is often short of the outline there) a ray
    # that leaves it only well past the expected outline is used up to the border (its edge
    # must then lie inside the image: see _pass1)
    t_in = min(t[-1], 0.3 * R) if cand.touches_border else t[-1]
    seg_in = cam.in_image(pts + t_in * dirs) & cam.in_image(pts + t[0] * dirs)
    if seg_in.sum() < 12:
        return "no outline edges"
    fit1 = _pass1(cam, pts, dirs, t, g, seg_in, "outermost", a_range_rad, R, rng)
    readings, arc, smoothed = [fit1], None, None
    good1 = fit1 is not None and fit1.inliers.sum() >= 0.75 * seg_in.sum() and fit1.sigma_px <= 1.0
    if cand.source != "background" and not good1:
        # without a background, clutter just outside the outline also makes edges: the
        # strongest colour edge per ray is the other reading; keep the rounder one
        gc = gradient_magnitude(sig.colour_profiles(pts, dirs, t), step)
        alt = _pass1(cam, pts, dirs, t, gc, seg_in, "strongest", a_range_rad, R, rng)
        readings.append(alt)
        if alt is not None and (fit1 is None or _quality(alt) > _quality(fit1)):
            fit1 = alt
        if not _pass1_usable(fit1, seg_in, R) and sig.diff is None:
            # (a clean arc is tried first: a start from single edges is firmer than a circle
            # picked among several per ray; the usable reading after it is the fallback)
            arc = _pass1_arc(cam, sig, readings, seg_in, R)
        if not _pass1_usable(fit1, seg_in, R):
            alt = _pass1_several(cam, sig, pts, dirs, step, R, seg_in, a_range_rad)
            if alt is not None and (fit1 is None or _quality(alt) > _quality(fit1)):
                fit1 = alt
        if not _pass1_usable(fit1, seg_in, R) and sig.diff is None:
            smoothed = _pass1_smoothed(cam, sig, (pts, dirs, t, step, seg_in), a_range_rad, R)
    # too little of the rays on a reading, or so ragged that the refinement, which narrows the
    # band around its outline, cannot make it round: no start (saves pass 2 on clutter)
    starts = [f for f in (arc, fit1 if _pass1_usable(fit1, seg_in, R) else None, smoothed) if f is not None]
    return starts or "no round outline"


def _pass1_usable(fit1: ConeFit | None, seg_in: np.ndarray, R: float) -> bool:
    """A pass-1 fit worth refining: on 40 % of the rays and not too ragged."""
    return (fit1 is not None and fit1.inliers.sum() >= 0.4 * seg_in.sum()
            and fit1.sigma_px <= max(PASS1_MAX_RMS_PX, PASS1_MAX_RMS_FRAC * R))


# ---- pass-1 rescue, without a background: a start for a candidate none of the readings gave
# one. The arc draws nothing (it is a reading's fit kept), the smoothed reading and the pass 2
# after either draw from their own random stream: every other fit's draws stay as they were.
# Pass 2 grows the start into the whole outline and is judged as usual.
RESCUE_READINGS = ("arc", "smoothed")
# a clean partial arc: on at least ARC_MIN_SHARE of the rays (half of the half-visible outline
# the detector accepts: a backrest's or a contact shadow's edges take the outermost and the
# strongest edge on the rest), as round as the tight refit's standard, with one hue just
# inside it, and so well constrained that the outline it predicts on the unseen side lies
# within pass 2's search band at ARC_BAND_SIGMAS standard deviations
ARC_MIN_SHARE = 0.25
ARC_BAND_SIGMAS = 3.0


def _rescued(fit1: ConeFit | None) -> bool:
    return fit1 is not None and fit1.reading in RESCUE_READINGS


def _pass1_arc(cam, sig: Signal, readings, seg_in: np.ndarray, R: float) -> ConeFit | None:
    """The outermost or the strongest reading's fit, when too few rays are on it to be usable
    but it is a clean partial arc (:func:`_arc_held`); before the several reading (a tight
    arc of single edges is a firmer start than a circle picked among several per ray)."""
    arcs = [f for f in readings if f is not None and _arc_held(cam, sig, f, seg_in, R)]
    if not arcs:
        return None
    best = max(arcs, key=_quality)
    best.reading = "arc"
    return best


def _arc_held(cam, sig: Signal, fit: ConeFit, seg_in: np.ndarray, R: float) -> bool:
    """A partial pass-1 arc worth growing (see ARC_MIN_SHARE): enough rays, tight, one surface
    inside, and a prediction of the rest of the outline good to within pass 2's band."""
    if fit.inliers.sum() < max(12, ARC_MIN_SHARE * seg_in.sum()) \
            or fit.sigma_px > TIGHT_RMS_FRACTION * clean_rms_px(R):
        return False
    centre, cov = centre_uv_and_cov(cam, fit)
    if not np.isfinite(centre).all() or not np.isfinite(cov).all():
        return False
    # the apparent radius moves with the half-angle as R / (sin a cos a)
    r_sd = R * np.sqrt(max(float(fit.cov_params[2, 2]), 0.0)) / max(np.sin(fit.a_rad) * np.cos(fit.a_rad), 1e-6)
    outline_sd = float(np.sqrt(np.linalg.eigvalsh(cov)[-1] + r_sd ** 2))
    half = pass2_half_px(fit.sigma_px, R)
    if ARC_BAND_SIGMAS * outline_sd > half:
        return False
    uv = fit.edge_uv_px[fit.inliers]
    nrm = uv - centre[None, :]
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-9)
    gap = max(3.0, 0.04 * R)
    c_in = sample_profiles(sig.img, sig.origin, uv, nrm, -gap - np.arange(3.0)).mean(axis=1) + 1.0
    hues = c_in / np.linalg.norm(c_in, axis=1, keepdims=True)
    return _within(hues) >= SEVERAL_MIN_INSIDE_AGREEMENT * len(hues)


def _pass1_smoothed(cam, sig: Signal, geo, a_range_rad, R: float) -> ConeFit | None:
    """Pass 1 on profiles smoothed along the rays by BLUR_SCALES_PX (as pass 2's smoothed
    reading): a motion-smeared outline is a ramp whose outermost and strongest raw gradient
    peaks are the sharp texture seen through it, scattered over its width; the smoothed
    gradient peaks at the ramp's middle. Not on a small blob, nor wider than a quarter radius
    (as :func:`outline_rms_limit_px`); usable as any pass-1 fit."""
    pts, dirs, t, step, seg_in = geo
    if R < SMALL_RADIUS_PX:
        return None
    prof = (sig.profiles(pts, dirs, t), sig.colour_profiles(pts, dirs, t))
    for s in BLUR_SCALES_PX:
        if 2.3548 * s > BLUR_MAX_RADIUS_FRACTION * R:
            break
        best = None
        for rule, p in zip(("outermost", "strongest"), prof):
            g = gradient_magnitude(gaussian_filter1d(p, s / step, axis=1, mode="nearest"), step)
            fit = _pass1(cam, pts, dirs, t, g, seg_in, rule, a_range_rad, R, np.random.default_rng(len(t)))
            if _pass1_usable(fit, seg_in, R) and (best is None or _quality(fit) > _quality(best)):
                best = fit
        if best is not None:
            best.reading = "smoothed"
            return best
    return None


def centre_floor_px2(edge_rms_px: float, radius_px: float, edge_width_px: float, blur_allowed: bool = True,
                     lopsided_px2: float = 0.0) -> float:
    """Variance (px^2) per image axis that the whole outline shares, added to the cone fit's
    centre covariance (which sees only the scatter of the edge points about the outline):
    systematic outline deviations (ragged open-mesh envelope, shading, JPEG), SYS_FRACTION x the
    edge RMS; a blurred outline's plateau (image.blur; only when ``blur_allowed``, a mostly
    visible outline); the lopsided limb, EDGE_WIDTH_FRACTION x the edge width (see above;
    nothing when the width is unknown), and the share its residuals show (``lopsided_px2``,
    image.limb.lopsided_floor_px2)."""
    v = (SYS_FRACTION * edge_rms_px) ** 2 + lopsided_px2
    if blur_allowed:
        v += blur_floor_px2(radius_px, edge_width_px)
    if np.isfinite(edge_width_px) and edge_width_px > 0:
        v += (EDGE_WIDTH_FRACTION * edge_width_px) ** 2
    return float(v)


def _lopsided_px2(fit: ConeFit, sil_f: np.ndarray, centre: np.ndarray, ok2: np.ndarray, k2: int) -> float:
    """The lopsided limb's floor (limb.lopsided_floor_px2) of a pass-2 fit: its inlier edges'
    residuals at the angles of their normals (the K outline points of the fit, in pass 2's order)."""
    nrm = outward_normals(sil_f, centre if np.isfinite(centre).all() else sil_f.mean(axis=0))
    th = np.arctan2(nrm[:, 1], nrm[:, 0])[ok2][fit.inliers]
    perim = float(np.linalg.norm(np.diff(np.vstack([sil_f, sil_f[:1]]), axis=0), axis=1).sum())
    corr = max(1.0, CORR_LENGTH_PX * k2 / max(perim, 1e-9))
    return lopsided_floor_px2(fit.residuals_px[fit.inliers], th, float(fit.sigma_px), corr)


def _fitted(cam, sig: Signal, p2, R: float, sphere_radius_m: float) -> tuple[CandidateFit, float]:
    """The pass-2 fit as a candidate fit (centre, covariance, outline, support, score,
    contrast, range; extras), not yet judged; and the outline's outside mismatch."""
    fit, ok2, s2, k2, widths = p2
    centre, cov = centre_uv_and_cov(cam, fit)
    sil_f = silhouette_uv(cam, fit.w, fit.a_rad, n=k2)
    support = float(fit.inliers.sum()) / k2
    # peak gradient of a step c smoothed by a Gaussian is c / (sigma sqrt(2 pi)); optics blur ignored
    contrast = float(np.median(s2[ok2][fit.inliers])) * SMOOTH_SIGMA_PX * np.sqrt(2 * np.pi)
    width = float(np.median(widths[fit.inliers])) if fit.inliers.any() else float("nan")
    # raggedness relative to what an edge of this width gives (a sharp edge: unchanged)
    # (the allowance as in _judge: only for a mostly visible outline)
    limit = outline_rms_limit_px(R, width if support >= TIGHT_MIN_SUPPORT else np.nan)
    sigma_rel = fit.sigma_px * clean_rms_px(R) / limit
    score = float(np.clip(support, 0, 1) * np.exp(-max(0.0, sigma_rel - 0.3) / 0.7))
    limb = _lopsided_px2(fit, sil_f, centre, ok2, k2)
    cov = cov + centre_floor_px2(fit.sigma_px, R, width, support >= TIGHT_MIN_SUPPORT, limb) * np.eye(2)
    res = CandidateFit(True, "", fit, centre, cov, sil_f, support, score, contrast,
                       float(sphere_radius_m / np.sin(fit.a_rad)))
    res.extras = {"edge_points": int(ok2.sum()), "inliers": int(fit.inliers.sum()),
                  "edge_rms_px": round(float(fit.sigma_px), 4), "support": round(support, 4),
                  "edge_contrast": round(float(contrast), 2),
                  "edge_width_px": round(width, 3), "lopsided_limb_px": round(float(np.sqrt(limb)), 4)}
    visible = cam.in_image(sil_f, margin_px=0.05 * R + 8)
    outside_bad = _outside_mismatch(sig, sil_f[visible], outward_normals(sil_f, sil_f.mean(axis=0))[visible], R) \
        if visible.sum() >= 8 else 1.0
    if fit.smear is not None:  # (read as a motion smear: its measured length and direction)
        res.extras["smear_px"] = round(fit.smear.length_px, 2)
        res.extras["smear_deg"] = round(float(np.degrees(fit.smear.angle_rad)), 1)
    res.extras["outside_mismatch"] = round(outside_bad, 4)
    res.extras["outline_coverage"] = round(support, 3)
    r_fit = float(np.mean(np.linalg.norm(sil_f - sil_f.mean(axis=0), axis=1)))
    res.seen_idx = np.flatnonzero(ok2)[fit.inliers]
    res.wobble = outline_wobble(res.seen_idx, k2, fit.residuals_px[fit.inliers], r_fit)
    if res.wobble is not None:
        res.extras["outline_wobble"] = round(res.wobble.excess_fraction, 4)
    return res, outside_bad


def _judge(cam, res: CandidateFit, R: float, outside_bad: float, with_background: bool) -> None:
    """Set ``res.credible``, ``res.ok`` and ``res.reason``: cut by the border, not round,
    mostly hidden, or inside a larger object."""
    fit, sil_f, support = res.fit, res.silhouette_px, res.support
    # a clean outline, maybe cut by the border: things inside it are its texture
    # judged at the fitted size (the candidate's coarse size can be well off)
    r_fit = float(np.mean(np.linalg.norm(sil_f - sil_f.mean(axis=0), axis=1)))
    # the wider limit of a blurred outline is a looser test: like the tight refit (the other
    # outline searched for rather than refined) it needs TIGHT_MIN_SUPPORT of the outline (a
    # soft-edged part-circle in texture is easily had)
    width = res.extras.get("edge_width_px", np.nan) if support >= TIGHT_MIN_SUPPORT else np.nan
    clean = fit.sigma_px <= outline_rms_limit_px(min(R, r_fit), width)
    # (a tile, a cell of a caustic network: round within the inlier band, not in its shape)
    corners = res.wobble is not None and res.wobble.has_corners
    clean = clean and not corners
    res.credible = support >= 0.45 and clean and outside_bad <= 0.2
    if not cam.in_image(sil_f, margin_px=1.0).all():
        res.ok = False
        partial_ok = support >= 0.3 and clean and outside_bad <= 0.25
        res.reason = "sphere cut by the image border" if partial_ok else "no round outline near the border"
    elif corners:
        res.ok, res.reason = False, res.wobble.reason
    elif not clean:
        res.ok, res.reason = False, f"outline not round (edge RMS {fit.sigma_px:.1f} px)"
    elif support < MIN_SUPPORT:
        res.ok, res.reason = False, f"outline {100 * (1 - support):.0f} % hidden or too faint"
    elif (outside_bad > (0.2 if with_background else OUTSIDE_MISMATCH_CLUTTER)
          and not (support >= 0.7 and outside_bad <= 0.5
                   and fit.sigma_px <= 0.35 * clean_rms_px(R))):
        # (a mostly visible, very clean round outline is a sphere whatever lies around it: a
        # ball resting on a block, in front of clutter)
        # the object goes on beyond the fitted outline: part of something larger (or cut)
        res.ok, res.reason = False, "round outline inside a larger object"


def pass2_half_px(sigma_px: float, R: float) -> float:
    """Half-width (px) of the band pass 2 searches around a pass-1 outline of edge RMS
    ``sigma_px`` and apparent radius ``R`` (also what a rescued arc's prediction must fit in)."""
    return max(3.0, 3.0 * sigma_px + 1.5, 0.02 * R)


def _outline_normals(cam, fit1: ConeFit):
    """(outline px (K,2), its normalised points, outward normals, K, perimeter px) of a fit's
    outline, one normal per EDGE_SPACING_PX; None when the outline is not all in front."""
    sil = silhouette_uv(cam, fit1.w, fit1.a_rad, n=180)
    if not np.isfinite(sil).all():
        return None
    perim = float(np.linalg.norm(np.diff(np.vstack([sil, sil[:1]]), axis=0), axis=1).sum())
    k2 = int(np.clip(perim / EDGE_SPACING_PX, 64, 360))
    sil_xy = silhouette_xy(fit1.w, fit1.a_rad, k2)
    sil = cam.distort(sil_xy)
    ctr = cam.project(fit1.w[None, :])[0]
    nrm = outward_normals(sil, sil.mean(axis=0) if np.isfinite(ctr).all() else ctr)
    return sil, sil_xy, nrm, k2, perim


def _smear_read(cam, sig, fit1: ConeFit, R: float, a_range_rad, geo, half: float):
    """:func:`_pass2_smear`, then once more along the normals of its own outline (the ramps'
    windows centred on them: the reading no longer depends on where the start put them)."""
    first = _pass2_smear(cam, sig, fit1, R, a_range_rad, geo, half)
    geo2 = None if first is None else _outline_normals(cam, first[0])
    if geo2 is None:
        return first
    again = _pass2_smear(cam, sig, first[0], R, a_range_rad, geo2, pass2_half_px(first[0].sigma_px, R))
    return again if again is not None and again[0].inliers.sum() >= first[0].inliers.sum() * 0.9 else first


def _pass2(cam, sig, fit1: ConeFit, R: float, a_range_rad, rng):
    """Edges along the normals of ``fit1``'s outline, refitted: (fit, used mask, strengths, K,
    edge widths). When that outline is not round for its edge width, the same normals are read
    again on profiles smoothed along them (BLUR_SCALES_PX): a motion-smeared edge is a ramp
    whose gradient is a low plateau, studded with the sharp edges of the still scene seen
    through the ramp; its smoothed gradient peaks at the ramp's middle, where the outline is."""
    geo = _outline_normals(cam, fit1)
    if geo is None:
        return None
    half = pass2_half_px(fit1.sigma_px, R)
    best = _pass2_reading(cam, sig, fit1, R, a_range_rad, rng, geo, half, 0.0)
    if best is None or best[0].sigma_px > 0.5 * clean_rms_px(R) or best[0].inliers.mean() < 0.9:
        alt = _pass2_several(cam, sig, fit1, R, a_range_rad, geo, max(half, PASS2_SEVERAL_HALF_FRAC * R))
        if alt is not None and _searched_held(cam, sig, alt, R) and (best is None or _quality(alt[0]) > _quality(best[0])):
            best = alt
    if R >= SMALL_RADIUS_PX and (best is None or is_blurred(_median_width(best))
                                 or best[0].sigma_px > outline_rms_limit_px(R, _median_width(best))):
        # a blurred or ragged outline: read it as a motion smear's ramps when the edge widths
        # around it say the blur is one (smear.py)
        alt = _smear_read(cam, sig, fit1, R, a_range_rad, geo, half)
        if alt is not None and _smear_held(cam, sig, alt, R) and (best is None or _quality(alt[0]) > _quality(best[0])):
            best = alt
    for s in BLUR_SCALES_PX:
        if best is not None and best[0].sigma_px <= outline_rms_limit_px(R, _median_width(best)):
            break
        if R < SMALL_RADIUS_PX or 2.3548 * s > BLUR_MAX_RADIUS_FRACTION * R:
            break  # (no smear on a small blob, none wider than a quarter radius: as outline_rms_limit_px)
        alt = _pass2_reading(cam, sig, fit1, R, a_range_rad, np.random.default_rng(geo[3]), geo, half + 3.0 * s, s)
        if alt is not None and _smoothed_held(alt, R) and (best is None or _quality(alt[0]) > _quality(best[0])):
            best = alt
    return best


def _pass2_smear(cam, sig: Signal, fit1: ConeFit, R: float, a_range_rad, geo, half: float):
    """Pass 2 read as a motion smear (:mod:`calib_core.detect.image.smear`): each normal's edge
    is the middle of the ramp its profile matches best, at the width the smear measured around
    the outline predicts there; None unless that smear is real (its anisotropy stands out from
    its standard error). An edge must stand for a colour step the region's noise and texture do
    not make (a step whose sharp gradient would pass pass 2's EDGE_NOISE_FACTOR) and at least
    0.3 of the typical step (as pass 2's readings). Same return as :func:`_pass2_reading`, the
    widths being the smear model's; its own random stream."""
    sil, sil_xy, nrm, k2, perim = geo
    reach = smear.window_px(R)
    t2 = np.arange(-half - reach, half + reach + 0.25, smear.STEP_PX)
    sig = sig.around(sil, half + reach + 1.0)
    use = cam.in_image(sil, margin_px=1.0) & sig.covers(sil, half + reach + 1.0)
    if use.sum() < 12:
        return None
    theta = np.arctan2(nrm[use, 1], nrm[use, 0])
    min_step = EDGE_NOISE_FACTOR * sig.noise * np.sqrt(2 * np.pi) * SMOOTH_SIGMA_PX
    te, step, w_k, sm = smear.read(sig.colour_profiles(sil[use], nrm[use], t2), t2, np.abs(t2) <= half, theta,
                                   R, max(1.0, CORR_LENGTH_PX * k2 / perim), min_step)
    if not sm.real:
        return None
    keep = step >= max(0.3 * float(np.median(step)), min_step)
    ok2 = np.zeros(k2, bool)
    ok2[np.flatnonzero(use)[keep]] = True
    if ok2.sum() < 12:
        return None
    uv2 = sil[ok2] + te[keep, None] * nrm[ok2]
    xy2 = normalize_near(cam, uv2, sil_xy[ok2], iterations=3)
    fit = _pass2_fit(cam, xy2, fit1, R, a_range_rad, np.random.default_rng(k2), k2, perim)
    # (the smear at most MAX_RADIUS_FRACTION of the fitted outline's radius, as of the bank's)
    if fit is None or sm.length_px > smear.MAX_RADIUS_FRACTION * cam.fx * np.tan(fit.a_rad):
        return None
    fit.reading = "smear"
    fit.smear = sm
    s2 = np.zeros(k2)
    s2[ok2] = step[keep] / (np.sqrt(2 * np.pi) * SMOOTH_SIGMA_PX)  # (as a sharp step's gradient peak)
    return fit, ok2, s2, k2, w_k[keep]


def _smear_held(cam, sig: Signal, p2, R: float) -> bool:
    """A smear reading's fit held like the other outlines searched for (:func:`_outline_held`:
    the tight refit's standard for its edge width, the surroundings just outside it, one hue
    inside per long arc with a colour step across the outline on each): it is searched for among
    ramp widths and positions, and oriented texture (brick courses) has edge widths that vary with
    the angle as a smear's do."""
    fit, _, _, k2, _ = p2
    sil = silhouette_uv(cam, fit.w, fit.a_rad, n=k2)
    visible = cam.in_image(sil, margin_px=0.05 * R + 8)
    if visible.sum() < 8 or not np.isfinite(sil).all():
        return False
    outside_bad = _outside_mismatch(sig, sil[visible], outward_normals(sil, sil.mean(axis=0))[visible], R)
    return _outline_held(sig, fit, float(fit.inliers.sum()) / k2, _median_width(p2), sil, R, outside_bad, need_step=True)


# the several-edges reading of pass 2 looks this far (x the coarse radius) either side of the
# pass-1 outline: 3 x pass 1's inlier band (0.04 R), plus room for the peak's neighbours
PASS2_SEVERAL_HALF_FRAC = 0.15


def _pass2_several(cam, sig: Signal, fit1: ConeFit, R: float, a_range_rad, geo, half: float):
    """Pass 2 read from the few strongest edges of every normal in a wider band, the outline
    being the cone most of them agree on, then one edge per normal (the nearest to it): where
    pass 1 is a few px off on one side and a strong edge just inside the ball, nearly parallel
    to its limb (a beach ball's gore boundary, a seam), is the outermost and strongest edge in
    the narrow band there, the ball's own outline lying just beyond it. A gore boundary runs
    along the limb over a stretch only; the limb is round all the way. Same return as
    :func:`_pass2_reading` (fit, used mask, strengths, K, edge widths); its own random stream."""
    sil, sil_xy, nrm, k2, perim = geo
    t2 = np.arange(-half, half + 0.25, 0.5)
    inside_img = cam.in_image(sil, margin_px=1.0) & sig.covers(sil, half + 1.0)
    g2 = gradient_magnitude(sig.colour_profiles(sil, nrm, t2), 0.5)
    if not inside_img.any():
        return None
    thr = max(0.3 * float(np.median(g2.max(axis=1)[inside_img])), EDGE_NOISE_FACTOR * sig.noise)
    te = edge_peaks(t2, g2, thr, SEVERAL_PEAKS)
    ray = np.broadcast_to(np.arange(k2)[:, None], te.shape)
    ok = np.isfinite(te) & inside_img[:, None]
    ray, te = ray[ok], te[ok]
    if len(np.unique(ray)) < 12:
        return None
    xy = normalize_near(cam, sil[ray] + te[:, None] * nrm[ray], sil_xy[ray], iterations=3)
    band = max(1.0, 0.01 * R)
    rng = np.random.default_rng(k2)
    fit = fit_cone(cam, xy, a_range_rad, inlier_px=band, rng=rng, max_iter=6, n_hyp=SEVERAL_HYPOTHESES)
    if fit is None:
        return None
    order = np.lexsort((np.abs(fit.residuals_px), ray))
    first = order[np.r_[True, ray[order][1:] != ray[order][:-1]]]
    one = np.full(k2, np.nan)
    one[ray[first]] = te[first]
    ok2 = np.isfinite(one)
    fit = _pass2_fit(cam, xy[first], fit, R, a_range_rad, rng, k2, perim)
    if fit is None:
        return None
    fit.reading = "several"
    _, s2 = pick_edges(t2, g2, "nearest", thr, np.where(ok2, one, 0.0))
    return fit, ok2, s2, k2, edge_widths(t2, g2, one)[ok2]


def _searched_held(cam, sig: Signal, p2, R: float) -> bool:
    """A pass-2 outline searched for among several edges per normal, held like the several
    reading of pass 1 (:func:`_outline_held`: the tight refit's standard, the outside looks
    like the surroundings, one hue inside per long arc with a colour step across the outline
    on each) and its edge width a smear's at most
    (as :func:`_smoothed_held`)."""
    fit, _, _, k2, _ = p2
    width = _median_width(p2)
    if not width <= BLUR_MAX_RADIUS_FRACTION * R:
        return False
    sil = silhouette_uv(cam, fit.w, fit.a_rad, n=k2)
    visible = cam.in_image(sil, margin_px=0.05 * R + 8)
    if visible.sum() < 8 or not np.isfinite(sil).all():
        return False
    outside_bad = _outside_mismatch(sig, sil[visible], outward_normals(sil, sil.mean(axis=0))[visible], R)
    # (a colour step across the outline all round: this reading looks farther from pass 1's
    # outline, among more edges, than any other; a small round patch in a block's corner had
    # one hue inside but the same colours outside)
    return _outline_held(sig, fit, float(fit.inliers.sum()) / k2, width, sil, R, outside_bad, need_step=True)


def _smoothed_held(p2, R: float) -> bool:
    """A smoothed reading's fit held to the tight refit's standard (smoothing makes any blob of
    texture rounder; like the several reading it is searched for): TIGHT_MIN_SUPPORT of the
    normals, edge RMS within TIGHT_RMS_FRACTION of the roundness limit of its edge width; and
    that width a smear's, not wider than a quarter of the radius (beyond: a streak, a shaded
    patch)."""
    fit, _, _, k2, _ = p2
    return (fit.inliers.sum() >= TIGHT_MIN_SUPPORT * k2
            and _median_width(p2) <= BLUR_MAX_RADIUS_FRACTION * R
            and fit.sigma_px <= TIGHT_RMS_FRACTION * outline_rms_limit_px(R, _median_width(p2)))


# smoothing (px, Gaussian sigma along the normal) of the profiles read again when the outline is
# not round for its edge width: a ramp of a few to a quarter radius wide
BLUR_SCALES_PX = (2.0, 4.0)


def _median_width(p2) -> float:
    fit, _, _, _, widths = p2
    return float(np.median(widths[fit.inliers])) if fit.inliers.any() else float("nan")


def _pass2_reading(cam, sig, fit1: ConeFit, R: float, a_range_rad, rng, geo, half: float, smooth_px: float):
    """One pass-2 reading: edges within ``half`` px of ``fit1``'s outline along its normals, on
    profiles smoothed along them by ``smooth_px`` (0: as sampled). The widths returned are those
    of the edges before that smoothing (its share taken out in quadrature)."""
    sil, sil_xy, nrm, k2, perim = geo
    t2 = np.arange(-half, half + 0.25, 0.5)
    # a normal whose band leaves the region of interest is not used: the samples there would be
    # the region's replicated border, not the image (pass 1 can fit a large outline from one
    # arc of it, seen from a candidate well off its centre)
    inside_img = cam.in_image(sil, margin_px=1.0) & sig.covers(sil, half + 1.0)
    prof = sig.colour_profiles(sil, nrm, t2)
    if smooth_px > 0:
        prof = gaussian_filter1d(prof, smooth_px / 0.5, axis=1, mode="nearest")
    g2 = gradient_magnitude(prof, 0.5)
    g2_typ = float(np.median(g2.max(axis=1)[inside_img])) if inside_img.any() else 0.0
    # the region's noise and texture, smoothed alike (per px of gradient, white noise falls as s^1.5)
    noise = sig.noise * min(1.0, (SMOOTH_SIGMA_PX / np.hypot(SMOOTH_SIGMA_PX, smooth_px)) ** 1.5)
    # the outline's envelope (outermost edge; open-mesh texture lies inside it) and, without a
    # background, also the strongest edge (clutter just outside the outline makes edges too)
    best = None
    for rule in ("outermost",) if sig.diff is not None else ("outermost", "strongest"):
        if best is not None and best[0].sigma_px <= 0.5 * clean_rms_px(R) \
                and best[0].inliers.mean() >= 0.9:
            break  # the envelope reading is clean already
        # an edge must stand out from the region's noise and texture: in noise alone, the
        # outermost of the small gradient peaks sits at the band's end for every normal and
        # makes a "round outline" of its own
        te, s2 = pick_edges(t2, g2, rule, max(0.3 * g2_typ, EDGE_NOISE_FACTOR * noise))
        ok2 = np.isfinite(te) & inside_img
        if ok2.sum() < 12:
            continue
        uv2 = sil[ok2] + te[ok2, None] * nrm[ok2]
        # edge points are within a few px of the model outline: Newton from its normalised points
        xy2 = normalize_near(cam, uv2, sil_xy[ok2], iterations=3)
        fit = _pass2_fit(cam, xy2, fit1, R, a_range_rad, rng, k2, perim)
        if fit is not None and (best is None or _quality(fit) > _quality(best[0])):
            w = edge_widths(t2, g2, te)[ok2]
            w = np.sqrt(np.maximum(w ** 2 - (2.3548 * smooth_px) ** 2, 0.0))
            best = (fit, ok2, s2, k2, w)
    return best


def _pass2_fit(cam, xy2, fit1: ConeFit, R: float, a_range_rad, rng, k2: int, perim: float) -> ConeFit | None:
    """The pass-2 cone on one reading's edge points: refined from ``fit1``, or, when that is
    not clean, the tightest majority's cone if it is very round."""
    kw = dict(inlier_px=max(1.0, 0.01 * R), rng=rng, corr_points=max(1.0, CORR_LENGTH_PX * k2 / perim))
    fit = fit_cone(cam, xy2, a_range_rad, start=(fit1.w, fit1.a_rad), **kw)
    if fit is None or fit.sigma_px > clean_rms_px(R):
        # edges of things touching the sphere (a seat, a backrest) pulled the fit off:
        # search again for the cone the tightest majority of the edges lie on
        # (it must be very round on the edges it keeps: a circle forced onto a box or onto
        # chair legs keeps a few tangent stretches, each off by up to the band)
        alt = fit_cone(cam, xy2, a_range_rad, tight=True, **kw)
        if (alt is not None and alt.sigma_px <= TIGHT_RMS_FRACTION * clean_rms_px(R)
                and alt.inliers.sum() >= TIGHT_MIN_SUPPORT * k2
                and (fit is None or _quality(alt) > _quality(fit))):
            fit = alt
    return fit


def _quality(fit: ConeFit) -> float:
    """Edge points on the cone, discounted by their spread (px): to choose between readings."""
    return float(fit.inliers.sum()) / (1.0 + fit.sigma_px ** 2)


def _pass1(cam, pts, dirs, t, g, seg_in, rule, a_range_rad, R, rng) -> ConeFit | None:
    """Pass-1 cone fit to one edge per ray (``rule`` of :func:`pick_edges`)."""
    t1, _ = pick_edges(t, g, rule, 0.35 * float(np.median(g.max(axis=1)[seg_in])))
    ok = np.isfinite(t1) & seg_in
    ok[ok] = cam.in_image(pts[ok] + t1[ok, None] * dirs[ok], margin_px=2.0)
    if ok.sum() < 12:
        return None
    uv1 = pts[ok] + t1[ok, None] * dirs[ok]
    fit = fit_cone(cam, normalize_near(cam, uv1), a_range_rad, inlier_px=max(1.5, 0.04 * R), rng=rng,
                   max_iter=6)
    if fit is not None:
        fit.edge_uv_px = uv1
    return fit


# the "several" reading: this many strongest edges per ray, down to this share of the typical
# strongest edge of a ray, and this many 3-point hypotheses (most points are not the outline)
SEVERAL_PEAKS = 4
SEVERAL_MIN_SHARE = 0.15
SEVERAL_HYPOTHESES = 512
SEVERAL_BAND = (-0.65, 0.8)


def _pass1_several(cam, sig: Signal, pts, dirs, step, R, seg_in, a_range_rad) -> ConeFit | None:
    """Pass-1 cone fit to the few strongest colour edges of every ray, then to one edge per ray
    (the one nearest to that cone): where the sphere's outline is neither the outermost nor
    the strongest edge (a dark ball before a dark backrest whose own edge is stronger and
    farther out). The band reaches farther in (SEVERAL_BAND): a candidate drawn to the chair
    around the ball can be twice the ball's size."""
    t = np.arange(SEVERAL_BAND[0] * R, SEVERAL_BAND[1] * R + step, step)
    g = gradient_magnitude(sig.colour_profiles(pts, dirs, t), step)
    te = edge_peaks(t, g, SEVERAL_MIN_SHARE * float(np.median(g.max(axis=1)[seg_in])), SEVERAL_PEAKS)
    ray = np.broadcast_to(np.arange(len(te))[:, None], te.shape)
    ok = np.isfinite(te) & seg_in[:, None]
    uv = pts[ray[ok]] + te[ok, None] * dirs[ray[ok]]
    inside = cam.in_image(uv, margin_px=2.0)
    uv, ray = uv[inside], ray[ok][inside]
    if len(np.unique(ray)) < 12:
        return None
    xy = normalize_near(cam, uv)
    band = max(1.5, 0.04 * R)
    # its own random stream: trying this reading must not change the draws of the fits after it
    # (the detection of a candidate this reading does not help stays what it was)
    fit = fit_cone(cam, xy, a_range_rad, inlier_px=band, rng=np.random.default_rng(len(xy)), max_iter=6,
                   n_hyp=SEVERAL_HYPOTHESES)
    if fit is None:
        return None
    # one edge per ray: the nearest to the cone
    order = np.lexsort((np.abs(fit.residuals_px), ray))
    first = order[np.r_[True, ray[order][1:] != ray[order][:-1]]]
    fit = fit_cone(cam, xy[first], a_range_rad, inlier_px=band, max_iter=6, start=(fit.w, fit.a_rad))
    if fit is not None:
        fit.reading = "several"
    return fit


SEVERAL_MIN_INSIDE_AGREEMENT = 0.75
# the narrowest gradient peak (FWHM, px) a step edge can have after the SMOOTH_SIGMA_PX smoothing
# of the profiles (a Gaussian's FWHM; the optics and JPEG only widen it)
MIN_EDGE_WIDTH_PX = 2.3548 * SMOOTH_SIGMA_PX
HUE_TOLERANCE_RAD = 0.12


# an arc of one hue: at least this share of the outline (a gore meets it over 1/16-1/4 of it);
# a change of hue is looked for between points HUE_STEP_LAG apart (a gore's boundary is blurred
# over a few px, ~2 px between outline points: neighbours alone differ too little)
SEVERAL_MIN_ARC_SHARE = 0.05
HUE_STEP_LAG = 2


def _inside_hues(sig: Signal, sil: np.ndarray, R: float) -> np.ndarray:
    """(K,3) unit RGB directions just inside the outline (shading scales a colour, does not turn it)."""
    c_in, _ = _colours_across(sig, sil, R)
    c_in = c_in + 1.0
    return c_in / np.linalg.norm(c_in, axis=1, keepdims=True)


def _colours_across(sig: Signal, sil: np.ndarray, R: float) -> tuple[np.ndarray, np.ndarray]:
    """(K,3) mean colours just inside and just outside the outline (3 samples each, a gap of
    max(3 px, 4 % of the radius) from it: the edge's own blur left out)."""
    gap = max(3.0, 0.04 * R)
    nrm = outward_normals(sil, sil.mean(axis=0))
    c_in = sample_profiles(sig.img, sig.origin, sil, nrm, -gap - np.arange(3.0)).mean(axis=1)
    c_out = sample_profiles(sig.img, sig.origin, sil, nrm, gap + np.arange(3.0)).mean(axis=1)
    return c_in, c_out


def _within(d: np.ndarray) -> int:
    """How many unit directions lie within HUE_TOLERANCE_RAD of their median."""
    med = np.median(d, axis=0)
    med /= max(float(np.linalg.norm(med)), 1e-9)
    return int(np.sum(np.arccos(np.clip(d @ med, -1.0, 1.0)) < HUE_TOLERANCE_RAD))


def _inside_colour_agreement(sig: Signal, sil: np.ndarray, R: float) -> float:
    """Share of the outline whose colour just inside points within HUE_TOLERANCE_RAD of the
    median inside colour."""
    d = _inside_hues(sig, sil, R)
    return _within(d) / len(d)


def _hue_arcs(d: np.ndarray) -> list[np.ndarray]:
    """Index arrays (into the outline's K points) of the arcs of one hue at least
    SEVERAL_MIN_ARC_SHARE of the outline long: the outline split where the hue ``d`` (K,3 unit
    directions) turns by more than HUE_TOLERANCE_RAD over HUE_STEP_LAG points."""
    k = len(d)
    turn = np.arccos(np.clip((d * np.roll(d, -HUE_STEP_LAG, axis=0)).sum(axis=1), -1.0, 1.0)) > HUE_TOLERANCE_RAD
    if not turn.any():
        return [np.arange(k)]
    start = int(np.flatnonzero(turn)[0])
    steady = np.roll(~turn, -start)  # (begins on a turn: no arc wraps around the end)
    edges = np.flatnonzero(np.diff(np.r_[0, steady.astype(np.int8), 0]))
    return [(start + np.arange(a, b)) % k for a, b in zip(edges[::2], edges[1::2])
            if b - a >= max(4, SEVERAL_MIN_ARC_SHARE * k)]


# a colour step across the outline: at least half of an arc's points must step by more than
# the colour noise alone gives at a 5 % false-alarm rate per point. The noise of one in-out
# difference is measured locally, on the arc itself: the differences between points of one
# side the same distance apart along the arc as the inside and outside samples are across it.
# Taken as Gaussian along one colour direction (texture is mostly luminance; the conservative
# case): the two-sided 5 % point is 1.96 sigma, the median of |difference| 0.6745 sigma. An
# arc passes by chance only if half of its points do: for the ~n/lag >= 4 independent ones of
# the shortest arc, P(Binomial(4, 0.05) >= 2) = 1.4 %, far less for longer arcs.
STEP_FALSE_ALARM_Z = 1.96
MEDIAN_ABS_NORMAL = 0.6745


def _arc_has_step(c_in: np.ndarray, c_out: np.ndarray, lag: int) -> bool:
    """Whether an arc's inside and outside colours (n,3 each, in order along the arc) differ
    by a real step: the median in-out distance beyond the 5 % point of the same-side
    differences ``lag`` points apart (the noise and texture of each side, at the in-out
    separation). A circle cut through one textured surface (brick, boards) has about the same
    colours on both sides; a ball's painted gore against its surroundings does not."""
    lag = int(np.clip(lag, 1, max(1, len(c_in) // 3)))
    same = np.r_[np.linalg.norm(c_in[lag:] - c_in[:-lag], axis=1),
                 np.linalg.norm(c_out[lag:] - c_out[:-lag], axis=1)]
    step = float(np.median(np.linalg.norm(c_in - c_out, axis=1)))
    return step > STEP_FALSE_ALARM_Z / MEDIAN_ABS_NORMAL * float(np.median(same))


def _step_lag(sil: np.ndarray, R: float) -> int:
    """Points along the outline as far apart as the inside and outside samples of
    :func:`_colours_across` are across it."""
    spacing = float(np.mean(np.linalg.norm(np.diff(sil, axis=0), axis=1)))
    return max(1, int(round(2.0 * (max(3.0, 0.04 * R) + 1.0) / max(spacing, 1e-6))))


def _inside_colour_arcs(sig: Signal, sil: np.ndarray, R: float) -> float:
    """Share of the outline in long arcs of one hue each: a painted ball (beach-ball gores,
    panels) changes hue only where a panel's boundary meets the outline, a few times around it;
    a circle run through texture or several objects changes it often. Arcs (:func:`_hue_arcs`)
    count with their points within tolerance of their own median hue, and only where the
    colour steps across the outline (:func:`_arc_has_step`): a circle straddling two
    textured surfaces (brick above, boards below) has two long arcs of one hue, but each lies
    on one surface, whose colour goes on outside it."""
    c_in, c_out = _colours_across(sig, sil, R)
    d = (c_in + 1.0) / np.linalg.norm(c_in + 1.0, axis=1, keepdims=True)
    lag = _step_lag(sil, R)
    good = sum(_within(d[ix]) for ix in _hue_arcs(d) if _arc_has_step(c_in[ix], c_out[ix], lag))
    return good / len(d)


def _outside_mismatch(sig: Signal, sil: np.ndarray, nrm: np.ndarray, R: float) -> float:
    """Fraction of the outline where the band just outside does not look like the surroundings.

    Just outside a true silhouette the signal is background (difference ~ noise, or the local
    surroundings' colour without a background image); a circle fitted inside a larger or cut
    object has the object itself there.
    """
    gap = max(3.0, 0.04 * R)
    t_in = -gap - np.arange(3.0)
    t_out = gap + np.arange(3.0)
    if sig.diff is not None:
        p_in = sample_profiles(sig.diff, sig.origin, sil, nrm, t_in)[..., 0].mean(axis=1)
        p_out = sample_profiles(sig.diff, sig.origin, sil, nrm, t_out)[..., 0].mean(axis=1)
    else:
        t_far = np.linspace(0.25 * R + gap, 0.35 * R + gap, 4)
        c_far = np.median(sample_profiles(sig.img, sig.origin, sil, nrm, t_far), axis=1)
        c_in = sample_profiles(sig.img, sig.origin, sil, nrm, t_in).mean(axis=1)
        c_out = sample_profiles(sig.img, sig.origin, sil, nrm, t_out).mean(axis=1)
        p_in = np.linalg.norm(c_in - c_far, axis=1)
        p_out = np.linalg.norm(c_out - c_far, axis=1)
        # in clutter the colour farther out varies by itself (brick, tiles, another block):
        # the band outside counts as "the object goes on" only where it also looks more like
        # the inside than like the surroundings farther out (a red ball on red brick)
        typical = float(np.median(p_in))
        like_inside = np.linalg.norm(c_out - c_in, axis=1) < p_out
        return float(np.mean((p_out > 0.5 * max(typical, 1e-6)) & like_inside))
    typical = float(np.median(p_in))
    return float(np.mean(p_out > 0.5 * max(typical, 1e-6)))
