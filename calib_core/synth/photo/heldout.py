"""Held-out image kinds, built to measure the detector on what it was not developed against
(issue 11: "other balls, backgrounds, rigs and range sensors"):

- "sports": a patterned sports ball indoors (the room of :mod:`calib_core.synth.room`): a
  football (black pentagons on white), a basketball (orange, dark seams), a tennis ball
  (yellow-green felt with a white seam and a fuzzy sheen), a volleyball (three-colour panels)
  (patterns: :mod:`calib_core.synth.photo.ball_patterns`); at its real size, resting on the floor,
  on a stick or held in a hand (:func:`~calib_core.synth.photo.heldout_parts.hand_blob`), seen at
  15 px radius (at 960x540) to half the frame height; the photographic light of the glossy
  kind (key light, cast and contact shadows, mild gloss).
- "outdoor": hard sun (a key light of small angular size: sharp cast and contact shadows), a
  bright sky (the miss radiance: blue to white, lighter towards the horizon and the sun), a
  grass, gravel or asphalt ground, sometimes a hedge or wall far behind and a few blocks
  (benches, bins); a ball of any shade (white, black, coloured: brighter or darker than the
  ground), often glossy; on the ground, on a stick or in a hand; a share placed above the
  horizon, against the sky (a white ball against a white-ish sky among them).
- "underwater": the product's own domain: per-channel attenuation (red strongest; blue
  ocean or green coastal water) and backscatter veil, so colour and contrast fall with
  range; sunlight from above with caustics on a share; a dive light's hot spot on a share;
  marine snow on a share; an orange, white, yellow or dark float on a rope from the surface,
  tethered from below, resting on a sand or rock seabed or held by a diver's hand; the
  seabed or open water behind (:mod:`calib_core.synth.photo.water`).

Each also gets camera artefacts on a share of the images (JPEG, high gain, defocus or shake:
:func:`~calib_core.synth.photo.heldout_parts.camera_artefacts`). Every function returns the linear
radiance, the ball's centre and radius, the :class:`~calib_core.synth.photo.effects.Photo`, the
render options and a label. ``with_ball`` False renders the same scene (same random draws)
without the ball, its holder and its shadow. No constant here was taken from a real image.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from calib_core.synth import room, world
from calib_core.synth.camera_render import Water
from calib_core.synth.photo import heldout_parts as hp
from calib_core.synth.photo.ball_patterns import PATTERNS
from calib_core.synth.photo.cases import clear_view, render_parts, draw_photo, rand_dir
from calib_core.synth.photo.effects import BallLook
from calib_core.synth.photo.water import marine_snow
from calib_core.synth.scene import Box, Cylinder, Material, Rect, Sphere

# (radius m, base albedo, foam texture scale m and contrast, gloss ks range)
SPORTS = {"football": (0.110, (0.92, 0.92, 0.90), 0.05, 0.02, (0.2, 0.7)),
          "basketball": (0.120, (0.80, 0.34, 0.10), 0.004, 0.25, (0.05, 0.25)),
          "tennis": (0.0335, (0.78, 0.88, 0.22), 0.002, 0.35, (0.0, 0.0)),
          "volleyball": (0.105, (0.92, 0.92, 0.90), 0.05, 0.03, (0.1, 0.5))}


def _r_px(cam, scale: float) -> tuple:
    return (30.0 * scale, 0.5 * cam.height_px)


def _holder(rng, kind: str, ball, c, radius_m, floor_z, T_wc) -> list:
    """The holder's parts: none (resting), a stick, or a hand."""
    eye = hp.eye_of(T_wc)
    if kind == "stick":
        return room.ball_parts(rng, dict(room.ball_style(rng), holder="stick"), c, radius_m, floor_z, eye)[1:]
    if kind == "hand":
        return [hp.hand_blob(rng, c, radius_m, eye, T_wc, ball)]
    return []


def _sports_look(rng, name: str, c, radius_m: float) -> BallLook:
    ks = SPORTS[name][4]
    cols = ()
    if name == "volleyball":
        pal = ((0.92, 0.92, 0.90), (0.10, 0.25, 0.70), (0.95, 0.80, 0.15), (0.80, 0.15, 0.12), (0.15, 0.55, 0.25))
        idx = [0] + list(rng.choice(np.arange(1, len(pal)), 2, replace=False))
        cols = tuple(pal[i] for i in idx)
    return BallLook(tuple(c), radius_m, ks=float(rng.uniform(*ks)), shininess=float(rng.uniform(15, 60)),
                    axis=rand_dir(rng), pattern=name, pattern_w=float(rng.uniform(0.008, 0.02)),
                    pattern_rgb=cols, sheen=float(rng.uniform(0.6, 1.2)) if name == "tennis" else 0.0)


def sports(rng, rig, cam, T_wc, scale, with_ball, opts):
    name = str(rng.choice(PATTERNS))
    radius, alb, tex_scale, tex_contrast, _ = SPORTS[name]
    holder = str(rng.choice(["floor", "stick", "hand"]))
    eye = hp.eye_of(T_wc)
    lift = float(rng.uniform(0.3, 1.2))

    def ok(c):
        return c[0] < 4.2 and (holder != "floor" or c[2] - radius < eye[2] - 0.25)
    c = hp.place_by_size(rng, cam, T_wc, radius, _r_px(cam, scale), ok)
    floor_z = float(c[2] - radius if holder == "floor" else min(eye[2] - 0.3, c[2] - radius) - lift)
    static = room.room_scene(rng, floor_z, [c])
    ball = Sphere(tuple(c), radius, Material(alb, 0.9, "foam", tex_scale, tex_contrast, int(rng.integers(1 << 30))),
                  tag="target")
    parts = [ball] + _holder(rng, holder, ball, c, radius, floor_z, T_wc)
    static = clear_view(static, ball, T_wc)
    photo = draw_photo(rng, c, radius, eye, _sports_look(rng, name, c, radius), scale)
    photo, opts = hp.camera_artefacts(rng, photo, opts, scale)
    L, _, _, photo = render_parts(rng, static, parts, with_ball, cam, T_wc, room.room_air(rng), photo, 3)
    return L, c, radius, photo, opts, f"sports/{name}/{holder}/{hp.artefact_label(photo, opts)}"


GROUNDS = {"grass": ((0.20, 0.36, 0.09), 0.05, (0.5, 0.9)), "gravel": ((0.55, 0.52, 0.47), 0.04, (0.4, 0.8)),
           "asphalt": ((0.17, 0.17, 0.18), 0.06, (0.5, 1.0))}
OUTDOOR_BALLS = ((0.90, 0.90, 0.88), (0.06, 0.06, 0.07), (0.88, 0.75, 0.10), (0.90, 0.42, 0.08),
                 (0.75, 0.15, 0.12), (0.50, 0.50, 0.50), (0.45, 0.65, 0.85))


def _outdoor_static(rng, floor_z: float, keep_clear) -> tuple[list, str]:
    gname = str(rng.choice(list(GROUNDS)))
    alb, tscale, contrast = GROUNDS[gname]
    ground = Rect((0, 0, floor_z), (0, 0, 1), material=Material(tuple(np.array(alb) * rng.uniform(0.8, 1.2)), 0.5,
                                                                gname, tscale, float(rng.uniform(*contrast)),
                                                                int(rng.integers(1 << 30))), tag="floor")
    prims = [ground]
    if rng.random() < 0.5:  # a hedge or a wall far behind
        far, h = float(rng.uniform(8.0, 20.0)), float(rng.uniform(1.0, 3.0))
        col = (0.12, 0.25, 0.08) if rng.random() < 0.5 else tuple(rng.uniform(0.3, 0.8, 3))
        prims.append(Rect((far, 0, floor_z + h / 2), (-1, 0, 0), (30.0, h / 2), u=(0, 1, 0),
                          material=Material(col, 0.5, "noise", float(rng.uniform(0.05, 0.3)), 0.6,
                                            int(rng.integers(1 << 30))), tag="wall"))
    for _ in range(int(rng.integers(0, 5))):
        size = rng.uniform(0.2, 0.9, 3)
        p = np.array([rng.uniform(1.5, 10.0), rng.uniform(-5, 5), floor_z + size[2] / 2])
        if min(np.linalg.norm((p - k)[:2]) for k in keep_clear) < 0.6 + size[:2].max():
            continue
        prims.append(Box(tuple(p), tuple(size / 2), material=Material(tuple(rng.uniform(0.05, 0.8, 3)), 0.5, "noise",
                                                                      0.1, 0.4, int(rng.integers(1 << 30))),
                         tag="clutter"))
    return prims, gname


def _sky_and_sun(rng):
    az, el = rng.uniform(0, 2 * np.pi), np.deg2rad(rng.uniform(15, 70))
    sun = np.array([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), np.sin(el)])
    haze = rng.uniform(0.2, 1.0)
    sky = (np.array([0.50, 0.68, 0.95]) * (1 - haze) + haze * np.array([0.92, 0.93, 0.95])) * rng.uniform(1.0, 1.5)
    horiz = np.array([sun[0], sun[1], 0.0]) / max(np.hypot(sun[0], sun[1]), 1e-9)
    air = Water(0.0, tuple(sky), up_gain=float(rng.uniform(-0.45, 0.0)), side_dir=tuple(horiz),
                side_gain=float(rng.uniform(0.0, 0.3)), light_rgb=(1.0, 0.97, 0.90),
                ambient=float(rng.uniform(0.15, 0.35)), diffuse=float(rng.uniform(0.8, 1.1)))
    return sun, air


def outdoor(rng, rig, cam, T_wc, scale, with_ball, opts):
    radius = float(rng.uniform(0.1, 0.35))
    holder = str(rng.choice(["ground", "stick", "hand"]))
    in_sky = holder != "ground" and rng.random() < 0.35
    eye = hp.eye_of(T_wc)
    drop = float(rng.uniform(0.6, 1.6))

    def ok(c):  # nearer than anything behind (a hedge or wall 8-20 m away)
        if np.linalg.norm(c - eye) > 7.0:
            return False
        if holder == "ground":
            return c[2] - radius < eye[2] - 0.3
        return not in_sky or c[2] - radius > eye[2] + 0.05
    c = hp.place_by_size(rng, cam, T_wc, radius, _r_px(cam, scale), ok, v_range=(0.0, 0.45) if in_sky else (0, 1))
    floor_z = float(c[2] - radius if holder == "ground" else min(eye[2] - 0.6, c[2] - radius - 0.2) - drop * 0.3)
    static, gname = _outdoor_static(rng, floor_z, [c])
    alb = np.array(OUTDOOR_BALLS[int(rng.integers(len(OUTDOOR_BALLS)))]) * rng.uniform(0.85, 1.05)
    ball = Sphere(tuple(c), radius, Material(tuple(np.clip(alb, 0, 1)), 0.9, "foam", 0.03,
                                             float(rng.uniform(0.0, 0.1)), int(rng.integers(1 << 30))), tag="target")
    parts = [ball] + _holder(rng, "stick" if holder == "stick" else holder, ball, c, radius, floor_z, T_wc)
    static = clear_view(static, ball, T_wc)
    sun, air = _sky_and_sun(rng)
    look = BallLook(tuple(c), radius, ks=float(rng.uniform(0.2, 1.0)) if rng.random() < 0.6 else 0.0,
                    shininess=float(rng.uniform(20, 150)), seam_dir=rand_dir(rng) if rng.random() < 0.3 else None,
                    logo_dir=rand_dir(rng) if rng.random() < 0.3 else None)
    photo = replace(draw_photo(rng, c, radius, eye, look, scale), key_dir=tuple(sun),
                    softness=float(rng.uniform(0.004, 0.015)), vignette=float(rng.uniform(0.0, 0.3)))
    photo, opts = hp.camera_artefacts(rng, photo, opts, scale)
    L, _, _, photo = render_parts(rng, static, parts, with_ball, cam, T_wc, air, photo, 3)
    where = "sky" if in_sky else holder
    return L, c, radius, photo, opts, f"outdoor/{gname}/{where}/{hp.artefact_label(photo, opts)}"


FLOATS = (((0.95, 0.40, 0.06), 0.4), ((0.88, 0.88, 0.86), 0.25), ((0.92, 0.80, 0.10), 0.1), ((0.06, 0.06, 0.07), 0.25))


def ocean_water(rng, T_wc):
    c_g = float(rng.uniform(0.06, 0.3))
    ocean = rng.random() < 0.5
    c_rgb = (c_g + float(rng.uniform(0.3, 0.7)), c_g, c_g * float(rng.uniform(0.5, 0.9) if ocean else rng.uniform(1.2, 2.0)))
    tint = (np.array([0.05, 0.30, 0.55]) if ocean else np.array([0.08, 0.45, 0.42])) * rng.uniform(0.5, 1.1)
    spot = rng.random() < 0.5
    fwd = hp.camera_forward(T_wc)
    axis = fwd + rng.normal(0, 0.12, 3)
    axis /= np.linalg.norm(axis)
    water = Water(c_g, tuple(tint), up_gain=float(rng.uniform(0.4, 1.0)), side_dir=tuple(rand_dir(rng)),
                  side_gain=0.0, light_rgb=(0.95, 1.0, 1.0), ambient=float(rng.uniform(0.2, 0.45)),
                  diffuse=float(rng.uniform(0.3, 0.8)), attenuation_rgb=c_rgb,
                  spot_veil=float(rng.uniform(0.05, 0.4)) if spot else 0.0, spot_dir=tuple(axis),
                  spot_power=float(rng.uniform(4, 25)))
    return water, spot


def seabed(rng, seabed_z: float, keep_clear) -> list:
    rock = rng.random() < 0.4
    alb = (0.36, 0.34, 0.30) if rock else (0.58, 0.53, 0.40)
    prims = [Rect((0, 0, seabed_z), (0, 0, 1), material=Material(tuple(np.array(alb) * rng.uniform(0.7, 1.2)), 0.5,
                                                                  "gravel" if rock else "sand",
                                                                  float(rng.uniform(0.08, 0.3)),
                                                                  float(rng.uniform(0.3, 0.8)),
                                                                  int(rng.integers(1 << 30))), tag="seabed")]
    for _ in range(int(rng.integers(0, 6))):  # boulders
        r = float(rng.uniform(0.1, 0.5))
        p = np.array([rng.uniform(1.0, 8.0), rng.uniform(-4, 4), seabed_z + 0.3 * r])
        if min(np.linalg.norm((p - k)[:2]) for k in keep_clear) < 0.5 + r:
            continue
        prims.append(Sphere(tuple(p), r, Material(tuple(rng.uniform(0.15, 0.45, 3)), 0.6, "noise", 0.05, 0.5,
                                                  int(rng.integers(1 << 30))), tag="clutter"))
    return prims


def underwater(rng, rig, cam, T_wc, scale, with_ball, opts):
    radius = float(rng.uniform(0.05, 0.2))
    water, spot = ocean_water(rng, T_wc)
    eye = hp.eye_of(T_wc)
    has_bed = rng.random() < 0.7
    holder = str(rng.choice(["rope", "seabed", "tether", "hand"] if has_bed else ["rope", "hand"]))
    d_max = float(np.clip(np.log(4.0) / water.attenuation_rgb[1], 1.0, 6.0))
    bed_drop = float(rng.uniform(0.8, 3.0))

    def ok(c):
        d = np.linalg.norm(c - eye)
        return d < d_max and (holder != "seabed" or c[2] - radius < eye[2] - 0.3)
    c = hp.place_by_size(rng, cam, T_wc, radius, _r_px(cam, scale), ok)
    seabed_z = float(c[2] - radius if holder == "seabed" else min(eye[2], c[2] - radius) - bed_drop)
    surface_z = float(max(eye[2], c[2]) + rng.uniform(0.5, 4.0))
    alb = np.array(FLOATS[int(rng.choice(len(FLOATS), p=[f[1] for f in FLOATS]))][0]) * rng.uniform(0.85, 1.05)
    ball = Sphere(tuple(c), radius, Material(tuple(np.clip(alb, 0, 1)), 0.9, "foam", 0.02,
                                             float(rng.uniform(0.0, 0.08)), int(rng.integers(1 << 30))), tag="target")
    static = seabed(rng, seabed_z, [c]) if has_bed else []
    parts = [ball] + water_holder(rng, holder, ball, c, radius, seabed_z, surface_z, T_wc)
    static = clear_view(static, ball, T_wc)
    look = BallLook(tuple(c), radius, ks=float(rng.uniform(0.0, 0.6)), shininess=float(rng.uniform(20, 100)))
    tilt = rng.normal(0, 0.25, 2)
    photo = replace(draw_photo(rng, c, radius, eye, look, scale), key_dir=tuple(np.array([tilt[0], tilt[1], 1.0])),
                    softness=float(rng.uniform(0.05, 0.2)), vignette=float(rng.uniform(0.2, 0.6)), bloom_px=0.0)
    if rng.random() < 0.5:
        photo = replace(photo, caustic=float(rng.uniform(0.3, 1.0)), caustic_scale_m=float(rng.uniform(0.15, 0.5)),
                        caustic_seed=int(rng.integers(1 << 30)))
    if spot:
        photo = replace(photo, spot_gain=float(rng.uniform(0.3, 1.5)), spot_pos=tuple(eye + [0, 0, 0.15]),
                        spot_dir=water.spot_dir, spot_power=water.spot_power)
    photo, opts = hp.camera_artefacts(rng, photo, opts, scale)
    L, _, _, photo = render_parts(rng, static, parts, with_ball, cam, T_wc, water, photo, 3)
    snow = rng.random() < 0.6
    if snow:
        s = scale / 0.5
        L = marine_snow(L, rng, int(rng.uniform(20, 300) * s * s), (0.4 * s, 2.5 * s), float(rng.uniform(0.3, 0.9)),
                        float(rng.uniform(1.0, 4.0)) * s)
    tags = "+".join(t for t in ("spot" if spot else "", "caustic" if photo.caustic else "", "snow" if snow else "") if t)
    label = f"underwater/{holder}/{'bed' if has_bed else 'open'}/{tags or 'plain'}/{hp.artefact_label(photo, opts)}"
    return L, c, radius, photo, opts, label


def water_holder(rng, kind, ball, c, radius, seabed_z, surface_z, T_wc) -> list:
    if kind == "rope":
        rope = world.chain(rng, np.asarray(c) + [0, 0, radius * 0.95], surface_z, float(rng.uniform(0.004, 0.01)),
                           tag="stand", links=False)
        return [rope] if rope is not None else []
    if kind == "tether":
        top = np.asarray(c) - [0, 0, radius * 0.95]
        foot = top + np.array([*rng.normal(0, 0.05, 2), seabed_z - top[2]])
        return [Cylinder(tuple(top), tuple(foot), float(rng.uniform(0.004, 0.01)), world.ROPE, tag="stand")]
    if kind == "hand":
        return [hp.hand_blob(rng, c, radius, hp.eye_of(T_wc), T_wc, ball)]
    return []


HELDOUT_KINDS = {"sports": sports, "outdoor": outdoor, "underwater": underwater}
