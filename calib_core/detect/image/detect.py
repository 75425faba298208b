"""Sphere detection in camera images.

Main entry: :func:`detect_sphere_in_image`. Steps:

1. coarse candidates in a downscaled image: difference to a background model when there is
   one (:mod:`.region`), else round-outline votes (:mod:`.votes`), then, when those
   give no clean outline, a colour centre-surround contrast (:mod:`.region`) and discs
   whose colour stands out from a textured surround (:mod:`.discs`), a print's cluster
   (:mod:`.pattern`), a see-through ball on a closed view (:mod:`.closing`), and behind a wide
   lens votes in the stereographic view, where an off-axis sphere is a circle again
   (:mod:`.conformal`); sizes bounded by the intrinsics, the known radius and plausible ranges;
2. per candidate, full-resolution sub-pixel silhouette edges and a robust fit of the sphere's
   silhouette cone in undistorted normalised coordinates (:mod:`.fit`, :mod:`.cone`);
   the sphere centre's perspective projection follows exactly from the cone axis (then the lens
   distortion gives raw pixels), and the known radius gives the range;
3. a verdict: one good candidate -> found; none -> the reason ("no round outline" / "sphere cut by the image
   border" / "outline 40 % hidden or too faint at (u, v)" ...); two good ones -> "two round
   objects: (u, v) and (u, v)" (never a guess).

``method="hough-circle"`` is the paper's baseline (Canny + Hough circle, circle centre) on the
same candidate region, for comparison.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Iterable

import cv2
import numpy as np

from calib_core.camera import CameraModel
from calib_core.detect.image.blur import SMALL_RADIUS_PX, blur_range_floor_m, clean_rms_px
from calib_core.detect.image.fit import (DRAWN_LINE, EDGES_CROSS_KEY, MIN_EDGE_WIDTH_PX, SMOOTH_SIGMA_PX, TIGHT_MIN_SUPPORT,
                                        TIGHT_RMS_FRACTION, CandidateFit, refine_candidate, seen_mask)
from calib_core.detect.image.overlay import drawn_in_image
from calib_core.detect.image.closing import closed_candidates, view_of
from calib_core.detect.image.conformal import candidates_in_view, stereographic_view, view_elongation
from calib_core.detect.image.discs import candidates_by_discs
from calib_core.detect.image.highlight import host_candidates, is_clipped_spot
from calib_core.detect.image.hough import hough_circle
from calib_core.detect.image.mirror import MirrorEvidence, noise_sigma_dn
from calib_core.detect.image.mirror import evidence as mirror_evidence
from calib_core.detect.image.pattern import MIN_GROWTH, enclosing_candidates, in_a_print, is_body, lies_inside
from calib_core.detect.image.apparent_range import cone_range_sigma_m, outline_range_floor_m
from calib_core.detect.image.score import features, probability
from calib_core.detect.image.votes import candidates_by_votes
from calib_core.detect.image.region import (Candidate, candidates_from_background,
                                            candidates_single_frame, choose_scale, downscale,
                                            radius_bounds_px)
from calib_core.detect.types import ImageDetection

METHODS = ("ellipse-exact", "hough-circle")
DEFAULT_RANGE_LIMITS_M = (0.3, 12.0)


def background_model(frames_rgb: Iterable[np.ndarray], how: str = "median") -> np.ndarray:
    """Per-pixel background image from frames without the sphere.

    Args:
        frames_rgb: RGB uint8 frames (H,W,3), e.g. from
            :func:`calib_core.io.images.load_background_frames` (a folder or a video window).
        how: "median" (robust to passing fish, bubbles) or "mean" (the paper's average).

    Returns:
        float32 (H,W,3) background in grey levels (0-255).

    Raises:
        ValueError: no frames, frames of different sizes, or an unknown ``how``.
    """
    if how not in ("median", "mean"):
        raise ValueError(f"background model must be 'median' or 'mean', not {how!r}")
    frames = [np.asarray(f) for f in frames_rgb]
    if not frames:
        raise ValueError("no background frames")
    shape = frames[0].shape
    if any(f.shape != shape for f in frames):
        raise ValueError("background frames differ in size")
    if how == "mean" or len(frames) == 1:
        acc = np.zeros(shape, np.float64)
        for f in frames:
            acc += f
        return (acc / len(frames)).astype(np.float32)
    if len(frames) <= MAX_NETWORK_FRAMES and all(f.dtype == np.uint8 for f in frames):
        return _median_by_sorting(frames)
    out = np.empty(shape, np.float32)
    rows = max(1, int(4e6 // (len(frames) * int(np.prod(shape[1:])))))  # ~4 MB per block
    for r0 in range(0, shape[0], rows):
        block = np.stack([f[r0:r0 + rows] for f in frames])
        out[r0:r0 + rows] = np.median(block, axis=0)
    return out


# up to this many 8-bit frames the median is taken by sorting them pixel by pixel (odd-even
# transposition, n (n - 1) / 2 min/max pairs): the value np.median gives, 8x faster for 3 frames
MAX_NETWORK_FRAMES = 9


def _median_by_sorting(frames: list[np.ndarray]) -> np.ndarray:
    """float32 per-pixel median of a few uint8 frames, equal to ``np.median(frames, axis=0)``:
    the middle value, or the mean of the two middle ones for an even count."""
    s = [np.array(f, copy=True) for f in frames]
    n = len(s)
    for p in range(n):
        for i in range(p % 2, n - 1, 2):
            lo = np.minimum(s[i], s[i + 1])
            np.maximum(s[i], s[i + 1], out=s[i + 1])
            s[i] = lo
    m = n // 2
    if n % 2:
        return s[m].astype(np.float32)
    return ((s[m - 1].astype(np.float64) + s[m]) / 2.0).astype(np.float32)


@dataclass
class PreparedBackground:
    """A background model with its downscaled copies cached (build once per camera with
    :func:`prepare_background`; saves ~3-5 ms per 1080p detection)."""

    image: np.ndarray  # (H,W,3) float32
    _small: dict = field(default_factory=dict, repr=False)

    def small(self, s: int) -> np.ndarray:
        if s not in self._small:
            self._small[s] = downscale(self.image, s)
        return self._small[s]


def prepare_background(background: np.ndarray | PreparedBackground) -> PreparedBackground:
    """Wrap a background image (see :func:`background_model`) for repeated detections."""
    if isinstance(background, PreparedBackground):
        return background
    return PreparedBackground(np.ascontiguousarray(np.asarray(background, np.float32)))


def _not_found(reason: str, method: str, **extras) -> ImageDetection:
    return ImageDetection(found=False, reason=reason, method=method, extras=extras)


NO_OUTLINE = "no round outline"
# a round outline this much visible (or more) but refused as hidden is named in the reason;
# a few per cent of a circle is no outline at all
HIDDEN_NAMED_SUPPORT = 0.3
CUT = "sphere cut by the image border"


def two_objects_reason(centres_uv_px, radii_px=None, notes=None) -> str:
    """'two round objects: (u, v) and (u, v)' (the operator-readable refusal); with ``radii_px``
    each place also says its apparent radius ('(u, v) r 22 px'), with ``notes`` what is wrong
    with it ('(u, v) r 32 px, cut by the image border')."""
    parts = []
    for k, c in enumerate(centres_uv_px):
        s = f"({c[0]:.0f}, {c[1]:.0f})"
        if radii_px is not None:
            s += f" r {radii_px[k]:.0f} px"
        if notes is not None and notes[k]:
            s += f", {notes[k]}"
        parts.append(s)
    return f"two round objects: {' and '.join(parts)}"


def _refusal(fits, cands, method) -> ImageDetection:
    """Why no candidate was accepted, in an operator's words: cut by the border, the best
    round outline's problem (hidden part, not round, inside a larger object), or none."""
    cut = [f for c, f in fits if f.reason == CUT]
    if cut:
        # the partial fit is often still good: keep it for an operator to confirm
        best = max(cut, key=lambda f: f.support)
        return _not_found(CUT, method, candidates=len(cands),
                          partial_center_uv_px=[round(float(v), 2) for v in best.centre_uv_px])
    if any(c.touches_border and c.source == "background" and f.fit is None for c, f in fits):
        return _not_found(CUT, method, candidates=len(cands))
    # a clean round outline, only partly visible, is worth naming; outlines that are not round
    # or sit inside something larger are clutter (listed in the extras, not in the reason)
    near = [f for _, f in fits if f.fit is not None and f.reason.startswith("outline ") and "hidden" in f.reason
            and f.support >= HIDDEN_NAMED_SUPPORT]
    if near:
        best = max(near, key=lambda f: f.support)
        u, v = best.centre_uv_px
        # the partly hidden outline's centre and range: a candidate for the session's rough rig
        # registration (calib_core.pipeline), never a detection by itself
        return _not_found(f"{best.reason} at ({u:.0f}, {v:.0f})", method, candidates=len(cands),
                          rejected=_rejected(fits), partial_center_uv_px=[round(float(u), 2), round(float(v), 2)],
                          partial_range_m=round(float(best.range_m), 4))
    return _not_found(NO_OUTLINE, method, candidates=len(cands), rejected=_rejected(fits))


def _stronger_refused(fits, best):
    for _, f in fits:
        if (not f.ok and f.credible and f.silhouette_px is not None
                and np.hypot(*(f.centre_uv_px - best.centre_uv_px)) > _mean_radius(best.silhouette_px)
                and _evidence(f) >= 0.5 * _evidence(best)):
            return f
    return None


# outlines whose evidence (_evidence) is within this ratio of each other are comparable (as for
# two round objects and a stronger refused outline)
COMPARABLE_EVIDENCE = 0.5


def _crossing_blocker(fits, best):
    """A round outline refused because the edges at it cross it (fit._edges_along) that
    outweighs the best accepted one: comparable to (COMPARABLE_EVIDENCE of) an accepted outline
    that is not clean and whole, or more than 1 / COMPARABLE_EVIDENCE times a clean whole one.
    Where circles are strung from a lattice or a net, a weaker outline is no better founded
    than they are: neither is taken (the reason names the strung one)."""
    ev = _evidence(best)
    need = COMPARABLE_EVIDENCE * ev if not _clean_whole(best) else ev / COMPARABLE_EVIDENCE
    for _, f in fits:
        if (f.extras.get(EDGES_CROSS_KEY) and f.silhouette_px is not None
                and np.hypot(*(f.centre_uv_px - best.centre_uv_px)) > _mean_radius(best.silhouette_px)
                and _evidence(f) > need):
            return f
    return None


def _clean_whole(f) -> bool:
    """An accepted outline that is credible (mostly seen, round, the surroundings just outside it
    unlike the sphere) and clean (fit score at least WEAK_FIT): a round object, not clutter."""
    return f.ok and f.credible and f.score >= WEAK_FIT


def _two_objects(objs, method: str, n_cands: int, fits) -> ImageDetection:
    """'two round objects: ...' with each object's centre, apparent radius and, for a refused one
    (cut by the border, partly hidden), why; ``two_candidates`` rows (u, v, range_m), strongest
    evidence first (at most 3), for a caller with another clue (the sonar's prediction, a click)."""
    objs = sorted(objs, key=lambda f: -_evidence(f))[:3]
    radii = [_mean_radius(f.silhouette_px) for f in objs]
    notes = ["" if f.ok else f.reason.removeprefix("sphere ") for f in objs]
    return _not_found(two_objects_reason([f.centre_uv_px for f in objs], radii, notes), method,
                      candidates=n_cands, rejected=_rejected(fits),
                      two_candidates=[[round(float(f.centre_uv_px[0]), 2), round(float(f.centre_uv_px[1]), 2),
                                       round(float(f.range_m), 4)] for f in objs],
                      two_candidates_radius_px=[round(float(r), 2) for r in radii],
                      two_candidates_notes=notes)


def _rejected(fits) -> list[str]:
    """The candidates looked at and why each was refused ("<reason> at (u, v)")."""
    out = []
    for _, f in fits:
        if f.reason and f.centre_uv_px is not None and " at (" not in f.reason:
            out.append(f"{f.reason} at ({f.centre_uv_px[0]:.0f}, {f.centre_uv_px[1]:.0f})")
        elif f.reason:
            out.append(f.reason)
    return out[:6]


def _evidence(f) -> float:
    """Weight of a fitted round outline: its score times the outline length it explains (px).
    Clutter makes small round outlines far more often than large ones, so a small round
    thing (a knob, a lamp) does not make a clear, large sphere outline ambiguous. An outline
    barely above the image noise (a few grey levels) counts less than a crisp one: at
    FAINT_CONTRAST grey levels half."""
    c = max(float(f.contrast), 0.0)
    return f.score * f.support * _perimeter(f.silhouette_px) * c / (c + FAINT_CONTRAST)


def _perimeter(sil: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(np.vstack([sil, sil[:1]]), axis=0), axis=1).sum())


def _ellipse_px(sil: np.ndarray) -> tuple:
    """((cx, cy), (major, minor) full axis lengths, angle_deg) of an outline (OpenCV style)."""
    (cx, cy), (a, b), ang = cv2.fitEllipse(sil.astype(np.float32))
    return ((float(cx), float(cy)), (float(max(a, b)), float(min(a, b))),
            float(ang if a >= b else (ang + 90.0) % 180.0))


def _mean_radius(sil: np.ndarray) -> float:
    return float(np.mean(np.linalg.norm(sil - sil.mean(axis=0), axis=1)))


def _inside(uv: np.ndarray, outline: np.ndarray) -> bool:
    return cv2.pointPolygonTest(outline.astype(np.float32), (float(uv[0]), float(uv[1])), False) > 0


def _refine_all(look, todo, hinted: bool):
    """Refine candidates in order; skip those that cannot change the verdict."""
    fits: list[tuple[Candidate, CandidateFit]] = []
    for c in todo:
        ok = [cf for cf in fits if cf[1].ok]
        same = [cf[0].strength for cf in ok if cf[0].source == c.source]  # comparable strengths
        if ok and (hinted or (same and c.strength < 0.12 * max(same))):
            break  # found, and what is left is far too weak to be a sphere (an open mesh
            # target has much less contrast than a solid decoy: keep checking those)
        if ok and (_evidence_bound(c) < 0.5 * max(_evidence(f) for _, f in ok)
                   or _same_outline(c, ok) or _dominated(c, ok)):
            continue
        fits.append((c, look.refine(c)))
    return fits


@dataclass(frozen=True)
class _Copy:
    copy: CandidateFit  # the farther outline: the mirror image
    ball: CandidateFit  # the nearer one it copies
    evidence: MirrorEvidence


def _mirror_input(f: CandidateFit, sphere_radius_m: float, cam: CameraModel) -> dict:
    """An accepted outline as :func:`.mirror.compare` reads it (the 3D centre: the ray through the
    projected centre at the cone's range, m)."""
    return {"centre_px": f.centre_uv_px, "radius_px": _mean_radius(f.silhouette_px), "range_m": float(f.range_m),
            "range_sigma_m": _range_sigma_m(f, sphere_radius_m), "sphere_radius_m": sphere_radius_m,
            "centre_cam_m": cam.rays(np.asarray(f.centre_uv_px, float)[None, :])[0] * float(f.range_m)}


def _without_mirror_copies(look, good):
    """The accepted outlines without those that are a mirror copy of a nearer one
    (:mod:`.mirror`), and the copies found. Only outlines that would make the image ambiguous
    (evidence at least half the best's) are compared."""
    top = [f for _, f in good[:3] if f.fit is not None and _evidence(f) >= 0.5 * _evidence(good[0][1])]
    if len(top) < 2:
        return good, []
    copies: list[_Copy] = []
    for far in sorted(top, key=lambda f: -f.range_m):
        for near in sorted(top, key=lambda f: f.range_m):
            k = None if any(near is k.copy for k in copies) else _mirror_copy_of(look, far, near)
            if k is not None:
                copies.append(k)
                break
    return [(c, f) for c, f in good if not any(f is k.copy for k in copies)], copies


def _set_aside_copies(look, good, fits):
    """(accepted outlines, all fits, copies) without the outlines that are a mirror copy of a
    nearer accepted one, nor a copy cut by the border that would block the ball
    (:func:`_stronger_refused`); the copies' other fits go too (they are no rivals)."""
    good, copies = _without_mirror_copies(look, good)
    fits = [(c, f) for c, f in fits if not any(_same_object(f, k.copy) for k in copies)]
    blocker = _stronger_refused(fits, good[0][1])
    cut_copy = None if blocker is None else _mirror_copy_of(look, blocker, good[0][1])
    if cut_copy is not None:
        copies.append(cut_copy)
        fits = [(c, f) for c, f in fits if not _same_object(f, blocker)]
    return good, fits, copies


def _same_object(f: CandidateFit, g: CandidateFit) -> bool:
    """``f`` is ``g`` or another fit of the same outline (centre within half its radius)."""
    if f is g:
        return True
    if f.centre_uv_px is None or g.silhouette_px is None:
        return False
    return bool(np.hypot(*(f.centre_uv_px - g.centre_uv_px)) < 0.5 * _mean_radius(g.silhouette_px))


def _mirror_copy_of(look, far: CandidateFit, near: CandidateFit) -> _Copy | None:
    """``far`` as the mirror copy of ``near`` (:mod:`.mirror`), or None."""
    if far.fit is None or near.fit is None or far.range_m is None or near.range_m >= far.range_m:
        return None
    if look.noise_dn is None:
        look.noise_dn = noise_sigma_dn(look.img)
    ev = mirror_evidence(look.img, _mirror_input(near, look.radius_m, look.cam),
                         _mirror_input(far, look.radius_m, look.cam), look.noise_dn, look.cam)
    return _Copy(far, near, ev) if ev.is_pair() else None


def _name_copies(det: ImageDetection, copies) -> None:
    """The detection's record names the mirror copies it set aside ("mirror copy at (u, v)")."""
    found = [k for k in copies if k.ball.centre_uv_px is not None
             and np.allclose(k.ball.centre_uv_px, det.center_uv_px)]
    if not found:
        return
    k = found[0]
    u, v = k.copy.centre_uv_px
    det.extras["mirror_copy"] = f"mirror copy at ({u:.0f}, {v:.0f})"
    det.extras["mirror_copy_uv_px"] = [round(float(u), 2), round(float(v), 2)]
    ev = k.evidence
    det.extras["mirror_evidence"] = {"flip_corr": round(ev.flip_corr, 3), "direct_corr": round(ev.direct_corr, 3),
                                     "colour_cos": round(ev.colour_cos, 4),
                                     "brightness_ratio": round(ev.brightness_ratio, 3),
                                     "range_sigmas": round(ev.range_sigmas, 1)}


# a clean, confident outline whose round-outline vote is this many times another candidate's
# is not made ambiguous by it (see _dominated)
DOMINANT_VOTE_RATIO = 2.0
DOMINANT_SCORE = 0.9


def _same_outline(c: Candidate, ok) -> bool:
    """A candidate centred on an accepted credible outline and no larger than it: refining it
    finds that outline again or texture inside it (either is dropped by :func:`_good_fits`)."""
    for _, f in ok:
        if not f.credible:
            continue
        r_f = _mean_radius(f.silhouette_px)
        if np.hypot(*(c.centre_px - f.centre_uv_px)) < 0.5 * r_f and c.radius_px <= 1.3 * r_f:
            return True
    return False


def _dominated(c: Candidate, ok) -> bool:
    """A vote candidate whose vote is under 1/DOMINANT_VOTE_RATIO of the vote of a candidate
    that gave a clean (score >= DOMINANT_SCORE), credible, mostly visible outline: outlines
    that vote this much less are clutter or a part of the scene, not a second sphere."""
    if c.source != "votes":
        return False
    return any(o.source == "votes" and f.credible and f.score >= DOMINANT_SCORE
               and c.strength * DOMINANT_VOTE_RATIO < o.strength for o, f in ok)


def _evidence_bound(c: Candidate) -> float:
    """Most evidence (:func:`_evidence`) a candidate's outline could give: its full perimeter,
    or for a vote candidate 1.5x the outline share that voted (votes undercount, never by half)."""
    share = min(1.0, 1.5 * c.strength / 100.0) if c.source == "votes" else 1.0
    return share * 2 * np.pi * 1.3 * c.radius_px


def _merge_candidates(first: list[Candidate], then: list[Candidate]) -> list[Candidate]:
    """Round-outline votes first (they place centre and size well), then the region-contrast
    candidates that are not the same object."""
    out = list(first)
    for c in then:
        if not any(np.hypot(*(c.centre_px - o.centre_px)) < 0.5 * max(c.radius_px, o.radius_px)
                   and 0.6 < c.radius_px / o.radius_px < 1.7 for o in out):
            out.append(c)
    return out


def _hint_candidates(cands, hint_uv, hint_r, r_bounds):
    hint = np.asarray(hint_uv, float)
    near = [c for c in cands if np.hypot(*(c.centre_px - hint)) < 1.25 * c.radius_px + 20]
    near.sort(key=lambda c: np.hypot(*(c.centre_px - hint)))
    r = hint_r if hint_r is not None else np.sqrt(r_bounds[0] * r_bounds[1])
    return near + [Candidate(hint, float(r), (float(r), float(r)), 0.0, False, 0.0, "hint")]


# a fit score (outline share x roundness) below which an accepted outline is ragged or mostly
# hidden: clutter makes those (chair legs, tiles); the second cue then looks as well
WEAK_FIT = 0.5
DISC_CANDIDATES = 6  # colour-distance disc candidates refined when the other cues found nothing
CLOSED_CANDIDATES = 3  # per view (closed, opened) in the see-through cue
CLOSED_MIN_FIT = 0.7  # the fit score (outline share x roundness) a see-through cue's outline needs
VOTE_CANDIDATES = 8  # round-outline vote peaks refined (clutter outranks a faint large outline often)
# where a lens stretches a small sphere's image by less than this (aspect ratio), the raw
# image's votes still meet at its outline: the stereographic view's cue looks only elsewhere
STEREO_MIN_ELONGATION = 1.15
FAINT_CONTRAST = 10.0  # grey levels: a background-difference outline this faint gets a second look


def detect_sphere_in_image(image_rgb: np.ndarray, cam: CameraModel, sphere_radius_m: float,
                           background: np.ndarray | None = None, method: str = "ellipse-exact",
                           hint_uv_px=None, hint_radius_px: float | None = None,
                           range_limits_m: tuple[float, float] = DEFAULT_RANGE_LIMITS_M,
                           max_candidates: int | None = None, seed: int = 0) -> ImageDetection:
    """Find the sphere in one raw camera image.

    Args:
        image_rgb: (H,W,3) RGB uint8 raw (distorted) image, the size ``cam`` describes.
        cam: intrinsics of the camera.
        sphere_radius_m: known sphere radius (m).
        background: (H,W,3) background model (:func:`background_model`), or the same wrapped by
            :func:`prepare_background` (faster when reused), or None (single-frame detection).
        method: "ellipse-exact" (default; exact projection of the centre from the silhouette
            cone) or "hough-circle" (the paper's Canny + Hough circle centre).
        hint_uv_px: optional (u, v) raw pixel an operator clicked near the sphere: candidates
            near it are preferred and, if none is found, the fit starts from the hint.
        hint_radius_px: optional apparent radius (px) for the hint.
        range_limits_m: plausible camera-to-sphere distances (m); bound the apparent size.
        max_candidates: most candidates refined at full resolution (default 6 with a
            background, 10 without).
        seed: seed of the RANSAC sampling (results are deterministic for a seed).

    Returns:
        :class:`ImageDetection`; ``found`` False with ``reason`` when nothing trustworthy.
        With a background, a miss or a faint outline (turbid water: the sphere differs little
        from the background model) gets a second, single-frame look; the stronger is kept.
    """
    kw = dict(method=method, hint_uv_px=hint_uv_px, hint_radius_px=hint_radius_px,
              range_limits_m=range_limits_m, max_candidates=max_candidates, seed=seed)
    det = _detect_once(image_rgb, cam, sphere_radius_m, background, **kw)
    if background is None or (det.found and det.extras.get("edge_contrast", 0) >= FAINT_CONTRAST):
        return det
    guessed_cut = det.reason == CUT and "partial_center_uv_px" not in det.extras  # a blob at the border
    if not det.found and not (det.reason == NO_OUTLINE or "hidden" in det.reason or guessed_cut):
        return det  # a fitted cut outline, two round objects, bad input: say so
    alone = _detect_once(image_rgb, cam, sphere_radius_m, None, **kw)
    if alone.found and (not det.found or alone.score * alone.radius_px > det.score * det.radius_px):
        alone.extras["background_used"] = False
        return alone
    return det


def _detect_once(image_rgb: np.ndarray, cam: CameraModel, sphere_radius_m: float,
                 background=None, method: str = "ellipse-exact", hint_uv_px=None,
                 hint_radius_px: float | None = None,
                 range_limits_m: tuple[float, float] = DEFAULT_RANGE_LIMITS_M,
                 max_candidates: int | None = None, seed: int = 0) -> ImageDetection:
    """One detection pass (arguments as :func:`detect_sphere_in_image`)."""
    t0 = time.perf_counter()
    if method not in METHODS:
        raise ValueError(f"unknown image detection method {method!r}; use one of {METHODS}")
    img = np.asarray(image_rgb)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    H, W = img.shape[:2]
    if (W, H) != (cam.width_px, cam.height_px):
        return _not_found(f"image is {W}x{H} but the intrinsics are {cam.width_px}x{cam.height_px}",
                          method)
    if background is not None:
        background = prepare_background(background)
        if background.image.shape[:2] != (H, W):
            return _not_found("background differs in size from the image", method)
    look = _Look(img, cam, sphere_radius_m, background, range_limits_m, hint_radius_px,
                 max_candidates, np.random.default_rng(seed))
    cands = look.first_candidates(hint_uv_px)
    t_region = time.perf_counter()
    if not cands and (hint_uv_px is not None or background is not None):
        return _not_found(NO_OUTLINE, method, candidates=0)  # (without them, the later cues still look)
    fits = _refine_all(look, _in_order(cands, look.max_candidates), hint_uv_px is not None)
    if hint_uv_px is None and background is None:
        cands, fits = _more_cues(look, cands, fits)
    det = _verdict(look, fits, cands, method, hint_uv_px is not None)
    if det.found and is_clipped_spot(img, det.center_uv_px, det.radius_px):
        det = _host_of_highlight(look, det, method)
    if det.found:
        det.extras["time_ms"] = round(1e3 * (time.perf_counter() - t0), 2)
        det.extras["region_ms"] = round(1e3 * (t_region - t0), 2)
        det.extras["refined"] = len(fits)  # candidates fitted at full resolution
    return det


def _clear(fits) -> bool:
    return any(f.ok and f.score >= WEAK_FIT for _, f in fits)


def _more_cues(look, cands, fits):
    """The cues after the round-outline votes, each only while no clear outline is found (or
    the clear one may be an element of a ball's print: then the print's cue looks as well)."""
    if _clear(fits):
        return _print_cue(look, cands, fits) if _clear_in_print(look, cands, fits) else (cands, fits)
    # no clear round outline among the votes (none, or only ragged ones: clutter): region
    # contrast (an open mesh, a low-contrast outline) as the second cue
    more = _new_candidates(fits, look.contrast_candidates())
    cands = cands + more
    fits = fits + _refine_all(look, _in_order(more, look.max_candidates), False)
    if _clear(fits):
        return _print_cue(look, cands, fits) if _clear_in_print(look, cands, fits) else (cands, fits)
    # third cue: a disc whose colour stands out from a textured surround (a red ball
    # before red brick), where neither outline votes nor plain contrast put a candidate
    more = _new_candidates(fits, look.disc_candidates())
    cands = cands + more
    fits = fits + _refine_all(look, more[:DISC_CANDIDATES], False)  # best first, border or not
    if _clear(fits) and not _clear_in_print(look, cands, fits):
        return cands, fits
    cands, fits = _print_cue(look, cands, fits)
    if not _clear(fits):
        cands, fits = _closed_cue(look, cands, fits)
    return (cands, fits) if _clear(fits) else _stereo_cue(look, cands, fits)


def _stereo_cue(look, cands, fits):
    """Sixth cue, when nothing else gave a clear outline, behind a wide lens only: round-outline
    votes in the stereographic view (:mod:`.conformal`), where an off-axis sphere that the lens
    stretched into an ellipse too long for circle votes is a circle again. Only its clear
    outlines count; otherwise the shared random stream is left as it was (as :func:`_print_cue`)."""
    if view_elongation(look.cam) < STEREO_MIN_ELONGATION:
        return cands, fits
    view = stereographic_view(look.cam, look.s)
    if view is None:
        return cands, fits
    # (only where the lens stretches a sphere that much: elsewhere the raw votes saw the same)
    more = _new_candidates(fits, candidates_in_view(look.small, look.cam, view, look.r_bounds, VOTE_CANDIDATES,
                                                    STEREO_MIN_ELONGATION))
    state = look.rng.bit_generator.state
    sixth = _refine_all(look, _in_order(more, look.max_candidates), False)
    if _clear(sixth):
        return cands + more, fits + sixth
    look.rng.bit_generator.state = state
    return cands, fits


def _closed_cue(look, cands, fits):
    """Fifth cue, when nothing else gave a clear outline: a see-through ball (lattice, cage,
    net, wiffle) looked for on the image closed at its mesh cell's scale (:mod:`.closing`).
    Only its clear outlines count (:func:`_closed_clear`; its other fits are guesses on a
    transformed image and are dropped: kept, an accepted blob the gate refuses could make the
    clear one "two round objects"); each candidate draws from its own random stream (the
    shared one is left as it was: what draws after it draws as without the cue)."""
    # (not where the image itself gave an accepted, if weak, outline: closing makes any dark or
    # bright blob rounder, and there it would only outbid the raw outline; a half-buried boulder
    # at 0.73 went to 1.00)
    accepted = [f for _, f in fits if f.ok]
    more = [c for c in look.closed_candidates() if not c.touches_border and not _near_accepted(c, accepted)]
    clear = [(c, f) for c, f in ((c, look.refine_closed(c)) for c in more) if _closed_clear(f)]
    return (cands + more, fits + clear) if clear else (cands, fits)


def _closed_clear(f: CandidateFit) -> bool:
    """A see-through cue's outline that counts: a guess on a transformed image, so clearer than
    the weak fit that would do on the raw image (CLOSED_MIN_FIT; a blob of a dim wall, closed,
    made one at 0.50), no smaller than the smallest sphere the detector is meant for
    (SMALL_RADIUS_PX: a mesh needs a few cells to be seen as one) and on edges that are steps
    (MIN_EDGE_WIDTH_PX, as fit._outline_held: a 13 px blob of a chair scene, closed, had 2.0 px)."""
    return (f.ok and f.score >= CLOSED_MIN_FIT and _mean_radius(f.silhouette_px) >= SMALL_RADIUS_PX
            and f.extras.get("edge_width_px", 0.0) >= MIN_EDGE_WIDTH_PX)


def _near_accepted(c: Candidate, accepted) -> bool:
    """A candidate at an accepted outline, of about its size."""
    return any(np.hypot(*(c.centre_px - f.centre_uv_px)) < 0.5 * _mean_radius(f.silhouette_px)
               and 0.6 < c.radius_px / _mean_radius(f.silhouette_px) < 1.6 for f in accepted)


def _clear_in_print(look, cands, fits) -> bool:
    """Every clear outline found lies in a cluster of candidates much larger than itself
    (:func:`~calib_core.detect.image.pattern.in_a_print`): maybe a pentagon of a football. Not
    when one of them is a clean, confident outline (DOMINANT_SCORE: an open mesh's holes
    cluster around the whole ball's outline; looking again there only costs time)."""
    clear = [f for _, f in fits if f.ok and f.score >= WEAK_FIT]
    return (bool(clear) and all(f.score < DOMINANT_SCORE for f in clear)
            and all(in_a_print(f, cands, look.r_bounds) for f in clear))


def _print_cue(look, cands, fits):
    """Fourth cue: a ball's print (pentagons, panels) made the small candidates: a cluster of them.
    A guess built from other candidates: it counts only when it gives a clear outline
    (discarded, it leaves the shared random stream as it found it: what draws after it, the
    host search around a clipped highlight, draws as without the cue)."""
    # (an outline much smaller than a cluster's circle does not stand for it: it may be one
    # of the print's elements)
    enc = enclosing_candidates(cands, look.r_bounds)
    smaller = [(c, f) for c, f in fits if not (f.credible and enc and all(
        MIN_GROWTH * _mean_radius(f.silhouette_px) <= e.radius_px for e in enc))]
    more = _new_candidates(smaller, enc)
    state = look.rng.bit_generator.state
    fourth = _refine_all(look, more, False)
    if _clear(fourth):
        return cands + more, fits + fourth
    look.rng.bit_generator.state = state
    return cands, fits


class _Look:
    """What one detection pass knows: the image, its downscaled copy, the size bounds."""

    def __init__(self, img, cam, sphere_radius_m, background, range_limits_m, hint_radius_px,
                 max_candidates, rng):
        self.img, self.cam, self.radius_m, self.rng = img, cam, sphere_radius_m, rng
        self.d_min, self.d_max = range_limits_m
        r_bounds = radius_bounds_px(cam, sphere_radius_m, range_limits_m)
        if hint_radius_px is not None:
            r_bounds = (0.6 * hint_radius_px, 1.6 * hint_radius_px)
        self.r_bounds, self.hint_radius_px = r_bounds, hint_radius_px
        self.a_range = (np.arcsin(min(sphere_radius_m / (1.25 * self.d_max), 0.999)),
                        np.arcsin(min(sphere_radius_m / max(0.8 * self.d_min, sphere_radius_m * 1.001), 0.999)))
        self.s = choose_scale(r_bounds[0], img.shape[1])
        self.small = downscale(img, self.s)
        self.background = background
        self.bg = background.image if background is not None else None
        self.max_candidates = max_candidates or (6 if background is not None else 10)
        self.noise_dn = None  # the image noise (grey levels), measured when a mirror pair is compared

    def first_candidates(self, hint_uv_px) -> list[Candidate]:
        """Background-difference blobs, else round-outline votes, else region contrast."""
        if self.background is not None:
            cands, _ = candidates_from_background(self.small, self.background.small(self.s), self.s, self.r_bounds)
        else:
            cands = candidates_by_votes(self.small, self.s, self.r_bounds, max_candidates=VOTE_CANDIDATES)
            if not cands:
                cands = self.contrast_candidates()
        if hint_uv_px is not None:
            cands = _hint_candidates(cands, hint_uv_px, self.hint_radius_px, self.r_bounds)
        return cands

    def contrast_candidates(self) -> list[Candidate]:
        return candidates_single_frame(self.small, self.s, self.r_bounds, max_candidates=12)

    def disc_candidates(self) -> list[Candidate]:
        return candidates_by_discs(self.small, self.s, self.r_bounds, max_candidates=DISC_CANDIDATES)

    def refine(self, c: Candidate) -> CandidateFit:
        return refine_candidate(self.img, self.cam, c, self.radius_m, self.a_range, self.bg, self.rng)

    def closed_candidates(self) -> list[Candidate]:
        return closed_candidates(self.small, self.s, self.r_bounds, CLOSED_CANDIDATES)

    def refine_closed(self, c: Candidate) -> CandidateFit:
        """A see-through cue's candidate refined on its closed view, from its own random stream."""
        f = refine_candidate(view_of(self.img, c), self.cam, c, self.radius_m, self.a_range, None,
                             np.random.default_rng(0))
        # a line drawn over the scene (an overlay's circle) is one in the image itself, whatever the view made of it
        if (f.ok or f.credible) and self.bg is None and drawn_in_image(self.img, f.silhouette_px, SMOOTH_SIGMA_PX, seen_mask(f)):
            f.ok, f.credible, f.reason = False, False, DRAWN_LINE
        return f


def _host_of_highlight(look, det: ImageDetection, method: str) -> ImageDetection:
    """The ball carrying a clipped highlight that was taken for the sphere
    (:mod:`.highlight`); the highlight's own detection when no ball outline is found
    around it (a small white ball overexposed is a clipped disc too)."""
    hosts = host_candidates(det.center_uv_px, det.radius_px, look.img.shape)
    fits = [(c, look.refine(c)) for c in hosts]  # all (the halo's outline must not stop the search)
    inside = [(c, f) for c, f in fits if f.ok and _mean_radius(f.silhouette_px) > 1.5 * det.radius_px
              and _inside(det.center_uv_px, f.silhouette_px)]
    # the highlight's halo (bloom) makes round outlines too: keep the outermost, the ball
    outer = [(c, f) for c, f in inside if not any(
        _mean_radius(g.silhouette_px) > 1.3 * _mean_radius(f.silhouette_px) and _inside(f.centre_uv_px, g.silhouette_px)
        for _, g in inside)]
    if not outer:
        return det
    host = _verdict(look, outer, hosts, method, False)
    if host.found:
        host.extras["highlight_uv_px"] = [round(float(x), 2) for x in det.center_uv_px]
    return host if host.found else det


def _in_order(cands, max_candidates):
    """Candidates touching the border last (a sphere there is cut anyway), at most 2 of them."""
    return ([c for c in cands if not c.touches_border][:max_candidates]
            + [c for c in cands if c.touches_border][:2])


def _new_candidates(fits, more: list[Candidate]) -> list[Candidate]:
    """Second-cue candidates that are not what was looked at already: not at a credible outline
    fitted, nor where a candidate tried found no edges at all (a vote candidate a little off
    can miss an outline that a region candidate a few px away finds)."""
    out = []
    for c in more:
        if any(f.fit is None and np.hypot(*(c.centre_px - o.centre_px)) < 0.1 * max(c.radius_px, o.radius_px)
               and 0.8 < c.radius_px / o.radius_px < 1.25 for o, f in fits):
            continue
        if any(f.credible and np.hypot(*(c.centre_px - f.centre_uv_px)) < 0.5 * _mean_radius(f.silhouette_px)
               for _, f in fits):
            continue
        out.append(c)
    return out


def _good_fits(fits):
    """Accepted outlines, each object once (its best fit), none inside a larger fitted one."""
    fitted = [(c, f) for c, f in fits if f.credible]
    bodies = _bodies(fits)
    good: list[tuple[Candidate, CandidateFit]] = []
    for c, f in sorted(fits, key=lambda cf: -cf[1].score):
        if not f.ok:
            continue
        r_f = _mean_radius(f.silhouette_px)
        # texture of a larger fitted object (e.g. the mesh of a sphere cut by the border)
        if any(_mean_radius(g.silhouette_px) > 2 * r_f and _inside(f.centre_uv_px, g.silhouette_px)
               for _, g in fitted):
            continue
        # a print's element (a pentagon, a panel) wholly inside a ball's outline, even one
        # refused as not round: the limb is the outermost closed contour of the body
        if any(g is not f and lies_inside(f, g) for g in bodies):
            continue
        # the same object found from two candidates: keep the better fit
        if not any(np.hypot(*(f.centre_uv_px - g.centre_uv_px)) < 0.8 * max(r_f, _mean_radius(g.silhouette_px))
                   for _, g in good):
            good.append((c, f))
    good.sort(key=lambda cf: -_evidence(cf[1]))
    return good


def _bodies(fits) -> list[CandidateFit]:
    """Fitted outlines a print could lie on (:func:`~calib_core.detect.image.pattern.is_body`:
    most of the outline seen, the surroundings just outside it as :func:`~.fit._judge` asks of a
    credible outline (BODY_OUTSIDE_MISMATCH, with or without a background: a circle run through
    clutter around a ball has clutter's edges on it, and the clutter goes on beyond them), at
    most 1 / TIGHT_RMS_FRACTION times as rough as an accepted outline may be: the tight refit's
    standard is half the limit, a body's twice it)."""
    return [f for _, f in fits if is_body(f, BODY_OUTSIDE_MISMATCH, TIGHT_MIN_SUPPORT, 1.0 / TIGHT_RMS_FRACTION)]


BODY_OUTSIDE_MISMATCH = 0.2  # the credible outline's limit (fit._judge)


def _verdict(look, fits, cands, method, hinted: bool) -> ImageDetection:
    """Found (one clear outline), or why not (none, cut, hidden, two round objects)."""
    good = _good_fits(fits)
    if not good:
        return _refusal(fits, cands, method)
    # a mirror copy (glass wall, water surface) is no second object: the ball is the nearer
    good, fits, copies = (good, fits, []) if hinted else _set_aside_copies(look, good, fits)
    # a clean round outline refused only for being cut by the border (or partly hidden) that
    # outweighs the best accepted one: the accepted one is likely clutter, the sphere is there
    blocker = _stronger_refused(fits, good[0][1])
    if blocker is not None and not hinted:
        if _clean_whole(good[0][1]):
            # a clean, credible whole outline beside a stronger cut (or partly hidden) one: two
            # round objects, both kept, so that the session's sonar prediction can choose
            # (a cut boulder on the seabed must not hide a whole ball, nor be taken for it)
            return _two_objects([f for _, f in good if _evidence(f) >= 0.5 * _evidence(good[0][1])] + [blocker],
                                method, len(cands), fits)
        u, v = blocker.centre_uv_px  # the accepted outline is ragged: likely clutter beside a cut sphere
        return _not_found(blocker.reason, method, candidates=len(cands),
                          partial_center_uv_px=[round(float(u), 2), round(float(v), 2)],
                          rejected=_rejected(fits))
    crossing = _crossing_blocker(fits, good[0][1])
    if crossing is not None and not hinted:
        return _not_found(crossing.reason, method, candidates=len(cands), rejected=_rejected(fits))
    if len(good) > 1 and not hinted and _evidence(good[1][1]) >= 0.5 * _evidence(good[0][1]):
        # both kept (u, v, range_m): a caller with another clue (the sonar's range, a click)
        # can choose; the detector does not guess
        return _two_objects([f for _, f in good[:3]], method, len(cands), fits)
    f = good[0][1]
    rival = _disputed_by(fits, f)
    if rival is not None and not hinted:
        d = float(np.hypot(*(rival.centre_uv_px - f.centre_uv_px)))
        u, v = f.centre_uv_px
        return _not_found(f"{DISPUTED} by {d:.1f} px at ({u:.0f}, {v:.0f})", method,
                          candidates=len(cands), rejected=_rejected(fits))
    if not (0.8 * look.d_min <= f.range_m <= 1.25 * look.d_max):
        return _not_found("apparent size outside the plausible range", method)
    runner_up = _evidence(good[1][1]) / max(_evidence(f), 1e-9) if len(good) > 1 else 0.0
    det = _detection(f, look.radius_m, method, len(cands), runner_up)
    det.extras["rival_share"] = round(_rival_share(fits, f), 4)
    if copies:
        _name_copies(det, copies)
    if method == "hough-circle":
        h = hough_circle(look.img, f.centre_uv_px, det.radius_px)
        if h is None:
            return _not_found("no Hough circle", method)
        det.center_uv_px, det.radius_px, det.cov_uv_px2 = h[0], h[1], h[2]
        det.ellipse_px = ((float(h[0][0]), float(h[0][1])), (2 * h[1], 2 * h[1]), 0.0)
    return det


# a round object elsewhere in the image counts as a rival of the accepted one when it is credible
# and clean (accepted, or refused only as cut by the border or partly hidden), of a similar size
# (radius within RIVAL_SIZE_RATIO) and its evidence at least RIVAL_MIN_EVIDENCE of the accepted one's
RIVAL_SIZE_RATIO = 2.0
RIVAL_MIN_EVIDENCE = 0.2


def _rival_share(fits, f) -> float:
    """Share of the round-object evidence in the image that is not the accepted outline ``f``:
    sum of the rivals' evidence over (that + ``f``'s); 0 without rivals. One image with several
    round objects of the sphere's size and contrast cannot say which one is the sphere."""
    r_f, ev_f = _mean_radius(f.silhouette_px), _evidence(f)
    rivals: list = []
    for _, g in sorted(fits, key=lambda cf: -_evidence(cf[1]) if cf[1].silhouette_px is not None else 0.0):
        if g is f or g.silhouette_px is None or not g.credible or g.score < WEAK_FIT:
            continue
        if not (g.ok or g.reason == CUT or "hidden" in g.reason):
            continue
        r_g = _mean_radius(g.silhouette_px)
        if not 1 / RIVAL_SIZE_RATIO <= r_g / r_f <= RIVAL_SIZE_RATIO or _evidence(g) < RIVAL_MIN_EVIDENCE * ev_f:
            continue
        if any(np.hypot(*(g.centre_uv_px - h.centre_uv_px)) < max(r_f, r_g) for h in [f, *rivals]):
            continue  # the same object again
        rivals.append(g)
    ev = sum(_evidence(g) for g in rivals)
    return float(ev / (ev + ev_f)) if ev > 0 else 0.0


DISPUTED = "two fits of one outline disagree"
# centres of two fits of one outline this many of the accepted fit's sigmas apart (and at least
# DISPUTE_MIN_PX) cannot both be right
DISPUTE_SIGMAS = 3.0
DISPUTE_MIN_PX = 1.5


def _disputed_by(fits, f: CandidateFit) -> CandidateFit | None:
    """A refused fit of the same outline (centre within a quarter radius, size within 15 %)
    that explains more of it (higher support and score) than the accepted, not credible fit
    ``f``, with a centre too far from ``f``'s for both to be right: the outline has two
    readings (a backrest's or a seat's edge taken for the ball's on part of it) and the
    accepted one is the weaker. A credible ``f`` (clean, mostly visible, the outside unlike
    the sphere) is not questioned."""
    if f.credible:
        return None
    r_f = _mean_radius(f.silhouette_px)
    tol = max(DISPUTE_MIN_PX, DISPUTE_SIGMAS * float(np.sqrt(max(np.linalg.eigvalsh(f.cov_uv_px2)[-1], 0.0))))
    for _, g in fits:
        if g.ok or g.fit is None or g.silhouette_px is None or g is f:
            continue
        d = float(np.hypot(*(g.centre_uv_px - f.centre_uv_px)))
        if (tol < d < 0.25 * r_f and abs(_mean_radius(g.silhouette_px) - r_f) < 0.15 * r_f
                and g.support > f.support and g.score > f.score):
            return g
    return None


def _blur_range_floor_m(f: CandidateFit, apparent_r_px: float, sphere_radius_m: float) -> float:
    """The range's share of a blurred outline's systematic floor (m), for a mostly seen outline
    (:func:`calib_core.detect.image.blur.blur_range_floor_m`); 0 for a sharp edge."""
    width = f.extras.get("edge_width_px", np.nan) if f.support >= TIGHT_MIN_SUPPORT else np.nan
    return blur_range_floor_m(sphere_radius_m / np.sin(f.fit.a_rad), apparent_r_px, width)


def _range_sigma_m(f: CandidateFit, sphere_radius_m: float) -> float:
    """Uncertainty (m) of an accepted outline's cone range: the fit's, the blur's floor and the
    outline's roughness floor, combined."""
    apparent_r = _mean_radius(f.silhouette_px)
    range_m = sphere_radius_m / np.sin(f.fit.a_rad)
    return float(np.linalg.norm([cone_range_sigma_m(sphere_radius_m, f.fit.a_rad, f.fit.cov_params[2, 2]),
                                 _blur_range_floor_m(f, apparent_r, sphere_radius_m),
                                 outline_range_floor_m(range_m, apparent_r, float(f.fit.sigma_px))]))


def _detection(f: CandidateFit, sphere_radius_m: float, method: str, n_cands: int,
               runner_up: float) -> ImageDetection:
    """The found detection of an accepted outline, with its score and extras."""
    extras = dict(f.extras)
    extras["candidates"] = n_cands
    extras["runner_up_ratio"] = round(runner_up, 4)
    apparent_r = _mean_radius(f.silhouette_px)
    extras["range_sigma_m"] = round(_range_sigma_m(f, sphere_radius_m), 5)
    # the cone's half-angle is what the camera measures; range_m = radius / sin(angle), so a
    # wrong diameter in session.yaml shows up as a range that disagrees with the sonar's
    extras["angular_radius_deg"] = round(float(np.degrees(f.fit.a_rad)), 5)
    extras["fit_quality"] = round(f.score, 4)
    score = probability(features(extras, apparent_r, clean_rms_px(apparent_r)), f.score)
    return ImageDetection(found=True, center_uv_px=f.centre_uv_px, cov_uv_px2=f.cov_uv_px2,
                          score=score, ellipse_px=_ellipse_px(f.silhouette_px),
                          radius_px=apparent_r, range_m=f.range_m, method=method, extras=extras)
