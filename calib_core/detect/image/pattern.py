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
