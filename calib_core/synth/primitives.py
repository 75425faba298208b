"""Analytic scene primitives (world frame, metres) used by :func:`calib_core.synth.scene.raycast`.

Each primitive has ``bound() -> (centre, radius) | None`` (a bounding sphere for culling)
and ``intersect(o (N,3), d (N,3) unit, acoustic) -> (t (N,), normal (N,3))`` giving the
nearest hit beyond ``T_MIN`` (inf on a miss). See :mod:`calib_core.synth.scene` for the
approximations (mesh lattice, acoustic view of the mesh).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

T_MIN = 1e-6
INF = np.inf


@dataclass(frozen=True)
class Material:
    """Optical albedo (RGB 0-1) and acoustic reflectivity (0-1); optionally a procedural
    texture (:mod:`calib_core.synth.textures`: "brick", "tiles", "noise", "foam") that
    modulates the albedo in camera images (the sonar ignores it)."""

    albedo: tuple[float, float, float] = (0.5, 0.5, 0.5)
    reflectivity: float = 0.5
    texture: str = ""
    texture_scale_m: float = 0.2
    texture_contrast: float = 0.5
    texture_seed: int = 0


def _vec(v) -> np.ndarray:
    return np.asarray(v, dtype=float).reshape(3)


def _unit(v) -> np.ndarray:
    v = _vec(v)
    return v / np.linalg.norm(v)


def frame_from_normal(n) -> np.ndarray:
    """3x3 with columns (u, v, n) for a unit normal n."""
    n = _unit(n)
    a = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
    u = np.cross(n, a)
    u /= np.linalg.norm(u)
    return np.column_stack([u, np.cross(n, u), n])


def rowwise_dot(a, b):
    return np.einsum("ij,ij->i", a, b)


def _sphere_roots(o, d, c, r):
    """Both ray parameters of a sphere hit (t1 <= t2), NaN where the ray misses."""
    oc = o - c
    b = rowwise_dot(oc, d)
    cc = rowwise_dot(oc, oc) - r * r
    disc = b * b - cc
    with np.errstate(invalid="ignore"):
        s = np.sqrt(disc)
    return -b - s, -b + s


def _first_positive(t1, t2):
    t = np.where(t1 > T_MIN, t1, np.where(t2 > T_MIN, t2, INF))
    return np.where(np.isnan(t), INF, t)


# ---- primitives ------------------------------------------------------------------
@dataclass(frozen=True)
class Sphere:
    """Solid sphere (decoys, floats)."""

    center_m: tuple
    radius_m: float
    material: Material = field(default_factory=Material)
    tag: str = "sphere"

    def bound(self):
        return _vec(self.center_m), self.radius_m

    def intersect(self, o, d, acoustic):
        c = _vec(self.center_m)
        t = _first_positive(*_sphere_roots(o, d, c, self.radius_m))
        n = (o + d * np.where(np.isfinite(t), t, 0)[:, None] - c) / self.radius_m
        return t, n


@dataclass(frozen=True)
class MeshSphere:
    """The open dark mesh target: lat/long wire lattice (see module notes).

    ``pole`` is the lattice's polar axis (world), ``n_lat`` latitude bands (rings at
    k*pi/n_lat), ``n_lon`` meridians, ``wire_m`` wire thickness (radial and lateral).
    """

    center_m: tuple
    radius_m: float
    material: Material = field(default_factory=lambda: Material((0.06, 0.06, 0.07), 0.9))
    n_lat: int = 12
    n_lon: int = 24
    wire_m: float = 0.005
    pole: tuple = (0.0, 0.0, 1.0)
    samples: int = 12
    tag: str = "target"

    def bound(self):
        return _vec(self.center_m), self.radius_m

    def _on_wire(self, p):
        """Boolean: sphere-relative points p (M,3) lie on a wire band."""
        R = frame_from_normal(self.pole)
        q = p @ R  # local coords, z = pole
        rho = np.linalg.norm(q, axis=1)
        theta = np.arccos(np.clip(q[:, 2] / np.maximum(rho, 1e-12), -1, 1))
        phi = np.arctan2(q[:, 1], q[:, 0])
        half = 0.5 * self.wire_m / self.radius_m  # angular half width of a wire
        dlat = np.pi / self.n_lat
        k = np.clip(np.round(theta / dlat), 1, self.n_lat - 1)
        on_lat = np.abs(theta - k * dlat) < half
        dlon = 2 * np.pi / self.n_lon
        dphi = np.abs(phi - np.round(phi / dlon) * dlon)
        on_lon = dphi * np.sin(theta) < half
        polar_cap = (theta < half) | (theta > np.pi - half)
        return on_lat | on_lon | polar_cap

    def intersect(self, o, d, acoustic):
        c = _vec(self.center_m)
        r = self.radius_m
        to1, to2 = _sphere_roots(o, d, c, r)
        if acoustic:
            t = _first_positive(to1, to2)
            n = (o + d * np.where(np.isfinite(t), t, 0)[:, None] - c) / r
            return t, n
        ti1, ti2 = _sphere_roots(o, d, c, r - self.wire_m)
        t = np.full(len(o), INF)
        hit_outer = np.isfinite(to1) & (to2 > T_MIN)
        inner = np.isfinite(ti1)
        # two segments through the wire layer: [to1, ti1 or to2] and [ti2, to2]
        segs = [(to1, np.where(inner, ti1, to2), hit_outer), (ti2, to2, hit_outer & inner)]
        for a, b, ok in segs:
            idx = np.nonzero(ok & ~np.isfinite(t))[0]
            if idx.size == 0:
                continue
            aa, bb = np.maximum(a[idx], T_MIN), b[idx]
            good = bb > aa
            idx, aa, bb = idx[good], aa[good], bb[good]
            # short crossings (front/back faces) need few samples, grazing ones many
            short = (bb - aa) < 1.5 * self.wire_m
            for sel, M in ((short, 3), (~short, self.samples)):
                if not sel.any():
                    continue
                frac = (np.arange(M) + 0.5) / M
                ii, a2, b2 = idx[sel], aa[sel], bb[sel]
                ts = a2[:, None] + (b2 - a2)[:, None] * frac[None, :]  # (K,M)
                P = (o[ii] - c)[:, None, :] + d[ii][:, None, :] * ts[..., None]
                on = self._on_wire(P.reshape(-1, 3)).reshape(ts.shape)
                anyhit = on.any(axis=1)
                first = np.argmax(on, axis=1)
                t[ii[anyhit]] = ts[anyhit, first[anyhit]]
        n = (o + d * np.where(np.isfinite(t), t, 0)[:, None] - c)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        return t, n


@dataclass(frozen=True)
class Disc:
    """Flat disc (decoy plates, round signs)."""

    center_m: tuple
    normal: tuple
    radius_m: float
    material: Material = field(default_factory=Material)
    tag: str = "disc"

    def bound(self):
        return _vec(self.center_m), self.radius_m

    def intersect(self, o, d, acoustic):
        return _disc(o, d, _vec(self.center_m), _unit(self.normal), self.radius_m)


def _disc(o, d, c, n, r):
    dn = d @ n
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((c - o) @ n) / dn
    p = o + d * np.where(np.isfinite(t), t, 0)[:, None] - c
    ok = np.isfinite(t) & (t > T_MIN) & (rowwise_dot(p, p) <= r * r)
    t = np.where(ok, t, INF)
    return t, np.broadcast_to(n, o.shape).copy()


def _cylinder_side(o, d, p0, axis, length, r):
    oc = o - p0
    da = d @ axis
    oa = oc @ axis
    dp = d - da[:, None] * axis
    op = oc - oa[:, None] * axis
    A = rowwise_dot(dp, dp)
    B = 2 * rowwise_dot(dp, op)
    C = rowwise_dot(op, op) - r * r
    disc = B * B - 4 * A * C
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.sqrt(disc)
        t1 = (-B - s) / (2 * A)
        t2 = (-B + s) / (2 * A)
    best = np.full(len(o), INF)
    for tt in (t2, t1):  # t1 last so it wins when valid
        h = oa + da * tt
        ok = np.isfinite(tt) & (tt > T_MIN) & (h >= 0) & (h <= length)
        best = np.where(ok & (tt < best), tt, best)
    p = oc + d * np.where(np.isfinite(best), best, 0)[:, None]
    n = p - (p @ axis)[:, None] * axis
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    return best, n


@dataclass(frozen=True)
class Capsule:
    """Cylinder with hemispherical ends (chain links, ropes, stand legs)."""

    p0_m: tuple
    p1_m: tuple
    radius_m: float
    material: Material = field(default_factory=Material)
    tag: str = "capsule"

    def bound(self):
        p0, p1 = _vec(self.p0_m), _vec(self.p1_m)
        return 0.5 * (p0 + p1), 0.5 * np.linalg.norm(p1 - p0) + self.radius_m

    def intersect(self, o, d, acoustic):
        p0, p1 = _vec(self.p0_m), _vec(self.p1_m)
        L = np.linalg.norm(p1 - p0)
        t, n = _cylinder_side(o, d, p0, (p1 - p0) / L, L, self.radius_m)
        for c in (p0, p1):
            ts = _first_positive(*_sphere_roots(o, d, c, self.radius_m))
            better = ts < t
            if better.any():
                t = np.where(better, ts, t)
                n[better] = (o[better] + d[better] * ts[better, None] - c) / self.radius_m
        return t, n


@dataclass(frozen=True)
class Cylinder:
    """Finite cylinder with flat caps (pipes, posts)."""

    p0_m: tuple
    p1_m: tuple
    radius_m: float
    material: Material = field(default_factory=Material)
    tag: str = "cylinder"

    def bound(self):
        p0, p1 = _vec(self.p0_m), _vec(self.p1_m)
        return 0.5 * (p0 + p1), float(np.hypot(0.5 * np.linalg.norm(p1 - p0), self.radius_m))

    def intersect(self, o, d, acoustic):
        p0, p1 = _vec(self.p0_m), _vec(self.p1_m)
        L = np.linalg.norm(p1 - p0)
        a = (p1 - p0) / L
        t, n = _cylinder_side(o, d, p0, a, L, self.radius_m)
        for c, nn in ((p0, -a), (p1, a)):
            tc, nc = _disc(o, d, c, nn, self.radius_m)
            better = tc < t
            t = np.where(better, tc, t)
            n[better] = nc[better]
        return t, n


@dataclass(frozen=True)
class Box:
    """Oriented box: ``R`` columns are the box axes in the world, ``half_m`` half sizes."""

    center_m: tuple
    half_m: tuple
    R: tuple = ((1.0, 0, 0), (0, 1.0, 0), (0, 0, 1.0))
    material: Material = field(default_factory=Material)
    tag: str = "box"

    def bound(self):
        return _vec(self.center_m), float(np.linalg.norm(self.half_m))

    def intersect(self, o, d, acoustic):
        R = np.asarray(self.R, float)
        h = np.asarray(self.half_m, float)
        if o.ndim == 2 and len(o) and o.strides[0] == 0:  # one shared origin: transform it once
            o = o[:1]
        ol = (o - _vec(self.center_m)) @ R
        dl = d @ R
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / dl
            t1 = (-h - ol) * inv
            t2 = (h - ol) * inv
        tlo, thi = np.minimum(t1, t2), np.maximum(t1, t2)  # NaN (origin on a slab face) -> NaN-free below
        np.nan_to_num(tlo, copy=False, nan=-INF)
        np.nan_to_num(thi, copy=False, nan=INF)
        ax_lo, ax_hi = tlo.argmax(axis=1), thi.argmin(axis=1)
        rows = np.arange(len(d))
        tnear, tfar = tlo[rows, ax_lo], thi[rows, ax_hi]
        hit = (tnear <= tfar) & (tfar > T_MIN)
        enter = tnear > T_MIN
        t = np.where(hit, np.where(enter, tnear, tfar), INF)
        ax = np.where(enter, ax_lo, ax_hi)
        nl = np.zeros((len(d), 3))
        nl[rows, ax] = -np.sign(dl[rows, ax])
        return t, nl @ R.T


@dataclass(frozen=True)
class Rect:
    """Finite plane (seabed, walls): centre, normal, in-plane half sizes along (u, v).

    ``u`` is an in-plane direction (orthogonalised against the normal); half sizes may be inf.
    """

    center_m: tuple
    normal: tuple
    half_m: tuple = (INF, INF)
    u: tuple = (1.0, 0.0, 0.0)
    material: Material = field(default_factory=Material)
    tag: str = "plane"

    def bound(self):
        if np.all(np.isfinite(self.half_m)):
            return _vec(self.center_m), float(np.linalg.norm(self.half_m))
        return None

    def intersect(self, o, d, acoustic):
        n = _unit(self.normal)
        u = _vec(self.u) - (_vec(self.u) @ n) * n
        if np.linalg.norm(u) < 1e-9:
            u = frame_from_normal(n)[:, 0]
        u = u / np.linalg.norm(u)
        v = np.cross(n, u)
        c = _vec(self.center_m)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((c - o) @ n) / (d @ n)
        p = o + d * np.where(np.isfinite(t), t, 0)[:, None] - c
        ok = np.isfinite(t) & (t > T_MIN) & (np.abs(p @ u) <= self.half_m[0]) & (np.abs(p @ v) <= self.half_m[1])
        return np.where(ok, t, INF), np.broadcast_to(n, o.shape).copy()


@dataclass(frozen=True)
class Group:
    """Several primitives acting as one (one id, one material): a chain of links, a stand.

    Rays are tested against the group's bounding sphere once, then against each member.
    """

    members: tuple
    material: Material = field(default_factory=Material)
    tag: str = "group"

    def __post_init__(self):
        bs = [m.bound() for m in self.members]
        if any(b is None for b in bs) or not bs:
            bound = None
        else:
            c = np.array([b[0] for b in bs]).mean(axis=0)
            bound = (c, float(max(np.linalg.norm(bc - c) + br for bc, br in bs)))
        object.__setattr__(self, "_bound", bound)
        object.__setattr__(self, "_member_bounds", bs)

    def bound(self):
        return self._bound

    def intersect(self, o, d, acoustic):
        t = np.full(len(o), INF)
        n = np.zeros((len(o), 3))
        for m, (c, R) in zip(self.members, self._member_bounds):
            oc = o - c
            b = rowwise_dot(oc, d)
            idx = np.nonzero(rowwise_dot(oc, oc) - b * b <= R * R)[0]
            if idx.size == 0:
                continue
            tm, nm = m.intersect(o[idx], d[idx], acoustic)
            better = tm < t[idx]
            sel = idx[better]
            t[sel] = tm[better]
            n[sel] = nm[better]
        return t, n
