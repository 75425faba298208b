"""Held-out image kind "tank": a ball in a test tank or pool, seen by a camera under water.

- The tank: a tiled floor and tiled walls (grid lines of grout, tile side 0.08-0.3 m, light
  blue or white tiles), axis-aligned around the camera, its water surface above the camera.
  On about half of the images one side wall next to the ball is a glass pane with a dim lab
  behind it.
- The camera: in the water 0.15-1.2 m under the surface, looking ahead and up by -5 to 35 deg
  (so that the surface fills the top of many frames and Snell's window shows in some).
- Mirrors (:mod:`calib_core.synth.photo.mirrors`): the surface seen from below reflects the
  tank and the ball totally outside Snell's window (a flipped copy of the ball just above it
  when the ball floats near the surface), and shows the bright sky inside the window; the
  glass pane reflects at grazing view (total reflection past 48.8 deg) and faintly near normal
  view (about 2 %): a second, flipped, dimmer copy of the ball beside it. The ball is placed
  0.01-0.4 m from the mirror it is drawn near. Ripples on the surface (slope 0-0.02 rad, wavelength 0.3-1 m)
  distort the reflection.
- Light: sun from above (a key light within 25 deg of the vertical), caustics on the floor
  and the ball on 60 % of the images; clear pool water (green attenuation 0.03-0.12 /m, red
  strongest) with a blue-cyan veil.
- The ball: a float (orange, white, yellow, red or dark), sometimes glossy, radius 0.05-0.2 m;
  on a rope to the surface, on a pole, tethered to the floor or resting on it.

Camera artefacts on a share (:func:`~calib_core.synth.photo.heldout_parts.camera_artefacts`).
No constant here was taken from a real image.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from calib_core.synth import world
from calib_core.synth.camera_render import Water, render_radiance
from calib_core.synth.photo import heldout_parts as hp
from calib_core.synth.photo.cases import draw_photo, metered
from calib_core.synth.photo.effects import BallLook
from calib_core.synth.photo.mirrors import Mirror, composite_mirror
from calib_core.synth.scene import Cylinder, Material, Rect, Scene, Sphere

FLOATS = ((0.95, 0.40, 0.06), (0.88, 0.88, 0.86), (0.92, 0.80, 0.10), (0.80, 0.12, 0.10), (0.06, 0.06, 0.07))
TILES = ((0.75, 0.85, 0.90), (0.88, 0.88, 0.86), (0.45, 0.65, 0.80))



def _tile_mat(rng) -> Material:
    alb = np.array(TILES[int(rng.integers(len(TILES)))]) * rng.uniform(0.85, 1.05)
    return Material(tuple(np.clip(alb, 0, 1)), 0.5, "tiles", float(rng.uniform(0.08, 0.3)),
                    float(rng.uniform(0.4, 0.9)), int(rng.integers(1 << 30)))


def tank_box(lo, hi, rng, glass_side: int):
    """Floor and four walls of the tank [lo, hi] (world, axis-aligned; normals inwards); the
    side wall y = hi (glass_side 1) or y = lo (-1) is a glass pane when glass_side != 0."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    floor = Rect((mid[0], mid[1], lo[2]), (0, 0, 1), (half[0], half[1]), u=(1, 0, 0), material=_tile_mat(rng),
                 tag="floor")
    prims = [floor]
    for axis, sgn in ((0, 1), (0, -1), (1, 1), (1, -1)):
        c = mid.copy()
        c[axis] = hi[axis] if sgn > 0 else lo[axis]
        n = np.zeros(3)
        n[axis] = -sgn
        other = 1 - axis
        u = np.zeros(3)
        u[other] = 1.0
        glass = axis == 1 and sgn == glass_side
        mat = Material((0.05, 0.07, 0.07), 0.5) if glass else _tile_mat(rng)
        prims.append(Rect(tuple(c), tuple(n), (half[other], half[2]), u=tuple(u), material=mat,
                          tag="glass" if glass else "wall"))
    return prims


def _place(rng, cam, T_wc, radius, scale, holder: str):
    eye = hp.eye_of(T_wc)

    def ok(c):  # in front; resting on the floor: the floor below the camera
        return 0.3 < c[0] - eye[0] and abs(c[2] - eye[2]) < 2.5 and (holder != "floor" or c[2] - radius < eye[2] - 0.3)
    return hp.place_by_size(rng, cam, T_wc, radius, (30.0 * scale, 0.45 * cam.height_px), ok)


def _tank_geometry(rng, eye, c, radius, holder):
    """Tank bounds (lo, hi), its surface height and the glass side (0 = none)."""
    near_surface = rng.random() < 0.6
    gap = float(np.exp(rng.uniform(np.log(0.01), np.log(0.4))))
    top = c[2] + radius + (gap if near_surface else rng.uniform(0.3, 1.5))
    surface_z = float(max(eye[2] + rng.uniform(0.15, 0.4), top))
    floor_z = float(c[2] - radius if holder == "floor" else min(eye[2] - 0.3, c[2] - radius) - rng.uniform(0.2, 1.5))
    side = float(np.sign(c[1] - eye[1]) or 1.0)
    glass_side = int(side) if rng.random() < 0.5 else 0
    g2 = float(np.exp(rng.uniform(np.log(0.01), np.log(0.4))))
    near_y = c[1] + side * (radius + g2) if glass_side else c[1] + side * (radius + rng.uniform(0.3, 2.5))
    far_y = eye[1] - side * rng.uniform(1.0, 3.0)
    lo = np.array([eye[0] - rng.uniform(0.5, 1.5), min(near_y, far_y), floor_z])
    hi = np.array([max(c[0] + radius + 0.3, eye[0] + 2.5) + rng.uniform(0.0, 4.0), max(near_y, far_y), surface_z])
    return lo, hi, surface_z, glass_side


def _holder(rng, holder, c, radius, floor_z, surface_z) -> list:
    if holder == "rope":
        rope = world.chain(rng, np.asarray(c) + [0, 0, radius * 0.95], surface_z, float(rng.uniform(0.003, 0.008)),
                           tag="stand", links=False)
        return [rope] if rope is not None else []
    if holder == "pole" and surface_z - c[2] > radius + 0.02:
        return [Cylinder(tuple(np.asarray(c) + [0, 0, radius * 0.9]), (c[0], c[1], surface_z - 1e-3),
                         float(rng.uniform(0.006, 0.015)), Material(tuple(rng.uniform(0.05, 0.5, 3)), 0.5), tag="stand")]
    if holder == "tether" and c[2] - radius - floor_z > 0.05:
        return [Cylinder(tuple(np.asarray(c) - [0, 0, radius * 0.95]), (c[0], c[1], floor_z + 1e-3),
                         float(rng.uniform(0.003, 0.008)), world.ROPE, tag="stand")]
    return []


def pool_water(rng):
    c_g = float(rng.uniform(0.03, 0.12))
    tint = np.array([0.06, 0.32, 0.45]) * rng.uniform(0.6, 1.2)
    return Water(c_g, tuple(tint), up_gain=float(rng.uniform(0.3, 0.9)), side_dir=(1.0, 0, 0), side_gain=0.0,
                 light_rgb=(0.95, 1.0, 1.0), ambient=float(rng.uniform(0.3, 0.5)), diffuse=float(rng.uniform(0.5, 0.9)),
                 attenuation_rgb=(c_g + float(rng.uniform(0.2, 0.45)), c_g, c_g * float(rng.uniform(0.8, 1.4))))


def _mirrors(rng, lo, hi, surface_z, glass_side) -> list:
    sky = np.array([0.65, 0.8, 1.0]) * rng.uniform(1.0, 2.0)
    out = [Mirror("surface", (0, 0, surface_z), (0, 0, -1.0), tuple(sky), float(rng.uniform(0.0, 0.02)),
                  float(rng.uniform(0.3, 1.0)), int(rng.integers(1 << 30)))]
    if glass_side:
        y = hi[1] if glass_side > 0 else lo[1]
        lab = tuple(np.full(3, rng.uniform(0.01, 0.12)))
        out.append(Mirror("glass", (0, y, 0), (0, -float(glass_side), 0), lab))
    return out


def tank(rng, rig, cam, T_wc, scale, with_ball, opts):
    T_wc = hp.pose_ahead(rng, T_wc, (-5, 35))
    radius = float(rng.uniform(0.05, 0.2))
    holder = str(rng.choice(["rope", "pole", "tether", "floor"]))
    try:
        c = _place(rng, cam, T_wc, radius, scale, holder)
    except RuntimeError:  # the floor below the camera is out of view (looking up): held on a rope instead
        holder = "rope"
        c = _place(rng, cam, T_wc, radius, scale, holder)
    eye = hp.eye_of(T_wc)
    lo, hi, surface_z, glass_side = _tank_geometry(rng, eye, c, radius, holder)
    water = pool_water(rng)
    alb = np.array(FLOATS[int(rng.integers(len(FLOATS)))]) * rng.uniform(0.85, 1.05)
    ball = Sphere(tuple(c), radius, Material(tuple(np.clip(alb, 0, 1)), 0.9, "foam", 0.02,
                                             float(rng.uniform(0.0, 0.08)), int(rng.integers(1 << 30))), tag="target")
    parts = [ball] + _holder(rng, holder, c, radius, lo[2], surface_z)
    surface = Rect((0, 0, surface_z), (0, 0, -1), tag="surface")
    static = tank_box(lo, hi, rng, glass_side) + [surface]
    look = BallLook(tuple(c), radius, ks=float(rng.uniform(0.0, 0.6)), shininess=float(rng.uniform(20, 100)))
    tilt = rng.normal(0, 0.2, 2)
    photo = replace(draw_photo(rng, c, radius, eye, look, scale), key_dir=(tilt[0], tilt[1], 1.0),
                    softness=float(rng.uniform(0.01, 0.05)), vignette=float(rng.uniform(0.1, 0.4)), bloom_px=0.0)
    if rng.random() < 0.6:
        photo = replace(photo, caustic=float(rng.uniform(0.3, 1.0)), caustic_scale_m=float(rng.uniform(0.15, 0.5)),
                        caustic_seed=int(rng.integers(1 << 30)))
    mirrors = _mirrors(rng, lo, hi, surface_z, glass_side)
    photo, opts = hp.camera_artefacts(rng, photo, opts, scale)
    photo = photo if with_ball else replace(photo, occluders=())
    scene = Scene(tuple(static + (parts if with_ball else [])))
    L, hit = render_radiance(scene, cam, T_wc, water, aa=3, photo=photo)
    for m in mirrors:
        L = composite_mirror(L, hit, scene, m, cam, T_wc, water, photo)
    photo = metered(rng, photo, L)
    label = f"tank/{holder}/{'glass' if glass_side else 'tiles'}/{hp.artefact_label(photo, opts)}"
    return L, c, radius, photo, opts, label, T_wc
