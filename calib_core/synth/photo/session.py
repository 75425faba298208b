"""Photographic looks of the session presets "gym", "carried-photo" and "underwater" (``Preset.photo``;
the underwater look's water, lights and snow: :mod:`calib_core.synth.photo.water_session`).

The session generator renders these presets with :mod:`calib_core.synth.photo.effects` switched on:

- per session (:func:`session_look`, stream ``[seed, 7919, 4242]``): the ball's surface (a
  glossy gym ball of varying shade with a seam / logo / valve as the "glossy" image case
  draws it, or a matte foam ball, yellow most often, with a seam and/or a logo) and the room's
  textures (tiled floor, brick wall) in place of the plain lab floor and wall, and indoor air
  (the lab presets' images otherwise see through a water veil);
- per capture (:func:`capture_light`, stream ``[seed, 7919, 5000 + k]``): the key light from
  the first camera's side and above, the ball's cast and contact shadows, and for "carried"
  a motion blur of the ball and the hands on some captures (2-24 px at 1920x1080, scaled);
- per camera image (:func:`render_capture`): vignetting, white balance, bloom and metered
  auto-exposure (the camera's own, so two cameras differ).

The range sensor sees the undressed scene (materials do not change its geometry). The truth
centre of a blurred ball is its mid-exposure position (the blur kernel is centred on it).
The streams are separate from the generator's, so the other presets are untouched.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from calib_core.synth import room
from calib_core.synth.camera_render import render_radiance
from calib_core.synth.photo import water_session
from calib_core.synth.photo.effects import BallLook, Photo, motion_composite
from calib_core.synth.photo.cases import draw_photo, gym_look, key_dir, metered, rand_dir
from calib_core.synth.scene import Material, Scene, Sphere

KINDS = ("gym", "carried", "underwater")
MOTION_SHARE = 0.4  # share of "carried" captures with motion blur
MOTION_PX_1080P = (2.0, 24.0)  # blur length range at scale 1
MOVING_TAGS = ("target", "hand")  # what moves with a carried ball


@dataclass(frozen=True)
class SessionLook:
    """The ball's surface and the room's textures of one session."""

    kind: str
    ball_material: Material
    ball: BallLook  # markings and gloss (centre set per capture)
    floor: Material
    wall: Material
    air: object  # camera_render.Water: indoor air and light (no water veil); underwater: the water
    seabed: Material | None = None  # the seabed's look (underwater)
    dive: object = None  # water_session.DiveLight (underwater)


@dataclass(frozen=True)
class CaptureLight:
    """The light of one capture (camera effects are drawn per image) and its motion blur."""

    photo: Photo
    motion_px: tuple | None  # (dx, dy) px of the ball during the exposure, None = still
    snow: float = 0.0  # marine snow particles per 960x540 image (underwater)


def session_look(kind: str, seed: int, radius_m: float) -> SessionLook:
    """The ball and room of a session of look ``kind`` ("gym" or "carried")."""
    if kind not in KINDS:
        raise ValueError(f"unknown photo look {kind!r}; use one of {KINDS}")
    rng = np.random.default_rng([int(seed), 7919, 4242])
    if kind == "underwater":
        mat, ball, seabed, wall, water, dive = water_session.session_parts(rng, radius_m)
        return SessionLook(kind, mat, ball, seabed, wall, water, seabed, dive)
    if kind == "gym":
        alb, ball = gym_look(rng, (0.0, 0.0, 0.0), radius_m)
        mat = Material(alb, 0.9, "foam", float(rng.uniform(0.02, 0.06)), float(rng.uniform(0.0, 0.05)),
                       int(rng.integers(1 << 30)))
    else:
        alb = np.clip(np.array(room.BALL_COLOURS[0]) * rng.uniform(0.85, 1.1), 0, 1)
        mat = Material(tuple(float(a) for a in alb), 0.9, "foam", float(rng.uniform(0.02, 0.08)),
                       float(rng.uniform(0.05, 0.25)), int(rng.integers(1 << 30)))
        ball = BallLook((0.0, 0.0, 0.0), radius_m, ks=float(rng.uniform(0.0, 0.15)), shininess=20.0,
                        seam_dir=rand_dir(rng) if rng.random() < 0.6 else None,
                        logo_dir=rand_dir(rng) if rng.random() < 0.7 else None, logo_deg=float(rng.uniform(12, 25)))
    return SessionLook(kind, mat, ball, _floor(rng), _brick(rng), room.room_air(rng))


def _floor(rng) -> Material:
    return Material(tuple(float(a) for a in rng.uniform(0.3, 0.7, 3)), 0.6, "tiles", float(rng.uniform(0.2, 0.5)),
                    float(rng.uniform(0.3, 0.8)), int(rng.integers(1 << 30)))


def _brick(rng) -> Material:
    brick = np.array([0.62, 0.33, 0.25]) * rng.uniform(0.7, 1.2)
    return Material(tuple(float(a) for a in np.clip(brick, 0, 1)), 0.7, "brick", float(rng.uniform(0.06, 0.09)),
                    float(rng.uniform(0.4, 0.9)), int(rng.integers(1 << 30)))


def dress(scene: Scene, look: SessionLook) -> Scene:
    """The scene as photographed: the ball's and the room's materials replaced."""
    new = {"floor": look.floor, "wall": look.wall}
    if look.seabed is not None:
        new["seabed"] = look.seabed
    prims = []
    for p in scene.primitives:
        if p.tag == "target" and isinstance(p, Sphere):
            p = replace(p, material=look.ball_material)
        elif p.tag in new:
            p = replace(p, material=new[p.tag])
        prims.append(p)
    return Scene(tuple(prims))


def capture_light(look: SessionLook, seed: int, k: int, centre, radius_m: float, eye, scale: float) -> CaptureLight:
    """Capture ``k``'s key light, shadows and (carried ball) motion blur."""
    rng = np.random.default_rng([int(seed), 7919, 5000 + int(k)])
    if look.dive is not None:
        photo, snow = water_session.capture_photo(rng, look.dive, look.ball, centre, radius_m, eye)
        return CaptureLight(photo, None, snow)
    c = tuple(float(x) for x in centre)
    ball = replace(look.ball, centre_m=c, radius_m=float(radius_m))
    photo = Photo(key_dir=key_dir(rng, c, eye), softness=float(rng.uniform(0.02, 0.12)),
                  occluders=((c, float(radius_m)),), ao=float(rng.uniform(0.7, 1.0)), ball=ball)
    motion = None
    if look.kind == "carried" and rng.random() < MOTION_SHARE:
        ang = rng.uniform(0, 2 * np.pi)
        blur = float(rng.uniform(*MOTION_PX_1080P)) * scale
        motion = (float(blur * np.cos(ang)), float(blur * np.sin(ang)))
    return CaptureLight(photo, motion)


def render_capture(scene: Scene, cam, T_wc, water, aa: int, light: CaptureLight, rng, scale: float):
    """(linear radiance, metered Photo for finish_image) of one camera's image of a dressed scene;
    ``rng`` draws the camera's own effects (vignetting, white balance, bloom, exposure)."""
    cam_fx = draw_photo(rng, light.photo.occluders[0][0], light.photo.occluders[0][1], T_wc[:3, 3],
                        light.photo.ball, scale)
    photo = replace(light.photo, vignette=cam_fx.vignette, wb_gains=cam_fx.wb_gains, bloom_px=cam_fx.bloom_px,
                    bloom_gain=cam_fx.bloom_gain)
    water = water_session.water_for(water, photo)  # (underwater: the dive light's glow along its axis)
    L, hit = render_radiance(scene, cam, T_wc, water, aa=aa, photo=photo)
    L = water_session.add_snow(L, rng, light.snow, scale)
    if light.motion_px is not None:
        L0, _ = render_radiance(scene.without(*MOVING_TAGS), cam, T_wc, water, aa=aa,
                                photo=replace(photo, occluders=()))
        L = motion_composite(L, L0, np.isin(hit, scene.ids_with_tag(*MOVING_TAGS)), light.motion_px)
    return L, metered(rng, photo, L)


def background_photo(photo: Photo) -> Photo:
    """A capture's camera effects for a ball-free background frame (no ball, no shadow)."""
    return replace(photo, occluders=())
