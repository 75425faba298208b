"""Coarse search for sphere candidates in a sonar cloud (sonar frame, metres).

Steps, all on a thinned copy of the cloud so that time does not grow with the point count:
thinning to about ``max_points`` points (by the points' own hashes), voxel downsampling (centroid per voxel),
removal of large planes (seabed, walls, dock faces) by RANSAC, connected-component
clustering, then a vectorised RANSAC sphere search inside each cluster and a first
plausibility screen (size, support, purity). The survivors are judged again at full
resolution by :mod:`calib_core.detect.sonar.detect`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from calib_core.detect.sonar.fit import algebraic_sphere, robust_sigma
from calib_core.detect.sonar.streams import content_rng, thin_hashed


@dataclass
class Candidate:
    """A coarse sphere hypothesis: centre (m, sonar frame), free radius seen in the
    downsampled cloud (m), support (voxels on the shell), purity (shell voxels over all
    voxels near the sphere), the cluster it came from, and a ranking quality in [0, 1]."""

    center_m: np.ndarray
    radius_m: float
    support: int
    purity: float
    cluster: int
    quality: float = 0.0
    spread_m: float = float("nan")


def crop_ball(P: np.ndarray, center: np.ndarray, radius: float) -> np.ndarray:
    """Indices of the points within ``radius`` of ``center`` (box test first, it is cheaper)."""
    box = np.nonzero(np.abs(P[:, 0] - center[0]) < radius)[0]
    box = box[np.abs(P[box, 1] - center[1]) < radius]
    d = P[box] - center
    return box[np.einsum("ij,ij->i", d, d) < radius * radius]


def voxel_downsample(points_m: np.ndarray, voxel_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(centroids (M,3), counts (M,)) of the points falling in each cubic voxel."""
    k = np.floor(points_m / voxel_m).astype(np.int64)
    k -= k.min(axis=0)
    span = k.max(axis=0) + 1
    key = (k[:, 0] * span[1] + k[:, 1]) * span[2] + k[:, 2]
    _, inv, cnt = np.unique(key, return_inverse=True, return_counts=True)
    inv = inv.ravel()
    cen = np.column_stack([np.bincount(inv, weights=points_m[:, j]) for j in range(3)])
    return cen / cnt[:, None], cnt


def _plane_from_3(P3: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = np.cross(P3[:, 1] - P3[:, 0], P3[:, 2] - P3[:, 0])
    nn = np.linalg.norm(n, axis=1)
    good = nn > 1e-12
    n = n / np.maximum(nn, 1e-12)[:, None]
    return n, np.einsum("ij,ij->i", n, P3[:, 0]), good


MAX_FAILED_PLANES = 3  # plane hypotheses that fail the extent/density checks before giving up
# a plane's voxels lie within a few tenths of the voxel of it (sd / voxel <= 0.2 measured on
# floors, walls, seabeds, tables of sonar, LiDAR and RGB-D clouds); a band filled evenly
# (sd / voxel ~ 0.5-0.75) is things that happen to line up (a ball, a person, a stick): no plane
MAX_PLANE_SCATTER = 0.35
# a plane whose returns sit on it to within a micron (MAD) is one depth step of a quantised
# sensor (stereo disparity steps), not a measured surface: it says nothing of the range noise
EXACT_PLANE_M = 1e-6


def remove_planes(Q: np.ndarray, min_extent_m: float, thr_m: float, rng: np.random.Generator,
                  max_planes: int = 4, n_hyp: int = 48, min_frac: float = 0.02,
                  min_count: int = 60, min_density: float = 0.1) -> tuple[np.ndarray, list]:
    """Mask of the voxels kept after removing up to ``max_planes`` large planes.

    A plane is removed when it holds at least ``max(min_count, min_frac * len)`` voxels within
    ``thr_m`` and spreads over more than ``min_extent_m`` (4 x the std along its second
    principal axis), so a sphere cap is never taken for a plane, fills at least
    ``min_density`` of the voxel cells of its area (scattered returns are no plane) and is thin
    (MAX_PLANE_SCATTER). A hypothesis that fails is set aside and another tried (up to
    MAX_FAILED_PLANES). Returns (keep mask,
    [(normal, offset, n_voxels)]).
    """
    keep = np.ones(len(Q), bool)
    tried = np.zeros(len(Q), bool)  # inliers of a plane that failed the checks: not sampled again
    planes = []
    for _ in range(max_planes + MAX_FAILED_PLANES):
        if len(planes) >= max_planes:
            break
        idx = np.nonzero(keep & ~tried)[0]
        if len(idx) < max(min_count, 10):
            break
        Qk = Q[idx]
        hyp = _plane_hypothesis(Qk, thr_m, rng, n_hyp, max(min_count * min(len(idx), 2000) / len(idx),
                                                             min_frac * min(len(idx), 2000)))
        if hyp is None:
            break
        nrm, off, ev, evec = _refit_plane(Qk, *hyp, thr_m)
        dist = np.abs(Qk @ nrm - off)
        on = dist < thr_m
        sd = 1.4826 * float(np.median(dist[on])) if on.any() else thr_m
        inl = idx[on]
        spread = 4.0 * np.sqrt(np.maximum(ev[[2, 1]], 0.0))
        density = len(inl) * thr_m * thr_m / max(spread[0] * spread[1], 1e-12)
        if len(inl) < min_count:
            break
        if spread[1] < min_extent_m or density < min_density or sd > MAX_PLANE_SCATTER * thr_m:
            tried[inl] = True  # (a sphere cap, scattered returns, a ball and a person that
            # happen to line up): look for another plane
            continue
        inl = _plane_pieces(Q, inl, evec[:, 1:], thr_m, 0.5 * min_extent_m, dist[on], sd)
        keep[inl] = False
        planes.append((nrm, off, int(len(inl))))
    return keep, planes


def _plane_hypothesis(Qk: np.ndarray, thr_m: float, rng: np.random.Generator, n_hyp: int,
                      min_support: float):
    """(normal, offset) of the best of ``n_hyp`` planes through random triples of (at most 2000
    of) the voxels ``Qk``, half anywhere, half among an anchor's 48 nearest (likelier coplanar);
    None when the best holds fewer than ``min_support`` of the sampled voxels within ``thr_m``."""
    S = Qk if len(Qk) <= 2000 else Qk[rng.integers(0, len(Qk), 2000)]
    k = min(48, len(S))
    _, nb = cKDTree(S).query(S[rng.integers(0, len(S), n_hyp // 2)], k=k)
    loc = np.take_along_axis(nb, np.c_[np.zeros(n_hyp // 2, int),
                                       rng.integers(1, k, (n_hyp // 2, 2))], axis=1)
    tri = S[np.vstack([rng.integers(0, len(S), (n_hyp - n_hyp // 2, 3)), loc])]
    n, d, good = _plane_from_3(tri)
    cnt = (np.abs(S @ n.T - d) < thr_m).sum(axis=0) * good
    b = int(np.argmax(cnt))
    return None if cnt[b] < min_support else (n[b], d[b])


def _refit_plane(Qk: np.ndarray, nrm, off, thr_m: float):
    """(normal, offset, eigenvalues ascending, eigenvectors) after two PCA refits on the voxels
    within ``thr_m`` of the plane."""
    ev, evec = np.zeros(3), np.eye(3)
    for _refit in range(2):
        X = Qk[np.abs(Qk @ nrm - off) < thr_m]
        if len(X) < 3:
            break
        mu = X.mean(axis=0)
        Xc = X - mu
        ev, evec = np.linalg.eigh(Xc.T @ Xc / len(X))  # ascending: normal first
        nrm, off = evec[:, 0], float(mu @ evec[:, 0])
    return nrm, off, ev, evec


def _plane_pieces(Q: np.ndarray, inl: np.ndarray, axes: np.ndarray, thr_m: float,
                  min_piece_m: float, dist_m: np.ndarray, sd_m: float) -> np.ndarray:
    """The plane's inliers that belong to connected pieces at least ``min_piece_m`` across
    (pieces: 8-connected cells of 2 x ``thr_m`` in the plane's own axes ``axes`` (3,2)): a
    ball that merely touches the plane (a table's front legs and the ball's front line up)
    is a small separate piece, curved through the band (rms distance ``dist_m`` over twice the
    plane's scatter ``sd_m``), and stays."""
    uv = Q[inl] @ axes
    cell = np.floor((uv - uv.min(axis=0)) / (2.0 * thr_m)).astype(int)
    grid = np.zeros(cell.max(axis=0) + 1, bool)
    grid[cell[:, 0], cell[:, 1]] = True
    lab_grid, n = ndimage.label(grid, structure=np.ones((3, 3), bool))
    if n <= 1:
        return inl
    lab = lab_grid[cell[:, 0], cell[:, 1]] - 1
    lo = np.full((n, 2), np.inf)
    hi = np.full((n, 2), -np.inf)
    np.minimum.at(lo, lab, uv)
    np.maximum.at(hi, lab, uv)
    big = (hi - lo).max(axis=1) >= min_piece_m
    # a small piece as flat as the plane is the plane (a patch cut off by a shadow); a small
    # piece spread through the band is something curved that touches it (a ball)
    cnt = np.bincount(lab, minlength=n)
    rms = np.sqrt(np.bincount(lab, weights=dist_m ** 2, minlength=n) / np.maximum(cnt, 1))
    flat = rms <= 2.0 * max(sd_m, 1e-9)
    return inl[(big | flat)[lab]]


def plane_range_noise_m(points_m: np.ndarray, planes: list, thr_m: float,
                        rng: np.random.Generator, max_points: int = 20_000) -> float:
    """Range noise scale (m) of the sensor, from the points on the removed planes: the robust
    spread of their distance to the plane converted to range (divided by the cosine of the
    incidence). NaN without planes. A rough (non-flat) seabed makes it larger, never smaller."""
    return plane_noise(points_m, planes, thr_m, rng, max_points)[0]


def plane_noise(points_m: np.ndarray, planes: list, thr_m: float, rng: np.random.Generator,
                max_points: int = 20_000) -> tuple[float, tuple[float, float]]:
    """(range noise (m) as :func:`plane_range_noise_m`, and (a, b) of the noise against range
    ``sigma(R) = sqrt(a^2 + (b R^2)^2)`` measured in range bins: constant for a sonar or a LiDAR,
    growing with the square of the range for a depth camera). NaNs without planes."""
    res, rr = _plane_residuals(points_m, planes, thr_m, rng, max_points)
    if len(res) < 50:
        return float("nan"), (float("nan"), float("nan"))
    return robust_sigma(res - np.median(res)), _noise_model(res, rr)


def _noise_model(res: np.ndarray, rr: np.ndarray) -> tuple[float, float]:
    """(a, b) of ``sigma(R)^2 = a^2 + b^2 R^4`` from the robust spread of the residuals ``res``
    in up to 6 range bins (non-negative least squares)."""
    from scipy.optimize import nnls

    n_bins = int(np.clip(len(res) // 200, 1, 6))
    edges = np.quantile(rr, np.linspace(0, 1, n_bins + 1))
    sig, rmid = [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        m = (rr >= lo) & (rr <= hi)
        if m.sum() >= 30:
            v = res[m]
            sig.append(robust_sigma(v - np.median(v)))
            rmid.append(float(np.median(rr[m])))
    if len(sig) < 2:
        return (sig[0] if sig else float("nan")), 0.0
    sol, _ = nnls(np.c_[np.ones(len(sig)), np.asarray(rmid) ** 4], np.asarray(sig) ** 2)
    return float(np.sqrt(sol[0])), float(np.sqrt(sol[1]))


def noise_at(model: tuple[float, float], range_m: float) -> float:
    """The range noise (m) of :func:`plane_noise`'s ``model`` at ``range_m``."""
    a, b = model
    return float(np.hypot(a, b * range_m * range_m)) if np.isfinite(a) else float("nan")


def _plane_residuals(points_m, planes, thr_m, rng, max_points):
    """(range residuals (m), ranges (m)) of the points near the removed planes."""
    if not planes:
        return np.zeros(0), np.zeros(0)
    sub = rng is not None and len(points_m) > max_points  # (None: the caller thinned them)
    S = points_m[rng.integers(0, len(points_m), max_points)] if sub else points_m
    R = np.linalg.norm(S, axis=1)
    D = S / np.maximum(R, 1e-12)[:, None]
    res, rr = [], []
    for n, off, _ in planes:
        dn = D @ n
        dist = S @ n - off
        m = (np.abs(dist) < 2 * thr_m) & (np.abs(dn) > 0.3)
        if m.sum() and np.median(np.abs(dist[m] - np.median(dist[m]))) < EXACT_PLANE_M:
            continue  # one depth step of a quantised sensor, not a surface: it shows no noise
        res.append(dist[m] / dn[m])
        rr.append(R[m])
    return (np.concatenate(res), np.concatenate(rr)) if res else (np.zeros(0), np.zeros(0))


def cluster_points(Q: np.ndarray, link_m: float) -> np.ndarray:
    """Connected-component labels (M,) of points linked when closer than ``link_m``."""
    if len(Q) == 0:
        return np.zeros(0, int)
    pairs = cKDTree(Q).query_pairs(link_m, output_type="ndarray")
    g = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(Q), len(Q)))
    return connected_components(g, directed=False)[1]


def _pairwise_dist(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """(len(A), len(B)) Euclidean distances, via |a|^2 + |b|^2 - 2 a.b (fast, ~1e-9 m exact)."""
    d2 = np.einsum("ij,ij->i", A, A)[:, None] + np.einsum("ij,ij->i", B, B)[None, :] - 2.0 * A @ B.T
    return np.sqrt(np.maximum(d2, 0.0))


def _batched_spheres(S4: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Spheres through 4-point samples (K,4,3): (centres (K,3), radii (K,), NaN if degenerate)."""
    o = S4[:, :1, :]
    X = S4[:, 1:, :] - o  # relative to the first point: sphere |x - c'|^2 = r^2 through 0
    A = 2.0 * X
    b = np.einsum("kij,kij->ki", X, X)
    det = np.linalg.det(A)
    ok = np.abs(det) > 1e-12
    A[~ok] = np.eye(3)
    cp = np.linalg.solve(A, b[..., None])[..., 0]
    r = np.linalg.norm(cp, axis=1)
    r[~ok] = np.nan
    return cp + o[:, 0, :], r


def ransac_sphere(X: np.ndarray, r_lo: float, r_hi: float, thr_m: float, reach_m: float,
                  rng: np.random.Generator, n_hyp: int = 96, r_pref: float | None = None,
                  r_pref_sd: float = 1.0):
    """Best sphere (centre, radius, inlier mask) with radius in [r_lo, r_hi] among random
    4-point samples drawn near random anchors; the centre must lie beyond its inliers as
    seen from the sonar at the origin. With ``r_pref`` the inlier count is weighted by a
    Gaussian in (radius - r_pref) / r_pref_sd, so a sphere of the expected size beats a
    larger one swallowing its chain or stand. None when no sample is acceptable."""
    n = len(X)
    if n < 6:
        return None
    anchors = rng.integers(0, n, n_hyp)
    if n <= 1500:  # 3 random partners within reach of each anchor
        dist = _pairwise_dist(X[anchors], X)
        key = np.where(dist < reach_m, rng.random(dist.shape), -1.0)
        key[np.arange(n_hyp), anchors] = -1.0
        part = np.argpartition(-key, 3, axis=1)[:, :3]
        pick = np.c_[anchors, part]
        pick[np.take_along_axis(key, part, axis=1).min(axis=1) < 0] = anchors[0]
    else:  # large cluster: partners among the k nearest of the anchor
        k = min(n, 96)
        dist, nb = cKDTree(X).query(X[anchors], k=k)
        col = rng.integers(1, k, (n_hyp, 3))
        pick = np.c_[anchors, np.take_along_axis(nb, col, axis=1)]
        pick[np.take_along_axis(dist, col, axis=1).max(axis=1) > reach_m] = anchors[0]
    C, Rr = _batched_spheres(X[pick])
    good = np.isfinite(Rr) & (Rr >= r_lo) & (Rr <= r_hi)
    if not good.any():
        return None
    C, Rr = C[good], Rr[good]
    Xs = X if n <= 3000 else X[rng.choice(n, 3000, replace=False)]
    dist = _pairwise_dist(C, Xs)
    cnt = (np.abs(dist - Rr[:, None]) < thr_m).sum(axis=1).astype(float)
    if r_pref is not None:
        cnt *= np.exp(-0.5 * ((Rr - r_pref) / r_pref_sd) ** 2)
    for b in np.argsort(-cnt, kind="stable")[:MAX_CHECKED]:
        inl = np.abs(np.linalg.norm(X - C[b], axis=1) - Rr[b]) < thr_m
        if inl.sum() < 6:
            continue
        ch = C[b] / np.linalg.norm(C[b])
        if np.mean((X[inl] - C[b]) @ ch) < -0.2 * Rr[b]:  # shell faces the sonar
            return C[b], float(Rr[b]), inl
    return None


def polar_about(dirs: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(angle from ``axis`` (rad), azimuth around it in [0, 2 pi)) of unit directions."""
    a = np.array([1.0, 0, 0]) if abs(axis[0]) < 0.9 else np.array([0, 1.0, 0])
    u = np.cross(axis, a)
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    x, y = dirs @ u, dirs @ v
    return np.arctan2(np.hypot(x, y), dirs @ axis), np.arctan2(y, x) + np.pi


def disc_coverage(dirs: np.ndarray, axis: np.ndarray, alpha: float) -> float:
    """Fraction of 12 polar bins (4 inner sectors, 8 outer) of the disc of angular radius
    ``alpha`` around ``axis`` that hold at least one of the unit directions ``dirs``."""
    theta, ang = polar_about(dirs, axis)
    rad = theta / alpha
    inner = rad < 0.55
    outer = (rad >= 0.55) & (rad <= 1.05)
    bins = np.where(inner, (ang / (2 * np.pi) * 4).astype(int) % 4,
                    4 + (ang / (2 * np.pi) * 8).astype(int) % 8)
    return len(np.unique(bins[inner | outer])) / 12.0


def ring_sectors(dirs: np.ndarray, axis: np.ndarray, alpha: float, width: float,
                 n_sectors: int = 16, min_points: int = 2) -> int:
    """How many of ``n_sectors`` sectors of the ring ``alpha < angle <= alpha + width`` around
    ``axis`` hold at least ``min_points`` of the unit directions ``dirs`` (a sphere hanging
    free leaves most empty: its chain or stand fills one to three; lone spurious returns none)."""
    theta, ang = polar_about(dirs, axis)
    sel = (theta > alpha) & (theta <= alpha + width)
    cnt = np.bincount((ang[sel] / (2 * np.pi) * n_sectors).astype(int) % n_sectors,
                      minlength=n_sectors)
    return int((cnt >= min_points).sum())


@dataclass(frozen=True)
class PreparedSearch:
    """The part of :func:`find_candidates` that does not depend on the beam half-angle, for one
    cloud, sphere radius, ``key`` and ``max_points``: the thinned points ``P`` (m), the clusters
    worth a look (``clusters``: (cluster id, its voxels without their local planes (m), the bit
    generator state of its random stream after that step)) and the counts of ``info``
    (voxels, planes, plane noise, clusters). Computed once by :func:`prepare_search`, it lets
    the beam width's crop detection (nominal width) and the final one (estimated width) of the
    same cloud share it; :func:`find_candidates` gives the same candidates with or without it."""

    n_points: int
    radius_m: float
    key: int
    max_points: int
    P: np.ndarray
    clusters: tuple
    info: dict

    def check(self, points_m: np.ndarray, radius_m: float, key: int, max_points: int) -> None:
        """Raise ValueError when this search was not prepared for these arguments (a cheap
        guard: the point count, radius, key and thinning; the caller vouches for the points)."""
        if (len(points_m), float(radius_m), int(key), int(max_points)) != \
                (self.n_points, self.radius_m, self.key, self.max_points):
            raise ValueError("the prepared search is of another cloud, radius, key or thinning")


def prepare_search(points_m: np.ndarray, radius_m: float, key: int = 0,
                   max_points: int = 40_000) -> PreparedSearch:
    """The beam-width-independent steps of :func:`find_candidates` on a cloud (sonar frame, m):
    thinning, voxels, large planes, their noise, clustering, and each large enough cluster's
    local planes (which draw from the cluster's own stream; its state after them is kept)."""
    r = float(radius_m)
    voxel = float(np.clip(r / 3.0, 0.005, 0.15))
    P = thin_hashed(points_m, max_points, key)
    Q, _ = voxel_downsample(P, voxel)
    info = {"n_voxels": int(len(Q)), "voxel_m": voxel}
    keep, planes = remove_planes(Q, min_extent_m=6.0 * r, thr_m=voxel, rng=np.random.default_rng([key, 1]))
    info["planes_removed"] = len(planes)
    info["noise_m"], info["noise_model"] = plane_noise(thin_hashed(P, 20_000, key), planes, voxel, None)
    Qk = Q[keep]
    labels = cluster_points(Qk, 2.2 * voxel)
    ids, counts = np.unique(labels, return_counts=True)
    clusters = []
    for cid in ids[np.argsort(-counts, kind="stable")]:
        X = Qk[labels == cid]
        if len(X) < MIN_VOXELS:
            break
        if np.ptp(X, axis=0).max() >= 0.6 * r:
            rng = content_rng(X, 0.1 * voxel, key)
            X = _cluster_voxels(X, r, voxel, rng)
            clusters.append((int(cid), _read_only(X), rng.bit_generator.state))
    info["n_clusters"] = int((counts >= MIN_VOXELS).sum())
    return PreparedSearch(len(points_m), r, int(key), int(max_points), _read_only(P), tuple(clusters), info)


def _read_only(A: np.ndarray) -> np.ndarray:
    """A read-only view of ``A`` (``A`` itself stays writeable): a shared search is never changed."""
    v = A.view()
    v.flags.writeable = False
    return v


def _stream(state: dict) -> np.random.Generator:
    """A fresh generator at a saved bit generator state (the saved state stays as it was)."""
    bg = getattr(np.random, state["bit_generator"])()
    bg.state = state
    return np.random.Generator(bg)


def find_candidates(points_m: np.ndarray, radius_m: float, half_angle_rad: float,
                    key: int = 0, max_points: int = 40_000,
                    max_candidates: int = 6, prepared: PreparedSearch | None = None) -> tuple[list[Candidate], dict]:
    """Sphere candidates in a cloud (sonar frame, m) for a sphere of nominal ``radius_m``.

    ``key`` seeds the random draws (:mod:`.streams`): the thinning by the points' own
    hashes, the plane search by a stream of its own, and each cluster's RANSAC by a stream
    seeded from that cluster's voxels, so what happens in one cluster (one more look, another
    object far away, the points' order) does not change the draws in another.
    ``prepared``: :func:`prepare_search` of the same points, radius, key and max_points (else
    computed here); the result is the same either way.
    Returns (at most ``max_candidates`` candidates, best first, and an info dict of counts).
    """
    r = float(radius_m)
    if prepared is None:
        prepared = prepare_search(points_m, r, key, max_points)
    prepared.check(points_m, r, key, max_points)
    P, info = prepared.P, dict(prepared.info)
    cands: list[Candidate] = []
    for cid, X, state in prepared.clusters:
        cands += _cluster_candidates(X, cid, r, half_angle_rad, info["voxel_m"], _stream(state))
    cands.sort(key=lambda k: -k.quality)
    info["n_coarse_candidates"] = len(cands)
    # the prescreen tells a sphere from round rocks (a few mm of spread against centimetres);
    # the coarse quality does not: on a seabed the ball ranked 13th of 37 at the right beam width
    # and 17th at 0.9 of it, so cutting to ``max_candidates`` before the prescreen lost it
    cands = _dedupe(cands, r)[:MAX_PRESCREENED]
    if cands:
        cands = prescreen(P, cands, r, half_angle_rad, info["noise_m"])[:max_candidates]
        info["n_prescreened"] = len(cands)
    return cands, info


MAX_PRESCREENED = 64  # coarse candidates prescreened, best coarse quality first


MIN_VOXELS = 6  # of a cluster, and on a candidate's shell
N_HYP = 96  # RANSAC samples per look
MAX_CHECKED = 32  # best-supported samples checked for a shell that faces the sensor
LONG_WIDTH = 3.5  # radii: a cluster at most this wide in its two shorter extents is long and thin
MAX_LOOKS = 12  # RANSAC looks in one cluster (a big one, a room with no plane removed, hides many round things)


def _cluster_voxels(X: np.ndarray, r: float, voxel: float, rng: np.random.Generator) -> np.ndarray:
    """A cluster's voxels as its RANSAC sees them: without its local planes when it is large
    (:func:`_without_local_planes`, drawing from ``rng``)."""
    if np.ptp(X, axis=0).max() > 3.0 * r and len(X) >= 3 * LOCAL_PLANE_MIN:
        return _without_local_planes(X, r, voxel, rng)
    return X


def _cluster_candidates(X: np.ndarray, cid: int, r: float, h: float, voxel: float,
                        rng: np.random.Generator) -> list[Candidate]:
    """Sphere candidates in one cluster of voxels (:func:`_cluster_voxels`): RANSAC, take the
    shell out, look again (a big cluster, a ball with the block, chair or person it touches,
    hides more than one)."""
    out = []
    bloom = float(np.linalg.norm(X.mean(axis=0))) * np.tan(h)
    thr = max(0.2 * r, 0.75 * voxel)
    r_hi = 1.5 * r + 2.0 * bloom + 0.01
    for _attempt in range(_n_looks(X, r)):
        found = ransac_sphere(X, 0.6 * r, r_hi, thr, 2.5 * r + bloom, rng, n_hyp=N_HYP,
                              r_pref=r + bloom, r_pref_sd=0.25 * r)
        if found is None:
            break
        c, rf, inl = found
        if inl.sum() >= 8:  # closed-form refit on the RANSAC shell
            c2, r2 = algebraic_sphere(X[inl])
            if np.isfinite(r2) and np.linalg.norm(c2 - c) < 0.5 * r:
                c, rf = c2, r2
        d = np.linalg.norm(X - c, axis=1)
        shell, ball = np.abs(d - rf) < thr, d < rf + thr
        cand = _candidate(X, shell, ball, c, rf, cid, r, h, r_hi)
        if cand is not None:
            out.append(cand)
        X = X[~(ball | shell)]
        if len(X) < 3 * MIN_VOXELS:  # a second sphere in the same cluster needs some room
            break
    return out


def _n_looks(X: np.ndarray, r: float) -> int:
    """RANSAC looks in a cluster: more for a big one (many voxels), and one per ball-sized
    stretch of a long thin one (a column or a post with the ball on its end, at most
    LONG_WIDTH radii across: each look takes out a band of it about a diameter long, and the
    ball is the last to be reached). Wider clusters (a ridge, a heap of rocks) get no more:
    their extra candidates cost restarts in the judging (500k seabed cloud: 64 -> 107 ms CPU)
    and can crowd the ball out of the few judged at full resolution."""
    ext = np.sort(np.ptp(X, axis=0))
    along = int(ext[2] / (2.0 * r)) if ext[1] <= LONG_WIDTH * r else 0
    return int(min(MAX_LOOKS, 2 + max(len(X) // 200, along)))


def _candidate(X, shell, ball, c, rf: float, cid: int, r: float, h: float, r_hi: float):
    """The Candidate of a RANSAC sphere (centre ``c``, radius ``rf``, its shell and ball masks
    over the cluster ``X``) when its shell is a cap seen from the sensor, else None."""
    support = int(shell.sum())
    purity = support / max(int(ball.sum()), 1)
    # a cap spreads in two directions; a chain or rope is a line
    ev = np.linalg.eigvalsh(np.cov(X[shell].T)) if support >= 3 else np.zeros(3)
    cn = float(np.linalg.norm(c))
    if (support < MIN_VOXELS or np.sqrt(max(ev[1], 0.0)) < 0.2 * r or cn <= rf
            or not 0.6 * r <= rf <= r_hi):
        return None
    S = X[shell]
    if disc_coverage(S / np.linalg.norm(S, axis=1)[:, None], c / cn,
                     float(np.arcsin(min(rf / cn, 1.0))) + h) < 0.4:
        return None
    # ranking: support (saturating), purity, and the radius a blooming sphere of the nominal
    # size would show (about r + range * tan(h))
    r_exp = r + cn * np.tan(h)
    quality = min(1.0, support / 20.0) * purity * float(np.exp(-0.5 * ((rf - r_exp) / (0.2 * r)) ** 2))
    return Candidate(np.asarray(c, float), float(rf), support, float(purity), cid, float(quality))


LOCAL_PLANE_MIN = 20  # voxels of a plane inside one cluster (a table top seen at a grazing angle)


def _without_local_planes(X: np.ndarray, r: float, voxel: float, rng: np.random.Generator) -> np.ndarray:
    """The cluster's voxels without the planes it holds that are too small for the cloud-wide
    search (a table top or a seat under the ball, seen at a grazing angle): up to two planes
    wider than 3 radii (a sphere cap never is)."""
    keep, planes = remove_planes(X, min_extent_m=3.0 * r, thr_m=voxel, rng=rng, max_planes=2,
                                 min_frac=0.1, min_count=LOCAL_PLANE_MIN)
    return X[keep] if planes and keep.sum() >= LOCAL_PLANE_MIN else X


def prescreen(points_m: np.ndarray, cands: list[Candidate], r: float, half_angle_rad: float,
              noise_m: float) -> list[Candidate]:
    """Keep the candidates whose returns look like a blooming sphere before any fit.

    For each, the cone-model range residuals at the coarse centre (moved nearer by the
    blooming, see ``start_center``) of the points inside its disc: their robust spread
    (``spread_m``, also tried with the radius the coarse fit suggests) is a few mm for a sphere
    and centimetres for boxes, pontoons and rocks cut by the seabed. Kept: spread below
    max(0.1 r, 2 x the plane noise, 2 x the best candidate's).
    """
    from calib_core.detect.sonar.fit import angle_to_axis_rad, cone_residuals

    for k in cands:
        best = np.inf
        r_alt = float(np.clip(k.radius_m - np.linalg.norm(k.center_m) * np.tan(half_angle_rad),
                              0.6 * r, 1.6 * r))
        X = points_m[crop_ball(points_m, start_center(k, r), 2.6 * r + 0.05)]
        if len(X) < 6:
            k.spread_m = best
            continue
        R = np.linalg.norm(X, axis=1)
        D = X / R[:, None]
        for rr in (r, r_alt):
            c = start_center(k, rr)
            cn = float(np.linalg.norm(c))
            ind = angle_to_axis_rad(D, c / cn) <= np.arcsin(min(rr / cn, 1.0)) + half_angle_rad
            if ind.sum() < 6:
                continue
            a, _ = cone_residuals(c, rr, R[ind], D[ind], half_angle_rad)
            best = min(best, 1.4826 * float(np.median(np.abs(a - np.median(a)))))
        k.spread_m = best
    lim = max(0.1 * r, 2.0 * noise_m if np.isfinite(noise_m) else 0.0,
              2.0 * min(k.spread_m for k in cands))
    return [k for k in cands if k.spread_m <= lim]


def start_center(cand: Candidate, radius_m: float) -> np.ndarray:
    """The coarse free-radius centre sits too far by about (apparent - true radius): the
    start for a cone-model fit of a sphere of ``radius_m``."""
    c0 = cand.center_m
    cn0 = float(np.linalg.norm(c0))
    return c0 * max(cn0 - (cand.radius_m - radius_m), radius_m * 1.5) / cn0


def _dedupe(cands: list[Candidate], r: float) -> list[Candidate]:
    out: list[Candidate] = []
    for c in cands:
        if all(np.linalg.norm(c.center_m - o.center_m) > r for o in out):
            out.append(c)
    return out

