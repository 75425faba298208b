"""Round boulders on the seabed around the work area (the "underwater" session preset).

A hard negative for both sensors: half-buried spheres of about the target's size, lying on the
seabed near where the target is held, so that an image shows round outlines of the ball's
size and contrast that are not the ball, and the sonar sees round caps on the seabed. They
are static scenery (the same in every capture); the target moves from capture to capture.

Placement: ``n`` boulders, each beside a target centre drawn at random (0.4-1.6 m across,
horizontally), radius 0.6-1.6 x the target's, its centre 0.4 r below to 0.3 r above the
seabed (half-buried); kept clear of every target centre (horizontal gap at least 0.3 m plus
both radii) and dropped when it hides any part of any capture's target from any camera
(:func:`calib_core.synth.occlusion.occluded_fraction`), or when no camera sees it.
"""

from __future__ import annotations

import numpy as np

from calib_core.geometry import invert_T, transform_points
from calib_core.synth.occlusion import occluded_fraction
from calib_core.synth.scene import Material, Scene, Sphere

GAP_M = 0.3  # horizontal clearance between a boulder and a target centre, beyond both radii
TRIES = 60


def round_boulders(rng, rig, seabed_z: float, n: int, target_radius_m: float, centers_world) -> list:
    """Up to ``n`` boulder spheres (tag "clutter"), see the module doc."""
    centers = [np.asarray(c, float) for c in centers_world]
    out: list = []
    for _ in range(TRIES):
        if len(out) >= n:
            break
        b = _draw(rng, seabed_z, target_radius_m, centers)
        if b is not None and _seen(rig, b) and not _hides_target(rig, b, centers, target_radius_m):
            out.append(b)
    return out


def _draw(rng, seabed_z: float, target_radius_m: float, centers: list):
    r = float(rng.uniform(0.6, 1.6)) * target_radius_m
    c = centers[int(rng.integers(len(centers)))]
    ang, dist = rng.uniform(0, 2 * np.pi), rng.uniform(0.4, 1.6)
    p = np.array([c[0] + dist * np.cos(ang), c[1] + dist * np.sin(ang), seabed_z + float(rng.uniform(-0.4, 0.3)) * r])
    if min(np.hypot(*(p - k)[:2]) for k in centers) < GAP_M + r + target_radius_m:
        return None
    shade = float(rng.uniform(0.12, 0.5))
    tint = rng.uniform(0.85, 1.15, 3)
    mat = Material(tuple(float(a) for a in np.clip(shade * tint, 0, 1)), 0.6, "noise", float(rng.uniform(0.03, 0.1)),
                   float(rng.uniform(0.2, 0.6)), int(rng.integers(1 << 30)))
    return Sphere(tuple(float(x) for x in p), r, mat, tag="clutter")


def _seen(rig, b: Sphere) -> bool:
    """Its top in front of some camera and inside its image."""
    top = np.asarray(b.center_m, float) + [0, 0, 0.5 * b.radius_m]
    for cam, T_wc in rig.cams.values():
        X = transform_points(invert_T(T_wc), top[None])
        if X[0, 2] > 0.3 and cam.in_image(cam.project(X)).all():
            return True
    return False


def _hides_target(rig, b: Sphere, centers: list, target_radius_m: float) -> bool:
    for c in centers:
        ball = Sphere(tuple(c), target_radius_m, tag="target")
        for _, T_wc in rig.cams.values():
            if occluded_fraction(Scene((ball, b)), 0, T_wc, c, target_radius_m) > 0:
                return True
    return False
