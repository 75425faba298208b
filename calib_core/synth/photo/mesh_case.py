"""Held-out image kind "mesh": a see-through ball (:mod:`calib_core.synth.photo.see_through`).

- The ball (radius 0.08-0.3 m), one of: an open lattice (6-16 latitude bands, 8-32 meridians,
  struts 1-3 % of the radius), a cage float (3-6 bands, 4-10 meridians, struts 4-10 % of the
  radius), a knotted diamond net (8-24 strands each way, twist 0.6-1.5, strands 1-3 % of the
  radius) or a wiffle-type shell with 8-40 round holes covering 25-55 % of it (shell 1-2 % of
  the radius thick); dark (albedo 0.03-0.1) or bright (white, yellow, orange: 0.6-0.95).
- The scene: the textured room of :mod:`calib_core.synth.room` under the photographic key
  light (60 %) or open water / a seabed with colour attenuation and veil (40 %; the water of
  the "underwater" kind); the ball on a stick, hanging on a rope from above, or resting on
  the floor / seabed.
- No cast shadow of the ball (see :mod:`calib_core.synth.photo.see_through`); the contact
  shadow is off too (the renderer's is that of a solid ball).

Camera artefacts on a share (:func:`~calib_core.synth.photo.heldout_parts.camera_artefacts`).
No constant here was taken from a real image.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from calib_core.synth import room, world
from calib_core.synth.photo import heldout as held
from calib_core.synth.photo import heldout_parts as hp
from calib_core.synth.photo.cases import clear_view, render_parts, draw_photo, rand_dir
from calib_core.synth.photo.effects import BallLook
from calib_core.synth.photo.see_through import OpenShell
from calib_core.synth.scene import Material

BRIGHT = ((0.92, 0.92, 0.90), (0.92, 0.82, 0.20), (0.95, 0.50, 0.10))


def open_ball(rng, c, radius: float) -> tuple[OpenShell, str]:
    """A see-through ball of a random style (see the module doc) and its style name."""
    style = str(rng.choice(["lattice", "cage", "net", "holes"]))
    dark = rng.random() < 0.5
    alb = np.full(3, rng.uniform(0.03, 0.1)) if dark else np.array(BRIGHT[int(rng.integers(3))]) * rng.uniform(0.65, 1.03)
    mat = Material(tuple(np.clip(alb, 0, 1)), 0.9)
    common = dict(material=mat, pole=rand_dir(rng), samples=16, tag="target")
    if style == "lattice":
        ball = OpenShell(tuple(c), radius, n_lat=int(rng.integers(6, 17)), n_lon=int(rng.integers(8, 33)),
                         wire_m=radius * float(rng.uniform(0.01, 0.03)), **common)
    elif style == "cage":
        ball = OpenShell(tuple(c), radius, n_lat=int(rng.integers(3, 7)), n_lon=int(rng.integers(4, 11)),
                         wire_m=radius * float(rng.uniform(0.04, 0.1)), **common)
    elif style == "net":
        ball = OpenShell(tuple(c), radius, n_lon=int(rng.integers(8, 25)), wire_m=radius * float(rng.uniform(0.01, 0.03)),
                         pattern="net", twist=float(rng.uniform(0.6, 1.5)), **common)
    else:
        n = int(rng.integers(8, 41))
        cover = float(rng.uniform(0.25, 0.55))
        hole = float(np.rad2deg(np.arccos(1 - 2 * cover / n)))
        ball = OpenShell(tuple(c), radius, wire_m=radius * float(rng.uniform(0.01, 0.02)), pattern="holes",
                         n_holes=n, hole_deg=hole, **common)
    return ball, f"{style}-{'dark' if dark else 'bright'}"


def _hanging(rng, c, radius, top_z) -> list:
    rope = world.chain(rng, np.asarray(c) + [0, 0, radius * 0.97], top_z, float(rng.uniform(0.003, 0.008)),
                       tag="stand", links=False)
    return [rope] if rope is not None else []


def _room_or_water(rng, c, radius, T_wc, holder):
    """(static parts, air / water, floor height, where) of the scene around the ball."""
    in_water = rng.random() < 0.4
    eye = hp.eye_of(T_wc)
    if holder == "floor":
        floor_z = float(c[2] - radius)
    else:
        floor_z = float(min(eye[2] - 0.3, c[2] - radius) - rng.uniform(0.3, 1.3))
    if in_water:
        water, _ = held.ocean_water(rng, T_wc)
        static = held.seabed(rng, floor_z, [c]) if (holder == "floor" or rng.random() < 0.6) else []
        return static, water, floor_z, "water"
    return room.room_scene(rng, floor_z, [c]), room.room_air(rng), floor_z, "room"


def mesh(rng, rig, cam, T_wc, scale, with_ball, opts):
    radius = float(rng.uniform(0.08, 0.3))
    holder = str(rng.choice(["stick", "rope", "floor"]))
    eye = hp.eye_of(T_wc)

    def ok(c):
        return c[0] + radius < 4.3 and abs(c[1]) + radius < 2.8 and (holder != "floor" or c[2] - radius < eye[2] - 0.25)
    c = hp.place_by_size(rng, cam, T_wc, radius, (30.0 * scale, 0.5 * cam.height_px), ok)
    static, air, floor_z, where = _room_or_water(rng, c, radius, T_wc, holder)
    ball, style = open_ball(rng, c, radius)
    if holder == "stick":
        parts = [ball] + room.ball_parts(rng, dict(room.ball_style(rng), holder="stick"), c, radius, floor_z, eye)[1:]
    elif holder == "rope":
        parts = [ball] + _hanging(rng, c, radius, float(max(eye[2], c[2]) + rng.uniform(1.0, 2.5)))
    else:
        parts = [ball]
    static = clear_view(static, ball, T_wc)
    photo = replace(draw_photo(rng, c, radius, eye, BallLook(tuple(c), radius), scale), occluders=())
    if where == "water":
        tilt = rng.normal(0, 0.25, 2)
        photo = replace(photo, key_dir=(tilt[0], tilt[1], 1.0), bloom_px=0.0)
    photo, opts = hp.camera_artefacts(rng, photo, opts, scale)
    L, _, _, photo = render_parts(rng, static, parts, with_ball, cam, T_wc, air, photo, 3)
    return L, c, radius, photo, opts, f"mesh/{style}/{holder}/{where}/{hp.artefact_label(photo, opts)}"
