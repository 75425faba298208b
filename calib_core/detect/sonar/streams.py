"""Randomness keyed to the content of a range cloud, so that what is drawn for one part of it
does not depend on the rest.

With one random stream for the whole cloud, one more RANSAC look in one cluster, one more
object far away, or the points in another order change every later draw, and a far, sparse
ball (a sonar fan or a 16-ring LiDAR at 3-4 m: 30-100 returns) flips between found and refused.
Here

- each point gets a pseudo-random 64-bit hash of its own coordinates (:func:`point_hash`):
  thinning keeps the points whose hash is low (:func:`thin_hashed`; adding points elsewhere
  changes only the threshold, so the kept set grows or shrinks by a few points, and the order
  of the points does not matter), and a crop's judged subset is its lowest hashes
  (:func:`lowest_hashes`);
- each cluster of voxels gets a random stream seeded from its own voxels (:func:`content_rng`).

``key`` (the detector's ``rng_seed``) mixes into every hash and stream: another key is another
draw of the whole search, which is how the benchmarks measure its luck.
"""

from __future__ import annotations

import zlib

import numpy as np

_M1 = np.uint64(0x9E3779B97F4A7C15)
_M2 = np.uint64(0xBF58476D1CE4E5B9)
_M3 = np.uint64(0x94D049BB133111EB)


def _mix(h: np.ndarray, tmp: np.ndarray) -> np.ndarray:
    """splitmix64's finaliser, in place on ``h`` (uint64; wrap-around arithmetic), with the
    scratch array ``tmp`` (fresh temporaries cost page faults on big clouds)."""
    for shift, mult in ((30, _M2), (27, _M3)):
        np.right_shift(h, np.uint64(shift), out=tmp)
        h ^= tmp
        h *= mult
    np.right_shift(h, np.uint64(31), out=tmp)
    h ^= tmp
    return h


def point_hash(points_m: np.ndarray, key: int = 0) -> np.ndarray:
    """(N,) uint64: a hash of each point's exact coordinates (float64 bits) and ``key``."""
    bits = np.ascontiguousarray(points_m, dtype=np.float64).view(np.uint64).reshape(-1, 3)
    with np.errstate(over="ignore"):
        h = bits[:, 0] * _M1
        tmp = np.multiply(bits[:, 1], _M2)
        h ^= tmp
        np.multiply(bits[:, 2], _M3, out=tmp)
        h ^= tmp
        h ^= np.uint64(key & 0xFFFFFFFFFFFFFFFF)
        return _mix(h, tmp)


def thin_hashed(points_m: np.ndarray, max_points: int, key: int = 0) -> np.ndarray:
    """About ``max_points`` of the points (all when there are no more): those whose hash lies
    below max_points / N of the hash range, in their original order."""
    n = len(points_m)
    if n <= max_points:
        return points_m
    limit = np.uint64(min(int(max_points / n * 2.0 ** 64), 2 ** 64 - 1))
    return points_m[point_hash(points_m, key) < limit]


def lowest_hashes(points_m: np.ndarray, n: int, key: int = 0) -> np.ndarray:
    """Indices of the ``n`` points with the lowest hashes (all of them when there are no more),
    in hash order: the same points in the same order whatever order they come in."""
    h = point_hash(points_m, key)
    order = np.argsort(h, kind="stable")
    return order[:n]


def content_rng(X: np.ndarray, step_m: float, key: int = 0) -> np.random.Generator:
    """A random stream of its own for the point set ``X`` (a cluster of voxels), seeded from
    its coordinates rounded to ``step_m`` (in any order) and ``key``."""
    q = np.round(np.asarray(X, float) / step_m).astype(np.int64).reshape(-1, 3)
    q = q[np.lexsort(q.T[::-1])]
    return np.random.default_rng([int(key) & 0xFFFFFFFF, zlib.crc32(q.tobytes())])
