"""Candidates for a ball printed with a pattern (the fourth cue of :mod:`.detect`).

A football's black pentagons, a volleyball's panels, a basketball's seams: the print makes
small, high-contrast blobs and outlines inside the ball's silhouette, and the other cues
(outline votes, region contrast, colour discs) put their candidates on those, not on the ball.
The ball then shows as a cluster of small candidates. Candidates of about one size (radii
within ``SIZE_RATIO``) whose discs lie close together (centres within ``LINK`` times the sum
of their radii: single linkage) form a group;
each group of at least ``MIN_MEMBERS`` whose smallest enclosing circle (of the members' discs)
is clearly larger than its members (``MIN_GROWTH`` times the largest) proposes that circle,
widened by ``MARGIN`` (the print stops short of the outline), as a candidate. The full fit
(:mod:`.fit`) then has to find the ball's own outline there; a cluster of texture
blobs yields no round outline and is refused as before.
"""

from __future__ import annotations

import cv2
import numpy as np

from calib_core.detect.image.blur import outline_rms_limit_px
from calib_core.detect.image.region import Candidate

LINK = 1.5
MIN_MEMBERS = 3
MIN_GROWTH = 1.6
MARGIN = 1.1
SIZE_RATIO = 2.0  # only blobs of about one size link (a print's panels; not the ball itself)


def _groups(cands: list[Candidate]) -> list[list[int]]:
    """Single-linkage groups (indices) of candidates whose discs are close."""
    n = len(cands)
    parent = list(range(n))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i
    for i in range(n):
        for j in range(i + 1, n):
            ri, rj = cands[i].radius_px, cands[j].radius_px
            d = np.hypot(*(cands[i].centre_px - cands[j].centre_px))
            if d < LINK * (ri + rj) and max(ri, rj) < SIZE_RATIO * min(ri, rj):
                parent[root(i)] = root(j)
    out: dict[int, list[int]] = {}
    for i in range(n):
        out.setdefault(root(i), []).append(i)
    return [g for g in out.values() if len(g) >= MIN_MEMBERS]


def _enclosing(members: list[Candidate]) -> tuple[np.ndarray, float]:
    ang = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    ring = np.column_stack([np.cos(ang), np.sin(ang)])
    pts = np.vstack([c.centre_px[None, :] + c.radius_px * ring for c in members]).astype(np.float32)
    (u, v), r = cv2.minEnclosingCircle(pts)
    return np.array([u, v], float), float(r)


def enclosing_candidates(cands: list[Candidate], r_bounds_px: tuple[float, float], most: int = 3) -> list[Candidate]:
    """Candidates around clusters of smaller candidates (see the module doc), most members first."""
    small = [c for c in cands if c.source != "hint" and c.radius_px < r_bounds_px[1] / MIN_GROWTH]
    out = []
    for g in sorted(_groups(small), key=len, reverse=True):
        members = [small[i] for i in g]
        centre, r = _enclosing(members)
        r *= MARGIN
        if r < MIN_GROWTH * max(c.radius_px for c in members) or not r_bounds_px[0] <= r <= r_bounds_px[1]:
            continue
        strength = float(np.mean([c.strength for c in members]))
        out.append(Candidate(centre, r, (r, r), 0.0, any(c.touches_border for c in members), strength, "pattern"))
        if len(out) >= most:
            break
    return out


# ---- a print's element accepted as the ball, inside the ball's own outline. The limb is the
# outermost closed contour of one body: a round outline whose whole circle lies inside a larger
# outline of a body (most of it seen, the surroundings just outside it, and at most twice as
# rough as an accepted outline may be) is a pentagon, a panel or a seam's loop, whatever its
# own roundness. "Inside" within the scatter of the larger outline's edges, and larger by more
# than that scatter (a second fit of one outline differs by about it).
BODY_SCATTER_SIGMAS = 2.0   # how far (x the larger outline's edge RMS) the inner one may reach past it
BODY_MIN_EXCESS_SIGMAS = 3.0  # how much larger (x that RMS, and >= BODY_MIN_EXCESS_PX) the body must be
BODY_MIN_EXCESS_PX = 2.0
# ... and an element is smaller than its body by more than a second reading of the same limb can
# differ: an outline within 0.8 of another's size around the same place is that object read again
# (the shadow or halo around a ball, _good_fits' same-object rule), not a pentagon or a panel on it
# (glossy s6: the ball's own outline, r 59.7 px, inside the ball-and-shadow outline, r 62.2 px)
BODY_MIN_RATIO = 1.0 / 0.8


def _radius(sil: np.ndarray) -> float:
    return float(np.mean(np.linalg.norm(sil - sil.mean(axis=0), axis=1)))


def is_body(g, outside_limit: float, min_support: float, rms_limits: float) -> bool:
    """Whether fit ``g`` (:class:`~calib_core.detect.image.fit.CandidateFit`) is the outline
    of a body a print could lie on: fitted wholly inside the image, on at least
    ``min_support`` of its outline, the outside like the surroundings (mismatch at most
    ``outside_limit``), edge RMS within ``rms_limits`` times the roundness limit of its radius
    and edge width (:func:`~calib_core.detect.image.blur.outline_rms_limit_px`; the print
    meeting the limb moves its edge: a black pentagon against a dark background, a white
    hexagon against it)."""
    if g.fit is None or g.silhouette_px is None or not np.isfinite(g.silhouette_px).all():
        return False
    if g.reason.startswith(("sphere cut", "no round outline near the border")):
        return False
    r = _radius(g.silhouette_px)
    width = float(g.extras.get("edge_width_px", np.nan)) if g.support >= min_support else np.nan
    return (g.support >= min_support and float(g.extras.get("outside_mismatch", 1.0)) <= outside_limit
            and g.fit.sigma_px <= rms_limits * outline_rms_limit_px(r, width))


def lies_inside(f, g) -> bool:
    """Whether fit ``f``'s whole outline lies inside fit ``g``'s (up to BODY_SCATTER_SIGMAS of
    ``g``'s edge RMS) and ``g`` is larger by more than its scatter and by BODY_MIN_RATIO."""
    s_g = float(g.fit.sigma_px)
    r_f, r_g = _radius(f.silhouette_px), _radius(g.silhouette_px)
    if r_g < r_f + max(BODY_MIN_EXCESS_PX, BODY_MIN_EXCESS_SIGMAS * s_g) or r_g < BODY_MIN_RATIO * r_f:
        return False
    poly = g.silhouette_px.astype(np.float32)
    worst = min(cv2.pointPolygonTest(poly, (float(u), float(v)), True) for u, v in f.silhouette_px[::3])
    return worst >= -BODY_SCATTER_SIGMAS * s_g


def in_a_print(f, cands: list[Candidate], r_bounds_px: tuple[float, float]) -> bool:
    """Whether accepted fit ``f`` lies in a cluster of candidates (:func:`enclosing_candidates`)
    whose enclosing circle is MIN_GROWTH times larger than it: maybe one element of a print."""
    r_f = _radius(f.silhouette_px)
    return any(np.hypot(*(e.centre_px - f.centre_uv_px)) < e.radius_px and e.radius_px >= MIN_GROWTH * r_f
               for e in enclosing_candidates(cands, r_bounds_px))
