"""Printed patterns of sports balls, painted in the ball's own frame (for the "sports" image
kind; :class:`~calib_core.synth.photo.effects.BallLook` ``pattern``).

Each pattern maps unit vectors q (N,3) from the ball's centre, expressed in the ball frame
(pole ``a``, equator axes ``e1``, ``e2``: x = q.e1, y = q.e2, z = q.a), to an albedo. The
seam half width ``w`` is an angle (rad) on the ball.

- "football": a truncated icosahedron (the classic 32-panel ball): 12 black pentagons and 20
  white hexagons, each point coloured by the face its central projection meets (the face f
  maximising ``q . n_f / d_f``, n_f its unit normal, d_f its distance from the centre, from the
  polyhedron's 60 vertices, the even permutations of (0, +-1, +-3 phi), (+-1, +-(2 + phi),
  +-2 phi), (+-phi, +-2, +-phi^3)); a dark stitched seam where the two best faces' values
  differ by less than ``w`` (relative).
- "basketball": orange pebbled leather (the material's texture) with dark seams: the two
  great circles z = 0 and x = 0, and two small circles of angular radius 50 deg around +-e2.
- "tennis": yellow-green felt with the white seam of a tennis ball, the curve
  (a cos t + b cos 3t, a sin t - b sin 3t, 2 sqrt(ab) sin 2t), a + b = 1, b = 0.3 (within ``w``
  of its nearest sampled point); the felt's fuzz is the ``sheen`` term of the shading.
- "volleyball": 18 panels, three on each face of the inscribed cube (the face of the largest
  |coordinate|), as stripes across the face, alternately oriented between opposite-axis
  faces; coloured from ``colours`` (cycled); dark thin seams between panels.
"""

from __future__ import annotations

import numpy as np

PATTERNS = ("football", "basketball", "tennis", "volleyball")
PHI = (1 + 5 ** 0.5) / 2
BLACK = np.array([0.06, 0.06, 0.07])
SEAM = np.array([0.10, 0.09, 0.08])
WHITE = np.array([0.92, 0.92, 0.90])


def _cyclic_signed(base) -> np.ndarray:
    """All cyclic permutations of ``base`` with every sign combination (duplicates removed)."""
    out = []
    for k in range(3):
        b = np.roll(np.asarray(base, float), k)
        for s in np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T:
            out.append(b * s)
    return np.unique(np.round(np.array(out), 12), axis=0)


def truncated_icosahedron():
    """(unit normals (32,3), distances (32,), is_pentagon (32,)) of the faces."""
    verts = np.vstack([_cyclic_signed(b) for b in ((0, 1, 3 * PHI), (1, 2 + PHI, 2 * PHI), (PHI, 2, PHI ** 3))])
    pent = _cyclic_signed((0, 1, PHI))
    hexa = np.vstack([_cyclic_signed((1, 1, 1)), _cyclic_signed((0, PHI, 1 / PHI))])
    normals = np.vstack([pent, hexa])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    d = (verts @ normals.T).max(axis=0)
    return normals, d, np.arange(len(normals)) < len(pent)


def football(q: np.ndarray, w: float) -> np.ndarray:
    normals, d, is_pent = truncated_icosahedron()
    s = (q @ normals.T) / d[None, :]
    order = np.argsort(-s, axis=1)[:, :2]
    best = np.take_along_axis(s, order, axis=1)
    out = np.where(is_pent[order[:, 0]][:, None], BLACK[None, :], WHITE[None, :])
    seam = (best[:, 0] - best[:, 1]) / best[:, 0] < w
    out[seam] = SEAM
    return out


def basketball(q: np.ndarray, w: float, base: np.ndarray) -> np.ndarray:
    x, y, z = q[:, 0], q[:, 1], q[:, 2]
    ang = np.arccos(np.clip(np.abs(y), 0, 1))
    seam = (np.abs(z) < np.sin(w)) | (np.abs(x) < np.sin(w)) | (np.abs(ang - np.deg2rad(50)) < w)
    out = base.copy()
    out[seam] = SEAM
    return out


def _tennis_curve(n: int = 240) -> np.ndarray:
    a, b = 0.7, 0.3
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    c = np.column_stack([a * np.cos(t) + b * np.cos(3 * t), a * np.sin(t) - b * np.sin(3 * t),
                         2 * np.sqrt(a * b) * np.sin(2 * t)])
    return c / np.linalg.norm(c, axis=1, keepdims=True)


def tennis(q: np.ndarray, w: float, base: np.ndarray) -> np.ndarray:
    curve = _tennis_curve(max(240, int(5 * np.pi / w)))  # samples closer than the seam is wide
    near = np.empty(len(q))
    for s in range(0, len(q), 4000):
        near[s:s + 4000] = (q[s:s + 4000] @ curve.T).max(axis=1)
    out = base.copy()
    out[near > np.cos(w)] = WHITE
    return out


def volleyball(q: np.ndarray, w: float, colours) -> np.ndarray:
    face = np.argmax(np.abs(q), axis=1)
    sgn = np.sign(q[np.arange(len(q)), face])
    across = (face + np.where(sgn > 0, 1, 2)) % 3  # the stripes run across this axis
    t = np.arctan2(q[np.arange(len(q)), across], np.abs(q[np.arange(len(q)), face])) / (np.pi / 2)  # -0.5..0.5
    k = np.clip(np.floor((t + 0.5) * 3), 0, 2).astype(int)
    cols = np.asarray(colours, float)
    out = cols[(k + face) % len(cols)]
    border = np.abs((t + 0.5) * 3 - np.round((t + 0.5) * 3)) < 3 * w / (np.pi / 2)
    edge = np.sort(np.abs(q), axis=1)
    border |= (edge[:, 2] - edge[:, 1]) < np.sin(w)
    out[border] = SEAM
    return out


def pattern_albedo(pattern: str, q: np.ndarray, base: np.ndarray, w: float, colours=()) -> np.ndarray:
    """Albedo (N,3) of ball-frame unit vectors q (N,3) for ``pattern`` (see the module doc)."""
    if pattern == "football":
        return football(q, w)
    if pattern == "basketball":
        return basketball(q, w, base)
    if pattern == "tennis":
        return tennis(q, w, base)
    if pattern == "volleyball":
        return volleyball(q, w, colours or (WHITE, (0.10, 0.25, 0.70), (0.95, 0.80, 0.15)))
    raise ValueError(f"unknown ball pattern {pattern!r}; use one of {PATTERNS}")
