"""Declarative scene primitives and ONE vectorised analytic ray caster.

The camera renderer (:mod:`calib_core.synth.camera_render`) and the sonar simulator
(:mod:`calib_core.synth.sonar_sim`) both call :func:`raycast`, so optics and acoustics
see exactly the same geometry. Everything is in the WORLD frame, metres; the world
frame is right-handed with z up (gravity along -z). Directions passed to
:func:`raycast` must be unit vectors.

Every primitive carries a :class:`Material`: an optical albedo (RGB, 0-1) and an acoustic
reflectivity (0-1; the sonar keeps a sub-ray hit only if it is strong enough).

Approximations (said here once):
- :class:`MeshSphere` is the open wire target: a latitude/longitude wire lattice
  occupying the spherical layer between ``radius_m - wire_m`` and ``radius_m``. Optical
  rays are marched through that layer at a fixed number of samples and stop at the
  first sample lying on a wire band, so very thin crossings can be missed and the hit
  depth is quantised to the sample spacing (the outer silhouette radius is exact where
  wires are, and ragged by < ~0.5 mm between them, like a real lattice). Acoustic
  rays see the mesh as a solid sphere of ``radius_m`` (wire spacing is comparable to
  the beam footprint, so the first return comes from the envelope).
- Normals of wires are taken radial (good enough for shading).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_core.synth.primitives import (INF, T_MIN, Box, Capsule, Cylinder, Disc, Group, Material,  # noqa: F401
                                         MeshSphere, Rect, Sphere, rowwise_dot)

__all__ = ["Box", "Capsule", "Cylinder", "Disc", "Group", "Material", "MeshSphere", "Rect", "Scene", "Sphere",
           "T_MIN", "raycast"]


@dataclass(frozen=True)
class Scene:
    """A list of primitives; ``hit_id`` from :func:`raycast` indexes ``primitives``."""

    primitives: tuple = ()

    def ids_with_tag(self, *tags: str) -> list[int]:
        return [i for i, p in enumerate(self.primitives) if p.tag in tags]

    def without(self, *tags: str) -> "Scene":
        """The same scene minus every primitive whose tag is in ``tags``."""
        return Scene(tuple(p for p in self.primitives if p.tag not in tags))

    def reflectivity(self) -> np.ndarray:
        return np.array([p.material.reflectivity for p in self.primitives] + [0.0])

    def albedo(self) -> np.ndarray:
        """(P+1,3) albedo per primitive id; the last row (index -1) is for misses."""
        return np.array([p.material.albedo for p in self.primitives] + [(0.0, 0.0, 0.0)], float)


def _candidate_rays(bound, o: np.ndarray, single: bool, d: np.ndarray, best: np.ndarray):
    """Indices of the rays that may hit a primitive with bounding sphere ``bound`` (centre,
    radius): the ray's line passes within the radius and the sphere is neither behind nor
    beyond the nearest hit so far. None (every ray) for an unbounded primitive."""
    if bound is None:
        return None
    c, R = bound
    oc = o - c
    if single:
        b = d @ oc
        dist2 = oc @ oc - b * b
    else:
        b = rowwise_dot(oc, d)
        dist2 = rowwise_dot(oc, oc) - b * b
    return np.nonzero((dist2 <= R * R) & (-b - R < best) & (-b + R > 0))[0]


def _keep_nearer(best, hit, normal, i: int, idx, t, n) -> None:
    """Record primitive ``i``'s hits ``t`` (normals ``n``) of the rays ``idx`` (None: all)
    where they are nearer than the best so far (in place)."""
    if idx is None:
        better = t < best
        best[better] = t[better]
        hit[better] = i
        normal[better] = n[better]
    else:
        better = t < best[idx]
        sel = idx[better]
        best[sel] = t[better]
        hit[sel] = i
        normal[sel] = n[better]


def raycast(scene: Scene, origins: np.ndarray, dirs: np.ndarray, acoustic: bool = False,
            max_range_m: float = INF):
    """Cast rays (world frame, metres; ``dirs`` unit) against every primitive.

    Returns ``(t_m (N,), hit_id (N,) int (-1 = miss), normal (N,3) unit, world frame)``: the
    nearest hit distance along each ray (inf on a miss), the index of the primitive hit
    and its outward surface normal. ``acoustic`` selects the sonar's view of primitives
    that differ between light and sound (the mesh target, see module notes).
    """
    d = np.ascontiguousarray(np.asarray(dirs, float).reshape(-1, 3))
    N = len(d)
    o_in = np.asarray(origins, float)
    single = o_in.size == 3  # one origin for every ray (a camera, a sonar): cheap culling
    o = o_in.reshape(3) if single else np.ascontiguousarray(np.broadcast_to(o_in, (N, 3)))
    best = np.full(N, float(max_range_m))
    hit = np.full(N, -1, dtype=np.int64)
    normal = np.zeros((N, 3))
    for i, prim in enumerate(scene.primitives):
        idx = _candidate_rays(prim.bound(), o, single, d, best)
        if idx is not None and idx.size == 0:
            continue
        if idx is None:
            t, n = prim.intersect(np.broadcast_to(o, (N, 3)) if single else o, d, acoustic)
        else:
            t, n = prim.intersect(np.broadcast_to(o, (len(idx), 3)) if single else o[idx], d[idx], acoustic)
        _keep_nearer(best, hit, normal, i, idx, t, n)
    best[hit < 0] = INF
    return best, hit, normal
