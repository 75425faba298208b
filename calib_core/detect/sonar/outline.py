"""What touches a sphere's outline in a range cloud (sonar frame, metres; beams from the origin).

A real sphere's outline, seen from the sensor, is a depth step: what lies behind it (a chair's
back, a wall, a person) is further away. What holds it (a seat, a table, a block, a stick, a
hand) continues the outline at or in front of the limb's range, along one arc. These helpers
sort 16 sectors around the outline into "attached" and "free", so that

- the detector can tell a ball resting on something (a short arc) from the cap of a larger
  surface (continued all round: a boulder, a dome), and
- the beam-width estimate can leave the holder's returns out: under a wide cone they pass for
  blooming, and inflate the width (:mod:`calib_core.detect.sonar.beam`).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from calib_core.detect.sonar.fit import robust_sigma
from calib_core.detect.sonar.search import polar_about

N_SECTORS = 16


# returns within this many samples outside the outline do not show an attachment: a stereo
# camera's matching window fattens a foreground edge by a pixel or two
RIM_SAMPLES = 2.0


def attached_sectors(R: np.ndarray, D: np.ndarray, c: np.ndarray, radius: float, alpha: float,
                     h: float, noise_m: float, rim: bool = True) -> np.ndarray:
    """(N_SECTORS,) bool: the sectors around the outline where something continues it.

    ``R``, ``D``: ranges (m) and unit directions of the points near the sphere; ``c`` its centre;
    ``alpha``: the angular radius of the (cone-widened) disc; ``h``: the beam's half-angle;
    ``noise_m``: the sensor's range noise (or NaN); ``rim``: leave out the returns just outside
    the outline (:func:`_rim_rad`). A sector is attached when at least two
    returns just outside the disc lie at or in front of the limb's range, and they are most of
    that sector's returns there (flying pixels between a ball's edge and the background are a
    minority).
    """
    cn = float(np.linalg.norm(c))
    limb = float(np.sqrt(max(cn * cn - radius * radius, 0.0)))
    tol = max(0.3 * radius, 4.0 * noise_m if np.isfinite(noise_m) else 0.0)
    theta, ang = polar_about(D, c / cn)
    rim = _rim_rad(D, h) if rim else 0.0
    sel = (theta > alpha * 1.05 + rim) & (theta <= alpha * 1.05 + rim + max(0.5 * alpha, 2 * h))
    sector = sector_of(ang[sel])
    front = R[sel] < limb + tol
    n_all = np.bincount(sector, minlength=N_SECTORS)
    n_front = np.bincount(sector[front], minlength=N_SECTORS)
    return (n_front >= 2) & (n_front >= 0.5 * n_all)


def _rim_rad(D: np.ndarray, h: float) -> float:
    """Angular width (rad) of the rim just outside the outline that shows no attachment: a
    footprint-less sensor's edge smear (a stereo camera's matching window fattens a foreground
    edge by a sample or two: RIM_SAMPLES samples); none when the beam's footprint is at least a
    sample wide, since the cone-widened disc (``h``) already holds that sensor's smear."""
    spacing = sample_spacing_rad(D)
    return RIM_SAMPLES * spacing if 2.0 * h < spacing else 0.0


def sample_spacing_rad(D: np.ndarray) -> float:
    """The sensor's angular sample spacing (rad) seen in unit directions ``D``: the median angle
    to each return's nearest neighbour (0 with fewer than 3 returns)."""
    if len(D) < 3:
        return 0.0
    d, _ = cKDTree(D).query(D, k=2)
    return float(np.median(d[:, 1]))


def sector_of(azimuth_rad: np.ndarray) -> np.ndarray:
    """Sector index (0 .. N_SECTORS-1) of azimuths in [0, 2 pi) about the sphere's direction."""
    return (np.asarray(azimuth_rad) / (2 * np.pi) * N_SECTORS).astype(int) % N_SECTORS


def attached_span(att: np.ndarray) -> int:
    """Over how many sectors (one contiguous arc, the shortest that holds every attached
    sector) something continues the outline: 0 for a sphere hanging free; a seat, a table or a
    stick make a short arc; a cap of a larger surface, or a pile, a long one."""
    if not att.any():
        return 0
    free = np.r_[~att, ~att]
    gap, run = 0, 0
    for f in free:  # longest circular run of free sectors
        run = run + 1 if f else 0
        gap = max(gap, min(run, len(att)))
    return len(att) - gap


def free_outline_mask(X: np.ndarray, c: np.ndarray, radius: float, h_max: float,
                      noise_m: float = float("nan"), inner: float = 0.5,
                      min_attached: int = 1) -> np.ndarray | None:
    """Points of ``X`` that are not in an attached sector (dilated by one sector each way),
    plus every point of the inner disc (angle from the centre below ``inner`` x the sphere's
    angular radius), for a beam up to ``h_max`` (rad) wide. Every point when fewer than
    ``min_attached`` sectors are attached (a thin chain or stick touches one). None when
    nothing of the outline is free (no blooming can be seen there)."""
    R = np.linalg.norm(X, axis=1)
    D = X / np.maximum(R, 1e-12)[:, None]
    cn = float(np.linalg.norm(c))
    a_sph = float(np.arcsin(min(radius / cn, 1.0)))
    att = attached_sectors(R, D, c, radius, a_sph + h_max, h_max, noise_m)
    if att.all():
        return None
    if att.sum() < min_attached:
        return np.ones(len(X), bool)
    bad = att | np.roll(att, 1) | np.roll(att, -1)
    if bad.all():
        bad = att
    theta, ang = polar_about(D, c / cn)
    return (theta < inner * a_sph) | ~bad[sector_of(ang)]


def roughness_m(ranges_m: np.ndarray, dirs: np.ndarray, k: int = 8) -> float:
    """Model-free range noise scale (m): robust spread of each range about the median range of
    its ``k`` angular neighbours (smooth surfaces cancel; about 1.2 x the range noise)."""
    if len(ranges_m) <= k:
        return float("nan")
    _, nb = cKDTree(dirs).query(dirs, k=k + 1)
    return robust_sigma(ranges_m - np.median(ranges_m[nb[:, 1:]], axis=1))


def longest_attached_arc(att: np.ndarray) -> int:
    """The longest run of attached sectors around the outline (circular), a single free sector
    between two attached ones counted as attached (a sparse scan misses one): a hand, a stick or
    a chain holds a ball over 1-3 sectors, each on its own; a body below a round thing (a head
    on its shoulders, a rock in the seabed) continues it over one long arc."""
    att = np.asarray(att, bool)
    n = len(att)
    if att.all():
        return n
    filled = att | (np.roll(att, 1) & np.roll(att, -1))
    start = int(np.argmin(filled))  # a free sector: unroll the circle there
    best = run = 0
    for a in np.roll(filled, -start):
        run = run + 1 if a else 0
        best = max(best, run)
    return best
