"""How much of a sphere a camera sees: rays from the camera centre to the sphere's centre
and to points just inside its outline, cast against a scene (world frame, metres)."""

from __future__ import annotations

import numpy as np

from calib_core.geometry import invert_T, transform_points
from calib_core.synth.scene import Scene, raycast

# the generator's aim for a target capture that is meant to be seen whole
MAX_OCCLUDED_FRACTION = 0.05


def ring_points(C, radius, n=36):
    """Points on the sphere's outline circle (tangent points seen from the camera origin)."""
    dist = np.linalg.norm(C)
    w = C / dist
    e1 = np.cross(w, [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(w, e1)
    a = np.arcsin(radius / dist)
    phi = np.linspace(0, 2 * np.pi, n, endpoint=False)
    tang = (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
    return C[None] - w[None] * radius * np.sin(a) + tang * radius * np.cos(a)


def occluded_fraction(scene: Scene, target_id: int, T_world_cam: np.ndarray, center_world_m, radius_m: float,
                      n: int = 36) -> float:
    """Share of the rays (centre + ``n`` points at 0.9 of the outline) whose first hit is not
    primitive ``target_id``. The camera is a pinhole at ``T_world_cam``'s origin."""
    C = transform_points(invert_T(T_world_cam), np.asarray(center_world_m, float)[None])[0]
    ring = C[None] + 0.9 * (ring_points(C, radius_m, n) - C[None])
    pts_w = transform_points(T_world_cam, np.vstack([C[None], ring]))
    d = pts_w - T_world_cam[:3, 3]
    dist = np.linalg.norm(d, axis=1)
    _, hit, _ = raycast(scene, T_world_cam[:3, 3], d / dist[:, None], acoustic=True)
    return float(np.mean(hit != target_id))
