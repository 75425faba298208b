"""Scene objects for range-sensor presets: a solid ball resting on a chair or a table, held
on a stick by a person-sized figure, or carried in a person's hands, in a room (floor and
wall). World frame, metres, z up.

These are the cases a range detector must keep: a sphere touching something larger than
itself (a seat, a table top, a seabed slab) or attached to a stick with a person close
behind, seen from one side only.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from calib_core.synth.scene import Box, Capsule, Cylinder, Group, Material, Rect, Sphere

GYM_GREY = Material((0.55, 0.56, 0.58), 0.9)
FOAM_YELLOW = Material((0.92, 0.78, 0.12), 0.9)
WOOD = Material((0.45, 0.30, 0.18), 0.7)
CLOTH = Material((0.15, 0.18, 0.30), 0.6)
SKIN = Material((0.80, 0.62, 0.50), 0.6)
STICK = Material((0.04, 0.04, 0.04), 0.5)
FLOOR = Material((0.55, 0.52, 0.48), 0.6)
WALL = Material((0.62, 0.38, 0.30), 0.7)

HOLDERS = ("chair", "table", "stick", "hand")
# occluded fraction of the ball (calib_core.synth.occlusion) a placement may show in a camera:
# a carrying hand is meant to hide part of the outline; other holders must not hide it
MAX_OCCLUDED = {"hand": 0.3}


def solid_ball(center_world, radius_m: float, yellow: bool) -> Sphere:
    """A solid ball (gym ball, foam ball): what optical range sensors see of a sphere."""
    return Sphere(tuple(center_world), radius_m, FOAM_YELLOW if yellow else GYM_GREY, tag="target")


def room(rng, floor_z: float) -> list:
    """Floor at ``floor_z`` and a wall 4.5-6.5 m ahead of the rig (+x)."""
    far = float(rng.uniform(4.5, 6.5))
    return [Rect((0, 0, floor_z), (0, 0, 1), material=FLOOR, tag="floor"),
            Rect((far, 0, floor_z + 2.5), (-1, rng.normal(0, 0.1), 0), (8.0, 2.5), u=(0, 1, 0),
                 material=WALL, tag="wall")]


def _yaw_away(rng, center, sensor_world, spread_deg: float) -> float:
    """Yaw (rad) of the direction from the sensor to ``center`` plus a random spread."""
    d = np.asarray(center, float) - np.asarray(sensor_world, float)
    return float(np.arctan2(d[1], d[0]) + np.deg2rad(rng.uniform(-spread_deg, spread_deg)))


def chair(rng, center, radius_m: float, floor_z: float, sensor_world) -> Group:
    """A chair whose seat top touches the ball's bottom; its backrest on the far side."""
    c = np.asarray(center, float)
    top = c[2] - radius_m
    yaw = _yaw_away(rng, c, sensor_world, 50.0)
    R = Rotation.from_euler("z", yaw).as_matrix()
    half = float(rng.uniform(0.2, 0.26))
    seat = Box(tuple(c - [0, 0, radius_m + 0.02]), (half, half, 0.02), tuple(map(tuple, R)))
    back_c = c + R[:, 0] * (half - 0.015)
    back = Box((back_c[0], back_c[1], top + 0.25), (0.015, half, 0.25), tuple(map(tuple, R)))
    legs = []
    for sx, sy in ((-1, -1), (-1, 1), (1, -1), (1, 1)):
        p = c + R[:, 0] * sx * (half - 0.03) + R[:, 1] * sy * (half - 0.03)
        legs.append(Cylinder((p[0], p[1], floor_z), (p[0], p[1], top - 0.04), 0.015))
    return Group((seat, back, *legs), WOOD, tag="chair")


def table(rng, center, radius_m: float, floor_z: float) -> Group:
    """A table (or a flat slab) wider than the ball in every direction, the ball on top."""
    c = np.asarray(center, float)
    top = c[2] - radius_m
    hx, hy = rng.uniform(0.5, 0.8, 2)
    R = Rotation.from_euler("z", rng.uniform(0, np.pi)).as_matrix()
    off = rng.uniform(-0.2, 0.2, 2)
    tc = c + R[:, 0] * off[0] + R[:, 1] * off[1]
    slab = Box((tc[0], tc[1], top - 0.025), (hx, hy, 0.025), tuple(map(tuple, R)))
    legs = []
    for sx, sy in ((-1, -1), (-1, 1), (1, -1), (1, 1)):
        p = tc + R[:, 0] * sx * (hx - 0.05) + R[:, 1] * sy * (hy - 0.05)
        legs.append(Cylinder((p[0], p[1], floor_z), (p[0], p[1], top - 0.05), 0.025))
    return Group((slab, *legs), WOOD, tag="table")


def stick_and_person(rng, center, radius_m: float, floor_z: float, sensor_world) -> list:
    """A black stick from the ball down to the hand of a person standing beside or behind
    it (0.35-0.9 m away, on the far side of the ball as the sensor sees it)."""
    c = np.asarray(center, float)
    yaw = _yaw_away(rng, c, sensor_world, 80.0)
    away = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    dist = float(rng.uniform(0.35, 0.9))
    feet = c + away * (dist + radius_m)
    feet[2] = floor_z
    height = float(rng.uniform(1.6, 1.9))
    hand = c + away * (0.3 * dist + radius_m) - [0, 0, rng.uniform(0.4, 0.7)]
    hand[2] = max(hand[2], floor_z + 0.6)
    toward = (hand - c) / np.linalg.norm(hand - c)
    stick = Cylinder(tuple(c + toward * radius_m * 0.98), tuple(hand), 0.012, STICK, tag="stick")
    hip, shoulder = feet + [0, 0, 0.5 * height], feet + [0, 0, 0.8 * height]
    side = np.cross(away, [0, 0, 1.0])
    body = [Capsule(tuple(hip), tuple(shoulder), 0.16),
            Capsule(tuple(feet + side * 0.1 + [0, 0, 0.05]), tuple(hip + side * 0.08), 0.07),
            Capsule(tuple(feet - side * 0.1 + [0, 0, 0.05]), tuple(hip - side * 0.08), 0.07),
            Capsule(tuple(shoulder + side * 0.18), tuple(hand), 0.045),
            Capsule(tuple(shoulder - side * 0.18), tuple(hip - side * 0.25), 0.045)]
    head = Sphere(tuple(feet + [0, 0, 0.93 * height]), 0.1, SKIN, tag="person")
    return [stick, Group(tuple(body), CLOTH, tag="person"), head]


def carried_by_person(rng, center, radius_m: float, floor_z: float, sensor_world) -> list:
    """A person standing behind the ball (as the sensor sees it) and holding it out at arm's
    length in one hand (from below) or two (on its sides); each hand lies on the ball's surface
    near its outline, so it hides part of the outline and continues it in range."""
    c = np.asarray(center, float)
    yaw = _yaw_away(rng, c, sensor_world, 35.0)
    away = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    side = np.cross([0, 0, 1.0], away)
    reach = float(rng.uniform(0.42, 0.62)) + radius_m
    feet = c + away * reach
    feet[2] = floor_z
    shoulder_z = max(c[2] + float(rng.uniform(0.05, 0.45)), floor_z + 1.05)
    height = shoulder_z - floor_z
    hip, neck = feet + [0, 0, 0.62 * height], feet + [0, 0, height]
    parts = [Capsule(tuple(hip), tuple(neck), 0.15),
             Capsule(tuple(feet + side * 0.1 + [0, 0, 0.05]), tuple(hip + side * 0.08), 0.07),
             Capsule(tuple(feet - side * 0.1 + [0, 0, 0.05]), tuple(hip - side * 0.08), 0.07)]
    hands = [None] if rng.random() < 0.4 else [1.0, -1.0]
    skin = [Sphere(tuple(neck + [0, 0, 0.2]), 0.1, SKIN, tag="person")]
    for sgn in hands:
        wrist, tip = _hand_on_ball(rng, c, radius_m, away, side, sgn)
        sh = neck + side * (0.2 * (sgn or float(rng.choice([-1.0, 1.0])))) - [0, 0, 0.04]
        parts.append(Capsule(tuple(sh), tuple(wrist), 0.045))
        skin.append(Capsule(tuple(wrist), tuple(tip), 0.04, SKIN, tag="hand"))
    if len(hands) == 1:  # the other arm hangs
        sh = neck - side * 0.2 - [0, 0, 0.04]
        parts.append(Capsule(tuple(sh), tuple(sh - [0, 0, 0.6 * height / 1.45]), 0.045))
    return [Group(tuple(parts), CLOTH, tag="person"), *skin]


def _hand_on_ball(rng, c, radius_m: float, away, side, sgn):
    """(wrist, fingertips) of a hand lying on the ball: under it (``sgn`` None) or on its side
    ``sgn`` (+1 / -1 along ``side``), tilted a little towards the sensor so that the fingers
    wrap over the visible outline."""
    if sgn is None:
        u = np.array([0, 0, -1.0]) * np.cos(np.radians(rng.uniform(10, 35))) - away * 0.4
    else:
        u = side * sgn + [0, 0, -rng.uniform(0.0, 0.5)] - away * rng.uniform(-0.2, 0.5)
    u /= np.linalg.norm(u)
    # the fingers run from the wrist (towards the person) over the surface towards the sensor
    t = -away - u * float(-away @ u)
    t /= max(np.linalg.norm(t), 1e-9)
    a = np.radians(rng.uniform(25, 40))  # the hand's length as an angle on the ball
    rh = radius_m + 0.035
    wrist = c + rh * (np.cos(a / 2) * u - np.sin(a / 2) * t)
    tip = c + rh * (np.cos(a / 2) * u + np.sin(a / 2) * t)
    return wrist, tip


def holder_parts(rng, kind: str, center, radius_m: float, floor_z: float, sensor_world) -> list:
    """The holder of the ball: "chair", "table", "stick" (with its person) or "hand" (a person
    carrying it)."""
    if kind == "chair":
        return [chair(rng, center, radius_m, floor_z, sensor_world)]
    if kind == "table":
        return [table(rng, center, radius_m, floor_z)]
    if kind == "stick":
        return stick_and_person(rng, center, radius_m, floor_z, sensor_world)
    if kind == "hand":
        return carried_by_person(rng, center, radius_m, floor_z, sensor_world)
    raise ValueError(f"unknown holder {kind!r}; use one of {HOLDERS}")
