"""A dry, cluttered, textured scene: a ball (any colour, matte foam) on a stick or resting on
a block, in front of a brick wall, on a tiled floor, among furniture-like blocks.

This is what real sphere-target data sets look like (a lab, a gym ball on a chair, a foam
ball carried in front of a brick wall): strong texture everywhere, no background frames, and
a holder that hides part of the outline. World frame as elsewhere (z up); the rig looks
roughly along +x (see :mod:`calib_core.synth.rig`).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from calib_core.synth.camera_render import Water
from calib_core.synth.scene import Box, Cylinder, Material, Rect, Sphere

AIR = Water(attenuation_per_m=0.0, water_rgb=(0.85, 0.85, 0.82), up_gain=0.1, side_gain=0.0,
            ambient=0.55, diffuse=0.45)
BALL_COLOURS = ((0.85, 0.75, 0.10), (0.55, 0.55, 0.55), (0.80, 0.20, 0.15), (0.15, 0.35, 0.75),
                (0.90, 0.90, 0.88), (0.12, 0.12, 0.13), (0.25, 0.60, 0.25))


def room_air(rng: np.random.Generator) -> Water:
    """Clear air, indoor light of a random strength."""
    g = float(rng.uniform(0.8, 1.15))
    return Water(0.0, (0.85 * g, 0.85 * g, 0.82 * g), up_gain=0.1, side_gain=0.0,
                 ambient=float(rng.uniform(0.45, 0.65)), diffuse=float(rng.uniform(0.35, 0.55)))


def _mat(rng, albedo, texture, scale, contrast):
    return Material(tuple(float(a) for a in albedo), 0.5, texture, float(scale), float(contrast),
                    int(rng.integers(1 << 30)))


def room_scene(rng: np.random.Generator, floor_z: float, keep_clear_world) -> list:
    """Tiled floor, brick back wall, side walls and furniture-like blocks (static parts)."""
    far = float(rng.uniform(4.5, 6.5))
    brick = np.array([0.62, 0.33, 0.25]) * rng.uniform(0.7, 1.2)
    prims = [
        Rect((0, 0, floor_z), (0, 0, 1), material=_mat(rng, rng.uniform(0.3, 0.7, 3), "tiles",
                                                       rng.uniform(0.2, 0.5), rng.uniform(0.3, 0.8)), tag="floor"),
        Rect((far, 0, floor_z + 3), (-1, 0, 0), (8.0, 3.2), u=(0, 1, 0),
             material=_mat(rng, brick, "brick", rng.uniform(0.06, 0.09), rng.uniform(0.4, 0.9)), tag="wall"),
    ]
    for side in (-1, 1):
        y = side * float(rng.uniform(3.0, 4.5))
        prims.append(Rect((far / 2, y, floor_z + 3), (0, -side, 0), (far, 3.2), u=(1, 0, 0),
                          material=_mat(rng, rng.uniform(0.4, 0.8, 3), "noise", 0.5, 0.3), tag="wall"))
    placed = 0
    for _ in range(300):
        if placed >= int(rng.integers(5, 10)):
            break
        size = np.array([rng.uniform(0.3, 1.2), rng.uniform(0.3, 1.2), rng.uniform(0.3, 1.1)])
        p = np.array([rng.uniform(1.0, far - 0.3), rng.uniform(-3.0, 3.0), floor_z + size[2] / 2])
        if min(np.linalg.norm((p - k)[:2]) for k in keep_clear_world) < 0.5 + size[:2].max() / 2:
            continue
        R = Rotation.from_euler("z", rng.uniform(0, np.pi)).as_matrix()
        tex = str(rng.choice(["noise", "tiles", "noise"]))
        prims.append(Box(tuple(p), tuple(size / 2), tuple(map(tuple, R)),
                         _mat(rng, rng.uniform(0.05, 0.9, 3), tex, rng.uniform(0.05, 0.3), rng.uniform(0.2, 0.7)),
                         tag="clutter"))
        placed += 1
    return prims


def ball_style(rng: np.random.Generator) -> dict:
    """Colour, foam texture and holder kind of a session's ball."""
    col = np.array(BALL_COLOURS[int(rng.integers(len(BALL_COLOURS)))]) * rng.uniform(0.8, 1.1)
    return {"albedo": tuple(np.clip(col, 0, 1)), "foam_scale": float(rng.uniform(0.02, 0.08)),
            "foam_contrast": float(rng.uniform(0.05, 0.25)), "holder": str(rng.choice(["stick", "stick", "rest"])),
            "seed": int(rng.integers(1 << 30))}


def ball_parts(rng: np.random.Generator, style: dict, centre_world, radius_m: float, floor_z: float,
               eye_world) -> list:
    """The ball and its holder: a dark stick from the ball's centre out and down past its
    outline (it hides part of the outline seen from ``eye_world``), or a block it rests on."""
    c = np.asarray(centre_world, float)
    ball = Sphere(tuple(c), radius_m, Material(style["albedo"], 0.9, "foam", style["foam_scale"],
                                               style["foam_contrast"], style["seed"]), tag="target")
    if style["holder"] == "rest" and c[2] - radius_m - floor_z > 0.1:
        top = c[2] - radius_m * 0.98
        h = top - floor_z
        size = rng.uniform(0.8, 1.6) * radius_m
        block = Box((c[0], c[1], floor_z + h / 2), (size, size, h / 2),
                    material=_mat(rng, rng.uniform(0.1, 0.8, 3), "noise", 0.1, 0.4), tag="stand")
        return [ball, block]
    view = c - np.asarray(eye_world, float)
    view /= np.linalg.norm(view)
    side = np.cross(view, [0, 0, 1.0])
    side /= max(np.linalg.norm(side), 1e-9)
    d = -0.8 * view * rng.uniform(0.0, 0.6) + side * rng.uniform(-1, 1) + np.array([0, 0, -rng.uniform(0.3, 1.0)])
    d /= np.linalg.norm(d)
    end = c + d * rng.uniform(1.0, 1.6)
    if end[2] < floor_z:
        end = c + d * (c[2] - floor_z - 0.02) / max(-d[2], 1e-3)
    stick = Cylinder(tuple(c), tuple(end), float(rng.uniform(0.008, 0.02)) * max(1.0, radius_m / 0.2),
                     Material(tuple(rng.uniform(0.03, 0.15, 3)), 0.5), tag="stand")
    return [ball, stick]
