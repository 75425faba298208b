"""Held-out image kind "dim": a ball photographed in low light, underexposed, at high gain.

- The scene: the textured room of :mod:`calib_core.synth.room` with almost no ambient light
  (0.5-4 % of the "clutter" kind's) and no key light, lit by one lamp: a point source with a
  cos^k beam (k 3-40) and inverse-square fall-off (the dive-light model of
  :mod:`calib_core.synth.photo.water` in clear air). The lamp casts no shadow in this model.
- Two looks, half each: a lit ball on a black background (the room's surfaces at 3-15 % of
  their albedo, black cloth; the lamp 0.3-1.5 m beside or above the camera aimed at the ball)
  or a dark ball (albedo 0.02-0.1) against a faintly lit wall (the lamp aimed at the wall
  behind the ball from near the wall, 1-2.5 m to one side: a wall washer; the ball, farther
  from it, gets less of its light). The ball is matte (the lamp makes no highlight here).
- Exposure: set so that the ball's mean differs from that of a ring around it (0.3-0.8 radii
  outside its outline) by 10-40 DN (drawn; the sign is whatever the scene gives), but no
  brighter than a ring and frame mean of 25-70 DN (then the contrast is what is left), so the
  whole frame lies in the low tens of DN.
- Sensor: high gain on every image (read noise 3-8 DN, shot-noise scale 0.5-2.5), row
  banding (a random offset per row, 0.3-1.5 DN rms), and JPEG at quality 40-85 on 60 %
  (blocking and posterised gradients in the dark); defocus or shake on a share as in the
  other held-out kinds.

No constant here was taken from a real image. ``with_ball`` False renders the same scene at
the same exposure without the ball and its holder.
"""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np

from calib_core.synth import room
from calib_core.synth.camera_render import Water, render_radiance
from calib_core.synth.photo import heldout_parts as hp
from calib_core.synth.photo.cases import clear_view, draw_photo
from calib_core.synth.photo.effects import BallLook
from calib_core.synth.scene import Material, Scene


def _darken(static: list, factor_rng) -> list:
    """Every static surface at 3-15 % of its albedo (black cloth, unlit walls)."""
    return [replace(p, material=replace(p.material, albedo=tuple(np.asarray(p.material.albedo) * factor_rng.uniform(0.03, 0.15))))
            for p in static]


def _lamp(rng, c, radius, eye, black_bg: bool, far_x: float):
    """(position, unit axis, power) of the lamp."""
    side = np.cross(np.asarray(c) - eye, [0, 0, 1.0])
    side /= max(np.linalg.norm(side), 1e-9)
    if black_bg:
        pos = eye + side * rng.uniform(-1.5, 1.5) + np.array([0, 0, rng.uniform(0.0, 1.0)])
        aim = np.asarray(c, float)
    else:  # a wall washer: near the wall, off to one side, aimed at the wall behind the ball
        aim = np.array([far_x, c[1] + rng.uniform(-0.5, 0.5), c[2] + rng.uniform(-0.3, 0.5)])
        pos = aim + np.array([-rng.uniform(0.4, 1.2), rng.choice([-1, 1]) * rng.uniform(1.0, 2.5), rng.uniform(0.3, 1.5)])
    axis = aim - pos
    return pos, axis / np.linalg.norm(axis), float(rng.uniform(3, 40))


def _contrast_exposure(rng, L, hit, ball_ids) -> float:
    """Exposure putting the ball's mean 10-40 DN away from a ring 0.3-0.8 radii outside it, but
    the ring's and the frame's means no higher than 25-70 DN (a dark frame stays dark)."""
    m = np.isin(hit, ball_ids).astype(np.uint8)
    if m.sum() < 10:
        return 1.0
    r = np.sqrt(m.sum() / np.pi)
    k = lambda s: cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * int(s) + 1, 2 * int(s) + 1))  # noqa: E731
    ring = (cv2.dilate(m, k(max(2, 0.8 * r))) > 0) & ~(cv2.dilate(m, k(max(1, 0.3 * r))) > 0)
    inner = cv2.erode(m, k(max(1, 0.1 * r))) > 0
    lum = L.mean(axis=2)
    diff = abs(float(lum[inner if inner.any() else m > 0].mean()) - float(lum[ring].mean())) if ring.any() else 0.0
    target = float(rng.uniform(10.0, 40.0))
    level = max(float(lum[ring].mean()) if ring.any() else 0.0, float(lum.mean()), 1e-6)
    cap = float(rng.uniform(25.0, 70.0)) / (255.0 * level)
    return float(np.clip(min(target / max(255.0 * diff, 1e-6), cap), 0.05, 400.0))


def _banding(rng, L, exposure: float) -> np.ndarray:
    rows = rng.normal(0, rng.uniform(0.3, 1.5), L.shape[0]) / (255.0 * exposure)
    return np.clip(L + rows[:, None, None], 0, None)


def _sensor(rng, photo, opts, scale):
    photo, opts = hp.camera_artefacts(rng, photo, opts, scale)
    opts = replace(opts, noise_dn=float(rng.uniform(3.0, 8.0)), shot_gain=float(rng.uniform(0.5, 2.5)))
    q = int(rng.integers(40, 86)) if rng.random() < 0.6 else 0
    return replace(photo, jpeg_quality=q), opts


def dim(rng, rig, cam, T_wc, scale, with_ball, opts):
    radius = float(rng.uniform(0.08, 0.3))
    black_bg = rng.random() < 0.5
    eye = hp.eye_of(T_wc)
    c = hp.place_by_size(rng, cam, T_wc, radius, (30.0 * scale, 0.5 * cam.height_px), lambda c: c[0] + radius < 4.3 and abs(c[1]) + radius < 2.8)
    floor_z = float(min(eye[2] - 0.3, c[2] - radius) - rng.uniform(0.0, 1.2))
    static = room.room_scene(rng, floor_z, [c])
    static = _darken(static, rng) if black_bg else static
    style = room.ball_style(rng)
    if not black_bg:
        style["albedo"] = tuple(np.full(3, rng.uniform(0.02, 0.1)) * rng.uniform(0.8, 1.2, 3))
    parts = room.ball_parts(rng, style, c, radius, floor_z, eye)
    static = clear_view(static, parts[0], T_wc)
    far_x = max(p.center_m[0] for p in static if p.tag == "wall")
    pos, axis, power = _lamp(rng, c, radius, eye, black_bg, far_x)
    air = Water(0.0, tuple(np.full(3, rng.uniform(0.001, 0.01))), up_gain=0.0, side_gain=0.0,
                ambient=float(rng.uniform(0.005, 0.04)) * 0.55, diffuse=0.0)
    photo = replace(draw_photo(rng, c, radius, eye, BallLook(tuple(c), radius), scale),
                    spot_gain=float(rng.uniform(1.0, 4.0)), spot_pos=tuple(pos), spot_dir=tuple(axis), spot_power=power,
                    bloom_px=0.0, vignette=float(rng.uniform(0.1, 0.5)))
    photo, opts = _sensor(rng, photo, opts, scale)
    scene = Scene(tuple(static + parts))
    L, hit = render_radiance(scene, cam, T_wc, air, aa=3, photo=photo)
    exposure = _contrast_exposure(rng, L, hit, scene.ids_with_tag("target"))
    if not with_ball:
        L, _ = render_radiance(Scene(tuple(static)), cam, T_wc, air, aa=3, photo=replace(photo, occluders=()))
    photo = replace(photo, exposure=exposure)
    L = _banding(rng, L, exposure)
    look = "lit-on-black" if black_bg else "dark-on-wall"
    return L, c, radius, photo, opts, f"dim/{look}/{hp.artefact_label(photo, opts)}"
