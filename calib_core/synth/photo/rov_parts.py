"""Parts of the held-out kind "rov" (:mod:`calib_core.synth.photo.rov`): the wide-angle lens,
the vehicle's own parts in view, and the water around it.

- :func:`wide_lens`: pinhole + plumb_bob with strong barrel distortion as an action camera or
  an ROV's dome-port camera is calibrated: k1 -0.35 to -0.25, k2 0.05-0.15, k3 within 0.01,
  p1, p2 of a few 1e-4, and a focal length giving 90-120 deg across the image's width through
  that distortion (the side edge's ray is at half that angle). Rejected and drawn again when
  the distortion folds inside the image (:func:`calib_core.synth.rig.lens_ok`) or stops being
  barrel before the corners (the radial factor must stay under 0.95 there: with k2 > 0 the
  polynomial turns up far out).
- :func:`vehicle_parts`: a skid (a bar across the bottom of the view), a manipulator arm (two
  links and a two-finger jaw reaching in from a bottom corner), the tether (a sagging cable
  leaving the view); each placed through the lens at a pixel near the frame's edge, at
  0.3-1.5 m, drawn on a share of the frames and left out when it would hide any of the ball.
- :func:`environment`: open water (the underwater kind's water, a sand or rock seabed on most),
  a test tank (the tank kind's tiled box and pool water, no mirror), or a dock (a concrete
  harbour wall behind, pilings, a muddy bed, coastal water).

No constant here was taken from a real image.
"""

from __future__ import annotations

import numpy as np

from calib_core.camera import CameraModel
from calib_core.geometry import transform_points
from calib_core.synth.occlusion import occluded_fraction
from calib_core.synth.photo import heldout as held
from calib_core.synth.photo.tank import pool_water, tank_box
from calib_core.synth.rig import lens_ok
from calib_core.synth.scene import Capsule, Cylinder, Group, Material, Rect, Scene

PART_COLOURS = ((0.85, 0.68, 0.08), (0.90, 0.40, 0.05), (0.45, 0.45, 0.47), (0.08, 0.08, 0.09), (0.80, 0.80, 0.78))


def wide_lens(rng, width_px: int, height_px: int, name: str = "cam1") -> CameraModel:
    """A wide-angle plumb_bob camera (see the module doc)."""
    for _ in range(1000):
        k1, k2, k3 = rng.uniform(-0.35, -0.25), rng.uniform(0.05, 0.15), rng.uniform(-0.01, 0.01)
        r = np.tan(np.deg2rad(rng.uniform(90.0, 120.0)) / 2)
        x_d = r * (1 + k1 * r ** 2 + k2 * r ** 4 + k3 * r ** 6)
        if x_d <= 0:
            continue
        f = 0.5 * width_px / x_d
        cx = width_px / 2 + rng.normal(0, 0.01 * width_px)
        cy = height_px / 2 + rng.normal(0, 0.01 * height_px)
        p1, p2 = rng.normal(0, 3e-4, 2)
        K = np.array([[f, 0, cx], [0, f * (1 + rng.normal(0, 0.002)), cy], [0, 0, 1.0]])
        cam = CameraModel(width_px, height_px, K, np.array([k1, k2, p1, p2, k3]), name=name)
        if lens_ok(cam) and _barrel_to_the_corners(cam):
            return cam
    raise RuntimeError("could not sample a wide-angle lens")


def _barrel_to_the_corners(cam: CameraModel) -> bool:
    """The radial factor 1 + k1 r^2 + k2 r^4 + k3 r^6 stays under 0.95 out to the image's
    corners (with k2 > 0 it rises again far out: such a lens would not be barrel there)."""
    W, H = cam.width_px, cam.height_px
    xy = cam.normalize(np.array([[-0.5, -0.5], [W - 0.5, -0.5], [-0.5, H - 0.5], [W - 0.5, H - 0.5]]))
    r2 = np.linspace(0.0, 1.0, 50)[:, None] * (xy ** 2).sum(axis=1)[None, :]
    k1, k2, _, _, k3 = cam.dist
    factor = 1 + k1 * r2 + k2 * r2 ** 2 + k3 * r2 ** 3
    return bool(np.isfinite(xy).all() and factor[1:].max() < 1.0 and factor[-1].max() < 0.95)


def _at_pixel(cam, T_wc, uv, depth_m) -> np.ndarray:
    """World point on the ray of raw pixel ``uv`` at ``depth_m`` (camera z)."""
    xy = cam.normalize(np.asarray(uv, float)[None])[0]
    return transform_points(T_wc, np.array([[xy[0] * depth_m, xy[1] * depth_m, depth_m]]))[0]


def _mat(rng) -> Material:
    alb = np.array(PART_COLOURS[int(rng.integers(len(PART_COLOURS)))]) * rng.uniform(0.8, 1.05)
    return Material(tuple(np.clip(alb, 0, 1)), 0.5, "noise", 0.05, float(rng.uniform(0.05, 0.3)),
                    int(rng.integers(1 << 30)))


def _skid(rng, cam, T_wc) -> Group:
    W, H = cam.width_px, cam.height_px
    z = float(rng.uniform(0.3, 0.8))
    v = float(rng.uniform(0.88, 0.99)) * H
    a, b = _at_pixel(cam, T_wc, (-0.3 * W, v), z), _at_pixel(cam, T_wc, (1.3 * W, v), z)
    r = float(rng.uniform(0.015, 0.04))
    return Group((Cylinder(tuple(a), tuple(b), r),), _mat(rng), tag="clutter")


def _arm(rng, cam, T_wc) -> Group:
    W, H = cam.width_px, cam.height_px
    side = float(rng.choice([-1.0, 1.0]))
    u0 = W / 2 + side * 0.55 * W
    base = _at_pixel(cam, T_wc, (u0, 1.05 * H), 0.3)
    elbow = _at_pixel(cam, T_wc, (W / 2 + side * rng.uniform(0.25, 0.45) * W, rng.uniform(0.72, 0.9) * H),
                      float(rng.uniform(0.5, 0.8)))
    wrist = _at_pixel(cam, T_wc, (W / 2 + side * rng.uniform(0.1, 0.3) * W, rng.uniform(0.65, 0.85) * H),
                      float(rng.uniform(0.8, 1.2)))
    r = float(rng.uniform(0.025, 0.045))
    d = (wrist - elbow) / np.linalg.norm(wrist - elbow)
    across = np.cross(d, T_wc[:3, 1])
    across /= max(np.linalg.norm(across), 1e-9)
    jaw = [Capsule(tuple(wrist), tuple(wrist + 0.08 * d + s * 0.03 * across), 0.4 * r) for s in (-1.0, 1.0)]
    return Group(tuple([Capsule(tuple(base), tuple(elbow), r), Capsule(tuple(elbow), tuple(wrist), 0.8 * r)] + jaw),
                 _mat(rng), tag="clutter")


def _tether(rng, cam, T_wc) -> Group:
    W, H = cam.width_px, cam.height_px
    side = float(rng.choice([-1.0, 1.0]))
    start = _at_pixel(cam, T_wc, (W / 2 + side * 0.6 * W, rng.uniform(0.2, 0.8) * H), float(rng.uniform(0.4, 0.8)))
    end = _at_pixel(cam, T_wc, (W / 2 + side * rng.uniform(-0.3, 0.4) * W, rng.uniform(0.3, 0.7) * H),
                    float(rng.uniform(3.0, 8.0)))
    s = np.linspace(0, 1, 9)[:, None]
    sag = float(rng.uniform(0.1, 0.6))
    pts = start + s * (end - start) - (np.sin(np.pi * s) * sag) * np.array([0, 0, 1.0])
    r = float(rng.uniform(0.008, 0.016))
    return Group(tuple(Capsule(tuple(a), tuple(b), r) for a, b in zip(pts[:-1], pts[1:])), _mat(rng), tag="clutter")


def vehicle_parts(rng, cam, T_wc, ball) -> tuple[list, list]:
    """(parts, names) of the vehicle in view: each of skid, arm, tether drawn on a share, and
    kept only when it hides none of ``ball``."""
    parts, names = [], []
    for name, make, p in (("skid", _skid, 0.35), ("arm", _arm, 0.3), ("rov-tether", _tether, 0.35)):
        if rng.random() >= p:
            continue
        part = make(rng, cam, T_wc)
        if occluded_fraction(Scene((ball, part)), 0, T_wc, ball.center_m, ball.radius_m) == 0:
            parts.append(part)
            names.append(name)
    return parts, names


def _dock(rng, eye, c, radius, floor_z) -> list:
    wall_x = float(c[0] + radius + rng.uniform(0.5, 4.0))
    concrete = Material(tuple(np.full(3, rng.uniform(0.3, 0.6)) * [1.0, 1.0, 0.95]), 0.5, "noise",
                        float(rng.uniform(0.05, 0.3)), float(rng.uniform(0.3, 0.7)), int(rng.integers(1 << 30)))
    prims = [Rect((wall_x, 0, floor_z + 5.0), (-1, 0, 0), (30.0, 5.0), u=(0, 1, 0), material=concrete, tag="wall")]
    for _ in range(int(rng.integers(1, 5))):
        p = np.array([rng.uniform(eye[0] + 1.0, wall_x), eye[1] + rng.uniform(-4, 4)])
        r = float(rng.uniform(0.08, 0.25))
        if np.hypot(*(p - np.asarray(c)[:2])) < radius + r + 0.3:
            continue
        prims.append(Cylinder((p[0], p[1], floor_z), (p[0], p[1], floor_z + 10.0), r,
                              Material(tuple(rng.uniform(0.15, 0.4, 3)), 0.5, "noise", 0.1, 0.5,
                                       int(rng.integers(1 << 30))), tag="clutter"))
    bed = Material((0.32, 0.30, 0.24), 0.5, "sand", float(rng.uniform(0.1, 0.3)), 0.5, int(rng.integers(1 << 30)))
    return prims + [Rect((0, 0, floor_z), (0, 0, 1), material=bed, tag="seabed")]


def environment(rng, where: str, T_wc, c, radius: float, floor_z: float, surface_z: float):
    """(static primitives, water, has_bed) of ``where``: "open", "bed", "tank" or "dock"."""
    eye = np.asarray(T_wc)[:3, 3]
    if where == "tank":
        lo = np.array([eye[0] - rng.uniform(0.5, 1.5), min(eye[1], c[1]) - radius - rng.uniform(0.5, 2.5), floor_z])
        hi = np.array([max(c[0] + radius + rng.uniform(0.3, 3.0), eye[0] + 2.5),
                       max(eye[1], c[1]) + radius + rng.uniform(0.5, 2.5), surface_z])
        return tank_box(lo, hi, rng, 0), pool_water(rng), True
    water, _ = held.ocean_water(rng, T_wc)
    if where == "dock":
        return _dock(rng, eye, c, radius, floor_z), water, True
    return (held.seabed(rng, floor_z, [c]) if where == "bed" else []), water, where == "bed"
