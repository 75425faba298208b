"""Scenes of the photographic image cases (glossy gym ball, beach ball, carried ball with
motion blur), rendered with the effects of :mod:`calib_core.synth.photo.effects`.

- "glossy": a gym ball (grey most often; also dark, white or coloured; sometimes a seam, a
  printed logo, a valve), glossy (Blinn-Phong highlight clipped at 255 with a bloom), resting on
  a chair or on the tiled floor, with its cast and contact shadows, under a key light from the
  camera's side and above; vignetting, metered exposure and a white-balance shift (real set A);
- "panels": an inflatable beach ball (6-8 gores of two to four colours, white caps, a valve,
  mildly glossy) on a stick, on a block or on the floor;
- "motion": a matte foam ball (sometimes a logo or seam) carried on a stick, blurred by its
  motion during the exposure (real set B).

Each function returns the linear radiance (ball or not), the ball centre and radius, the
:class:`~calib_core.synth.photo.effects.Photo` for the finishing step, and a label. ``with_ball``
False renders the same scene (same random draws) without the ball, its holder and its shadow.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from calib_core.synth import room
from calib_core.synth.range import scenes as range_scenes
from calib_core.synth.camera_render import render_radiance
from calib_core.synth.occlusion import occluded_fraction
from calib_core.synth.photo.effects import BallLook, Photo, motion_composite
from calib_core.synth.rig import sample_target_center
from calib_core.synth.scene import Scene

PANEL_COLOURS = ((0.85, 0.12, 0.10), (0.95, 0.80, 0.10), (0.10, 0.30, 0.80), (0.15, 0.60, 0.20),
                 (0.95, 0.50, 0.08), (0.92, 0.92, 0.90))


def rand_dir(rng) -> tuple:
    v = rng.normal(0, 1, 3)
    return tuple(v / np.linalg.norm(v))


def key_dir(rng, centre, eye) -> tuple:
    """A key light from the camera's side of the ball and above (highlight visible)."""
    view = np.asarray(centre, float) - np.asarray(eye, float)
    view /= np.linalg.norm(view)
    side = np.cross(view, [0, 0, 1.0])
    side /= max(np.linalg.norm(side), 1e-9)
    k = -view * rng.uniform(0.3, 1.0) + np.array([0, 0, rng.uniform(0.6, 1.5)]) + side * rng.uniform(-1, 1)
    return tuple(k / np.linalg.norm(k))


def draw_photo(rng, centre, radius, eye, look: BallLook, scale: float) -> Photo:
    """Lighting and camera effects drawn for one image (exposure metered later)."""
    wb = (1.0 + rng.uniform(-0.12, 0.12), 1.0, 1.0 + rng.uniform(-0.12, 0.12))
    return Photo(key_dir=key_dir(rng, centre, eye), softness=float(rng.uniform(0.02, 0.12)),
                 occluders=((tuple(centre), radius),), ao=float(rng.uniform(0.7, 1.0)), ball=look,
                 vignette=float(rng.uniform(0.1, 0.5)), wb_gains=tuple(float(g) for g in wb),
                 bloom_px=float(rng.uniform(2.0, 6.0)) * scale, bloom_gain=float(rng.uniform(0.3, 0.8)))


def metered(rng, photo: Photo, L: np.ndarray) -> Photo:
    """Auto-exposure: scale so the frame's mean radiance lands at 0.35-0.55 (of white)."""
    target = float(rng.uniform(0.35, 0.55))
    return replace(photo, exposure=float(np.clip(target / max(float(L.mean()), 1e-3), 0.4, 3.0)))


def clear_view(static: list, ball, T_wc) -> list:
    """The static parts minus clutter that would hide part of the ball (the case shows it whole,
    apart from its own holder)."""
    return [p for p in static if p.tag != "clutter"
            or occluded_fraction(Scene((ball, p)), 0, T_wc, ball.center_m, ball.radius_m) == 0]


def render_parts(rng, parts_static, parts_ball, with_ball, cam, T_wc, air, photo, aa):
    photo = photo if with_ball else replace(photo, occluders=())
    scene = Scene(tuple(parts_static + (parts_ball if with_ball else [])))
    L, hit = render_radiance(scene, cam, T_wc, air, aa=aa, photo=photo)
    return L, hit, scene, metered(rng, photo, L)


def gym_look(rng, c, radius) -> tuple[tuple, BallLook]:
    r = rng.random()
    if r < 0.5:
        alb = np.full(3, rng.uniform(0.35, 0.65))
    elif r < 0.65:
        alb = np.full(3, rng.uniform(0.06, 0.14))
    elif r < 0.75:
        alb = np.full(3, rng.uniform(0.8, 0.9))
    else:
        alb = np.array(room.BALL_COLOURS[int(rng.integers(len(room.BALL_COLOURS)))]) * rng.uniform(0.8, 1.0)
    look = BallLook(tuple(c), radius, ks=float(rng.uniform(0.3, 1.0)), shininess=float(rng.uniform(15, 150)),
                    seam_dir=rand_dir(rng) if rng.random() < 0.5 else None,
                    seam_width_m=float(rng.uniform(0.002, 0.006)),
                    logo_dir=rand_dir(rng) if rng.random() < 0.5 else None, logo_deg=float(rng.uniform(10, 25)),
                    valve_dir=rand_dir(rng) if rng.random() < 0.3 else None)
    return tuple(float(a) for a in np.clip(alb, 0, 1)), look


def glossy(rng, rig, cam, T_wc, scale, with_ball):
    radius = float(rng.uniform(0.2, 0.33))
    eye = T_wc[:3, 3]
    on_chair = rng.random() < 0.5
    c, _ = sample_target_center(rng, rig, radius, "cam1", rng.random() < 0.2,
                                lambda c: c[2] - radius < eye[2] - 0.3, dist_range=(1.3, 4.5))
    floor_z = float(c[2] - radius - (rng.uniform(0.4, 0.5) if on_chair else 0.0))
    static = room.room_scene(rng, floor_z, [c])
    alb, look = gym_look(rng, c, radius)
    style = dict(room.ball_style(rng), albedo=alb, foam_contrast=float(rng.uniform(0.0, 0.05)), holder="stick")
    ball = room.ball_parts(rng, style, c, radius, floor_z, eye)[0]
    static = clear_view(static, ball, T_wc)
    parts = [ball] + ([range_scenes.chair(rng, c, radius, floor_z, eye)] if on_chair else [])
    air = room.room_air(rng)
    photo = draw_photo(rng, c, radius, eye, look, scale)
    L, _, _, photo = render_parts(rng, static, parts, with_ball, cam, T_wc, air, photo, 3)
    return L, c, radius, photo, f"glossy/{'chair' if on_chair else 'floor'}"


def _panel_look(rng, c, radius) -> BallLook:
    n_col = int(rng.integers(2, 5))
    idx = rng.choice(len(PANEL_COLOURS), n_col, replace=False)
    cols = tuple(tuple(float(x) for x in PANEL_COLOURS[i]) for i in idx)
    axis = rand_dir(rng)
    a = np.asarray(axis)
    e = np.cross(a, rand_dir(rng))
    valve = tuple(e / np.linalg.norm(e) * 0.9 + a * 0.44)
    return BallLook(tuple(c), radius, ks=float(rng.uniform(0.1, 0.6)), shininess=float(rng.uniform(20, 100)),
                    axis=axis, panels=int(rng.choice([6, 6, 8, 4])), panel_rgb=cols,
                    cap_deg=float(rng.uniform(8, 20)), valve_dir=valve, valve_deg=float(rng.uniform(2, 4)))


def panels(rng, rig, cam, T_wc, scale, with_ball):
    radius = float(rng.uniform(0.12, 0.3))
    eye = T_wc[:3, 3]
    where = str(rng.choice(["stick", "rest", "floor"]))
    c, _ = sample_target_center(rng, rig, radius, "cam1", rng.random() < 0.25,
                                lambda c: c[2] - radius < eye[2] - 0.2, dist_range=(1.0, 4.0))
    floor_z = float(c[2] - radius - (0.0 if where == "floor" else rng.uniform(0.4, 1.0)))
    static = room.room_scene(rng, floor_z, [c])
    look = _panel_look(rng, c, radius)
    style = dict(room.ball_style(rng), albedo=(1.0, 1.0, 1.0), foam_contrast=0.0,
                 holder="rest" if where == "rest" else "stick")
    parts = room.ball_parts(rng, style, c, radius, floor_z, eye)
    parts = parts[:1] if where == "floor" else parts
    static = clear_view(static, parts[0], T_wc)
    air = room.room_air(rng)
    photo = draw_photo(rng, c, radius, eye, look, scale)
    L, _, _, photo = render_parts(rng, static, parts, with_ball, cam, T_wc, air, photo, 3)
    return L, c, radius, photo, f"panels/{where}"


def motion(rng, rig, cam, T_wc, scale, with_ball):
    radius = float(rng.uniform(0.1, 0.3))
    eye = T_wc[:3, 3]
    floor_z = float(min(eye[2], 0.0) - rng.uniform(0.6, 1.3))
    c, _ = sample_target_center(rng, rig, radius, "cam1", rng.random() < 0.3,
                                lambda c: c[2] - radius > floor_z + 0.3, dist_range=(1.0, 4.0))
    static = room.room_scene(rng, floor_z, [c])
    style = dict(room.ball_style(rng), holder="stick")
    parts = room.ball_parts(rng, style, c, radius, floor_z, eye)
    static = clear_view(static, parts[0], T_wc)
    look = BallLook(tuple(c), radius, ks=float(rng.uniform(0.0, 0.15)), shininess=20.0,
                    seam_dir=rand_dir(rng) if rng.random() < 0.3 else None,
                    logo_dir=rand_dir(rng) if rng.random() < 0.4 else None, logo_deg=float(rng.uniform(12, 25)))
    ang = rng.uniform(0, 2 * np.pi)
    blur = float(rng.uniform(4.0, 30.0)) * scale
    motion_px = (blur * np.cos(ang), blur * np.sin(ang))
    air = room.room_air(rng)
    photo = draw_photo(rng, c, radius, eye, look, scale)
    L, hit, scene, photo = render_parts(rng, static, parts, with_ball, cam, T_wc, air, photo, 3)
    if with_ball:
        L0, _ = render_radiance(Scene(tuple(static)), cam, T_wc, air, aa=3, photo=replace(photo, occluders=()))
        moving = np.isin(hit, scene.ids_with_tag("target", "stand"))
        L = motion_composite(L, L0, moving, motion_px)
    return L, c, radius, photo, f"motion/{np.hypot(*motion_px):.0f}px"
