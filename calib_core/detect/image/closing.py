"""See-through balls (open lattice, cage, net, wiffle): the image closed at the mesh cell's scale.

An open-mesh ball is a thin pattern of struts with the background seen through its cells. Its
outline is only where struts reach the limb (piled up edge-on there, with gaps of up to a cell
between them), and the background's own edges (mortar lines, tiles) run on through the cells:
the outermost edge of a ray often lies beyond the limb, the strongest on an inner strut, and a
sparse lattice votes little for its round outline. A grey-level morphological closing (bright
struts: the maxima spread over a cell, then the minima) or opening (dark struts) with a disc
about a cell wide fills the cells with the struts' colour: the ball becomes a solid disc whose
outline is the struts' outer envelope, i.e. the limb (a closing leaves the outline of a convex
shape where it is; it only fills gaps narrower than the disc), while thin dark (bright) lines
of the background vanish.

The cell's size is not known; it scales with the ball's apparent radius (a lattice of N
meridians has cells 2 pi R / N wide at the equator, fewer and larger for a cage), so the disc
is CELL_FRACTION of the candidate's radius at full resolution, and CANDIDATE_KERNEL_PX on the
downscaled image the candidates are voted on (at that scale a small ball's cells are a few px).

Used only as the last cue of a free search that found no clear outline (see
:func:`calib_core.detect.image.detect`): the closed views are a guess about the object, and
their fits are judged by the same standards as any other.
"""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np

from calib_core.detect.image.region import Candidate
from calib_core.detect.image.votes import candidates_by_votes

CELL_FRACTION = 0.2  # closing disc diameter / apparent radius (a cell of a lattice of ~30 meridians)
MIN_KERNEL_PX, MAX_KERNEL_PX = 3, 61
CANDIDATE_KERNEL_PX = 5  # on the downscaled image
KINDS = ("bright", "dark")  # bright struts: closing; dark struts: opening


def _disc(k: int) -> np.ndarray:
    k = int(k) | 1
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))


def closed(img: np.ndarray, k_px: int, kind: str) -> np.ndarray:
    """The image (H,W,3 uint8) closed (``kind`` "bright") or opened ("dark") per channel with a
    disc ``k_px`` wide."""
    op = cv2.MORPH_CLOSE if kind == "bright" else cv2.MORPH_OPEN
    return cv2.morphologyEx(np.ascontiguousarray(img), op, _disc(k_px))


def kernel_px(radius_px: float) -> int:
    """The closing disc's diameter (full-resolution px) for a ball of this apparent radius."""
    return int(np.clip(round(CELL_FRACTION * radius_px), MIN_KERNEL_PX, MAX_KERNEL_PX)) | 1


def closed_around(img: np.ndarray, cand: Candidate, kind: str) -> np.ndarray:
    """A copy of the image closed (or opened) in the region a refinement of ``cand`` reads
    (its box, see :func:`calib_core.detect.image.fit.refine_candidate`, plus the disc)."""
    H, W = img.shape[:2]
    R = max(cand.axes_px[0], cand.radius_px)
    k = kernel_px(R)
    m = int(np.ceil(2.0 * R + 10 + k))
    x0, y0 = max(0, int(cand.centre_px[0]) - m), max(0, int(cand.centre_px[1]) - m)
    x1, y1 = min(W, int(cand.centre_px[0]) + m + 1), min(H, int(cand.centre_px[1]) + m + 1)
    out = np.array(img, copy=True)
    if x1 - x0 > 2 and y1 - y0 > 2:
        out[y0:y1, x0:x1] = closed(img[y0:y1, x0:x1], k, kind)
    return out


def closed_candidates(small_rgb: np.ndarray, s: int, r_bounds_px: tuple[float, float],
                      per_kind: int) -> list[Candidate]:
    """Round-outline vote candidates (:func:`~calib_core.detect.image.votes.candidates_by_votes`)
    on the downscaled image closed and opened by CANDIDATE_KERNEL_PX, the best ``per_kind`` of
    each; ``source`` "closed-bright" or "closed-dark" says which view to refine them on."""
    out = []
    for kind in KINDS:
        cs = candidates_by_votes(closed(small_rgb, CANDIDATE_KERNEL_PX, kind), s, r_bounds_px,
                                 max_candidates=per_kind)
        out += [replace(c, source=f"closed-{kind}") for c in cs]
    return out


def view_of(img: np.ndarray, cand: Candidate) -> np.ndarray:
    """The image a candidate of :func:`closed_candidates` is refined on."""
    return closed_around(img, cand, cand.source.split("-", 1)[1])
