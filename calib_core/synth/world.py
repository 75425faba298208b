"""Scene content of synthetic sessions (world frame, metres, z up).

Static parts (pontoons at the surface, seabed, wall or dock, clutter) are shared by every
capture and the background frames; per-capture parts are the target with its chain or
stand, decoys, and the flange assembly.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from calib_core.geometry import transform_points
from calib_core.synth.camera_render import Water, camera_rays
from calib_core.synth.scene import Box, Capsule, Cylinder, Disc, Group, Material, MeshSphere, Rect, Sphere

DARK_MESH = Material((0.05, 0.05, 0.06), 0.9)
BRIGHT_MESH = Material((0.92, 0.80, 0.35), 0.9)
CHAIN = Material((0.10, 0.10, 0.10), 0.55)
ROPE = Material((0.20, 0.19, 0.16), 0.4)
STEEL = Material((0.38, 0.36, 0.33), 0.95)


def sample_water(rng: np.random.Generator, bright_target: bool) -> Water:
    """Turbidity and lighting: backlit bright water, or dark water for a bright target."""
    c = float(rng.uniform(0.08, 0.55))
    side = rng.normal(0, 1, 3)
    side[2] = 0
    side /= np.linalg.norm(side)
    if bright_target:
        base = rng.uniform(0.04, 0.12) * np.array([0.7, 1.0, 1.0])
        return Water(c, tuple(base), up_gain=float(rng.uniform(0.2, 0.8)), side_dir=tuple(side),
                     side_gain=float(rng.uniform(0.0, 0.15)), ambient=0.5, diffuse=0.5)
    tint = np.array([rng.uniform(0.45, 0.65), rng.uniform(0.62, 0.80), rng.uniform(0.55, 0.78)])
    return Water(c, tuple(tint * rng.uniform(0.85, 1.1)), up_gain=float(rng.uniform(0.2, 0.6)),
                 side_dir=tuple(side), side_gain=float(rng.uniform(0.0, 0.15)))


def surface_and_pontoons(rng, rig, scene_kind: str):
    """Water surface height (world z) and dark pontoon hulls in cam1's upper corners."""
    cam, T_wc = rig.cams["cam1"]
    W, H = cam.width_px, cam.height_px
    corners = np.array([[0.04 * W, 0.03 * H], [0.96 * W, 0.03 * H]])
    rays = camera_rays(cam, corners) @ T_wc[:3, :3].T
    eye = T_wc[:3, 3]
    dist = rng.uniform(3.0, 5.5)
    up = max(rays[:, 2].max(), 0.15)
    # the rig hangs 1.2-3.5 m below the surface (the paper's: ~2 m)
    surface_z = float(np.clip(eye[2] + dist * up + 0.45, 1.2, 3.5))
    prims = []
    hull = Material((0.07, 0.07, 0.08), 0.8)
    for ray in rays:
        if ray[2] <= 0.05:
            continue
        s = (surface_z - 0.45 - eye[2]) / ray[2]
        if s > 12:
            continue
        p = eye + s * ray
        horiz = np.array([ray[0], ray[1], 0.0])
        horiz /= max(np.linalg.norm(horiz), 1e-9)
        centre = p + 0.35 * horiz
        centre[2] = surface_z - 0.25
        yaw = np.arctan2(horiz[1], horiz[0]) + rng.uniform(-0.3, 0.3)
        R = Rotation.from_euler("z", yaw).as_matrix()
        prims.append(Box(tuple(centre), (rng.uniform(1.5, 3.0), rng.uniform(0.3, 0.45), 0.3),
                         tuple(map(tuple, R)), hull, tag="pontoon"))
    return surface_z, prims


def seabed_scene(rng, rig, seabed_z: float, keep_clear_world):
    """Seabed plane, a wall or a dock behind the work area, and clutter on the seabed."""
    sand = Material(tuple(np.array([0.45, 0.42, 0.33]) * rng.uniform(0.7, 1.1)), 0.5)
    prims = [Rect((0, 0, seabed_z), (0, 0, 1), material=sand, tag="seabed")]
    far = rng.uniform(4.5, 6.5)
    concrete = Material((0.30, 0.31, 0.30), 0.8)
    if rng.random() < 0.5:
        prims.append(Rect((far, 0, seabed_z + 3), (-1, rng.normal(0, 0.1), 0), (8.0, 3.0), u=(0, 1, 0),
                          material=concrete, tag="wall"))
    else:
        deck = Box((far + 1.0, 0, seabed_z + rng.uniform(2.5, 3.5)), (1.0, 6.0, 0.2), material=concrete, tag="dock")
        piles = tuple(Cylinder((far, y, seabed_z - 0.1), (far, y, deck.center_m[2]), 0.12)
                      for y in np.arange(-5.0, 5.1, rng.uniform(1.2, 2.0)))
        prims += [deck, Group(piles, concrete, tag="dock")]
    n_clutter = int(rng.integers(4, 9))
    placed = 0
    for _ in range(200):
        if placed >= n_clutter:
            break
        p = np.array([rng.uniform(0.8, far - 0.5), rng.uniform(-3, 3), seabed_z])
        if min(np.linalg.norm((p - k)[:2]) for k in keep_clear_world) < 0.7:
            continue
        mat = Material(tuple(rng.uniform(0.1, 0.5, 3)), float(rng.uniform(0.4, 0.9)))
        kind = rng.integers(3)
        s = rng.uniform(0.08, 0.3)
        if kind == 0:  # half-buried rock
            prims.append(Sphere(tuple(p + [0, 0, rng.uniform(-0.5, 0.2) * s]), s, mat, tag="clutter"))
        elif kind == 1:  # block
            R = Rotation.from_euler("z", rng.uniform(0, np.pi)).as_matrix()
            prims.append(Box(tuple(p + [0, 0, s * 0.5]), (s, s * rng.uniform(0.4, 1.0), s * 0.5),
                             tuple(map(tuple, R)), mat, tag="clutter"))
        else:  # pipe or tyre-like short cylinder lying down
            a = rng.uniform(0, np.pi)
            dvec = np.array([np.cos(a), np.sin(a), 0]) * rng.uniform(0.2, 0.8)
            prims.append(Cylinder(tuple(p + [0, 0, 0.06]), tuple(p + dvec + [0, 0, 0.06]), 0.06, mat, tag="clutter"))
        placed += 1
    return prims


def target(rng_style, center_world, radius_m: float, bright: bool):
    """The open mesh sphere; lattice density, wire and pole tilt from ``rng_style`` (a dict)."""
    return MeshSphere(tuple(center_world), radius_m, BRIGHT_MESH if bright else DARK_MESH,
                      n_lat=rng_style["n_lat"], n_lon=rng_style["n_lon"], wire_m=rng_style["wire_m"],
                      pole=rng_style["pole"], tag="target")


def sample_target_style(rng, radius_m: float) -> dict:
    tilt = Rotation.from_rotvec(rng.normal(0, np.deg2rad(8), 3)).as_matrix()
    return {"n_lat": int(rng.integers(10, 15)), "n_lon": int(rng.integers(16, 25)),
            "wire_m": float(rng.uniform(0.0035, 0.006)) * radius_m / 0.11, "pole": tuple(tilt[:, 2])}


def chain(rng, top_world, surface_z: float, radius_m: float = 0.006, tag: str = "chain", links: bool = True):
    """A chain from ``top_world`` up to the surface, slightly swaying: interlocking links
    (each ring = 4 capsules, an approximation of a torus-like link) of overall half width
    ~``radius_m``, or a smooth rope of radius ``radius_m`` if ``links`` is False."""
    top = np.asarray(top_world, float)
    L = surface_z - top[2]
    if L <= 0.05:
        return None
    sway = rng.normal(0, 0.04, 2)
    bend = rng.normal(0, 0.02, 2)
    n = 10
    s = np.linspace(0, 1, n + 1)
    pts = np.column_stack([top[0] + sway[0] * s + bend[0] * np.sin(np.pi * s),
                           top[1] + sway[1] * s + bend[1] * np.sin(np.pi * s), top[2] + L * s])
    if not links:
        segs = tuple(Capsule(tuple(a), tuple(b), radius_m) for a, b in zip(pts[:-1], pts[1:]))
        return Group(segs, CHAIN if tag == "chain" else ROPE, tag=tag)
    # link chain: stadium-like rings of wire radius rw, alternately turned 90 deg about the axis
    rw = 0.5 * radius_m
    pitch, half_w = 6 * rw, 1.8 * rw
    A = 0.5 * pitch + 1.5 * rw  # consecutive links overlap (interlock) along the axis
    segs, k = [], 0
    for a, b in zip(pts[:-1], pts[1:]):
        ax = (b - a) / np.linalg.norm(b - a)
        e1 = np.cross(ax, [1.0, 0, 0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(ax, e1)
        group = []
        for s_k in np.arange(0.5 * pitch, np.linalg.norm(b - a), pitch):
            lat = e1 if k % 2 == 0 else e2
            k += 1
            c = a + ax * s_k
            corners = [c + sa * A * ax + sl * half_w * lat for sa, sl in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
            group.append(Group(tuple(Capsule(tuple(corners[i]), tuple(corners[(i + 1) % 4]), rw) for i in range(4))))
        if group:
            segs.append(Group(tuple(group)))
    return Group(tuple(segs), CHAIN, tag=tag)


def stand(rng, bottom_world, seabed_z: float):
    """A post from the seabed up to the sphere's bottom, with a base plate."""
    b = np.asarray(bottom_world, float)
    post_r = rng.uniform(0.012, 0.025)
    post = Cylinder((b[0], b[1], seabed_z - 0.02), tuple(b + [0, 0, 0.004]), post_r)
    base = Box((b[0], b[1], seabed_z + 0.02), (0.2, 0.2, 0.02))
    return Group((post, base), Material((0.25, 0.25, 0.22), 0.7), tag="stand")


def decoys(rng, rig, target_world, radius_m: float, n: int):
    """Other round things: spheres and discs whose size differs clearly from the target's,
    in cam1's view, away from the target and not hiding it."""
    cam, T_wc = rig.cams["cam1"]
    eye = T_wc[:3, 3]
    out = []
    for _ in range(100):
        if len(out) >= n:
            break
        uv = np.array([[rng.uniform(0.05, 0.95) * cam.width_px, rng.uniform(0.05, 0.95) * cam.height_px]])
        p = transform_points(T_wc, camera_rays(cam, uv) * rng.uniform(1.2, 5.0))[0]
        r = radius_m * (rng.uniform(0.3, 0.6) if rng.random() < 0.5 else rng.uniform(1.6, 3.0))
        if np.linalg.norm(p - target_world) < r + radius_m + 0.4:
            continue
        # not between any camera and the target
        ok = True
        for _, T in rig.cams.values():
            e = T[:3, 3]
            d = target_world - e
            s = np.clip((p - e) @ d / (d @ d), 0, 1)
            if np.linalg.norm(e + s * d - p) < r + radius_m + 0.15:
                ok = False
        if not ok or np.linalg.norm(p - eye) < 1.0:
            continue
        bright = rng.random() < 0.5
        mat = Material((0.85, 0.5, 0.2) if bright else (0.08, 0.08, 0.1), float(rng.uniform(0.5, 0.9)))
        if rng.random() < 0.6:
            out.append(Sphere(tuple(p), r, mat, tag="decoy"))
        else:
            nrm = (eye - p) / np.linalg.norm(eye - p) + rng.normal(0, 0.3, 3)
            out.append(Disc(tuple(p), tuple(nrm), r, mat, tag="decoy"))
    return out


def flange_assembly(rng, rig, surface_z: float):
    """Steel pipe with a square flange at one end (paper Fig. 5), hung from two ropes,
    placed 2-3.5 m in front of cam1."""
    cam, T_wc = rig.cams["cam1"]
    uv = np.array([[rng.uniform(0.35, 0.65) * cam.width_px, rng.uniform(0.4, 0.6) * cam.height_px]])
    c = transform_points(T_wc, camera_rays(cam, uv) * rng.uniform(2.0, 3.5))[0]
    yaw = rng.uniform(0, np.pi)
    a = np.array([np.cos(yaw), np.sin(yaw), rng.normal(0, 0.05)])
    a /= np.linalg.norm(a)
    L, r = rng.uniform(1.0, 1.6), rng.uniform(0.08, 0.12)
    p0, p1 = c - a * L / 2, c + a * L / 2
    side = rng.uniform(0.15, 0.22)
    x = a
    y = np.cross([0, 0, 1.0], x)
    y /= np.linalg.norm(y)
    R = np.column_stack([x, y, np.cross(x, y)])
    flange = Box(tuple(p1), (0.025, side, side), tuple(map(tuple, R)), STEEL, tag="flange")
    pipe = Cylinder(tuple(p0), tuple(p1), r, STEEL, tag="pipe")
    ropes = [chain(rng, p + [0, 0, r], surface_z, 0.005, tag="rope", links=False) for p in (p0 + a * 0.2, p1 - a * 0.2)]
    return [pipe, flange] + [rp for rp in ropes if rp is not None]


def decoy_and_occluder(rng, rig, target_world, radius_m: float, style: dict, bright: bool):
    """A wrong-image-detection scene for cam1: a fully visible decoy that looks exactly like the
    target (same size, same mesh) beside it at about the same range, and a dark panel between
    cam1 and the target whose edge crosses the target's centre, hiding about half of it.
    Both are put in the image only (the scan is taken without them)."""
    cam, T_wc = rig.cams["cam1"]
    eye = T_wc[:3, 3]
    d = np.asarray(target_world, float) - eye
    rng_m = float(np.linalg.norm(d))
    right, down = T_wc[:3, 0], T_wc[:3, 1]
    side = right if rng.random() < 0.5 else -right
    uv_t = cam.project(transform_points(np.linalg.inv(T_wc), np.asarray([target_world], float)))[0] \
        if hasattr(cam, "project") else None
    if uv_t is not None and not (0.3 * cam.width_px < uv_t[0] < 0.7 * cam.width_px):
        side = right if uv_t[0] < 0.5 * cam.width_px else -right  # towards the image centre
    decoy_c = eye + d + side * (6.0 * radius_m) + down * (0.5 * radius_m)
    decoy = MeshSphere(tuple(decoy_c), radius_m, BRIGHT_MESH if bright else DARK_MESH, n_lat=style["n_lat"],
                       n_lon=style["n_lon"], wire_m=style["wire_m"], pole=style["pole"], tag="decoy")
    # the panel's near edge passes through the line of sight to the target centre, on the far side
    # from the decoy, so the target keeps its visible half next to the panel
    at = eye + 0.6 * d
    half = 0.4 * 0.6 * rng_m
    centre = at - side * half
    n = -d / rng_m
    u = side - (side @ n) * n
    panel = Rect(tuple(centre), tuple(n), (half, half), u=tuple(u / np.linalg.norm(u)), material=Material((0.05, 0.06, 0.07), 0.6),
                 tag="occluder")
    return [decoy, panel]
