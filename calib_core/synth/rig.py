"""Random intrinsics, rig geometry and sphere placements for synthetic sessions.

World frame: metres, z up, the sonar at the origin looking roughly along +x.
Sonar frame: x forward, y left, z up (see :mod:`calib_core.synth.sonar_sim`).
Camera frames: OpenCV (x right, y down, z forward).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from calib_core.camera import CameraModel
from calib_core.geometry import invert_T, look_at_T_cam_world, make_T, transform_points
from calib_core.synth.camera_render import camera_rays


@dataclass
class Rig:
    """Sensors of a synthetic session. ``cams[name] = (CameraModel, T_world_cam)``."""

    T_world_sonar: np.ndarray
    cams: dict = field(default_factory=dict)

    def T_cam_world(self, name: str) -> np.ndarray:
        return invert_T(self.cams[name][1])

    def T_cam_sonar(self, name: str) -> np.ndarray:
        return self.T_cam_world(name) @ self.T_world_sonar


def sample_intrinsics(rng: np.random.Generator, width_px: int, height_px: int, name: str,
                      scale: float = 1.0) -> CameraModel:
    """Random but realistic pinhole + plumb_bob intrinsics (f 900-1800 px at 1920 wide).

    Mixes mild, strong barrel and pincushion lenses; rejects any whose distortion folds
    back (is not invertible) inside the image, as a real calibration would never give.
    """
    for _ in range(500):
        f = rng.uniform(900, 1800) * scale
        fy = f * (1 + rng.normal(0, 0.002))
        cx = width_px / 2 + rng.normal(0, 0.015 * width_px)
        cy = height_px / 2 + rng.normal(0, 0.015 * height_px)
        style = rng.choice(3, p=[0.45, 0.4, 0.15])
        if style == 0:  # mild
            k = [rng.uniform(-0.15, 0.05), rng.uniform(-0.05, 0.15), rng.uniform(-0.02, 0.02)]
        elif style == 1:  # strong barrel
            k = [rng.uniform(-0.45, -0.2), rng.uniform(0.05, 0.3), rng.uniform(-0.05, 0.05)]
        else:  # pincushion (flat port)
            k = [rng.uniform(0.02, 0.15), rng.uniform(-0.05, 0.05), 0.0]
        p1, p2 = rng.normal(0, 0.0008, 2)
        K = np.array([[f, 0, cx], [0, fy, cy], [0, 0, 1.0]])
        cam = CameraModel(width_px, height_px, K, np.array([k[0], k[1], p1, p2, k[2]]), name=name)
        if lens_ok(cam):
            return cam
    raise RuntimeError("could not sample invertible intrinsics")  # practically unreachable


def lens_ok(cam: CameraModel) -> bool:
    """Distortion invertible over the image (with 15 % radius to spare) and round-trip exact."""
    W, H = cam.width_px, cam.height_px
    border = np.array([[-0.5, -0.5], [W - 0.5, -0.5], [-0.5, H - 0.5], [W - 0.5, H - 0.5],
                       [W / 2, -0.5], [-0.5, H / 2], [W - 0.5, H / 2], [W / 2, H - 0.5]])
    xy = cam.normalize(border)
    if not np.isfinite(xy).all() or np.abs(cam.distort(xy) - border).max() > 1e-6:
        return False
    rmax = 1.15 * np.linalg.norm(xy, axis=1).max()
    r = np.linspace(0, rmax, 400)
    k1, k2, _, _, k3 = cam.dist
    g = 1 + 3 * k1 * r**2 + 5 * k2 * r**4 + 7 * k3 * r**6  # d/dr of r*(1+k1 r^2+...)
    return bool(g.min() > 0.25)


def _rot(yaw_deg, pitch_deg, roll_deg) -> np.ndarray:
    return Rotation.from_euler("ZYX", [yaw_deg, pitch_deg, roll_deg], degrees=True).as_matrix()


def look_at_pose(rng, eye, target, roll_sigma_deg=2.0) -> np.ndarray:
    """T_world_cam of an OpenCV camera at ``eye`` looking at ``target`` with a random roll."""
    T_cam_world = look_at_T_cam_world(eye, target)
    roll = Rotation.from_rotvec([0, 0, np.deg2rad(rng.normal(0, roll_sigma_deg))]).as_matrix()
    T_cam_world = make_T(roll, [0, 0, 0]) @ T_cam_world
    return invert_T(T_cam_world)


def sample_fisheye_intrinsics(rng: np.random.Generator, width_px: int, height_px: int, name: str,
                              scale: float = 1.0) -> CameraModel:
    """Random wide-angle intrinsics in OpenCV's fisheye (equidistant) model, as a dome-port
    action camera is calibrated: 110-160 deg across the image width, k1..k4 of a few percent;
    rejects any whose angle polynomial folds inside the image (15 % to spare)."""
    for _ in range(500):
        half_fov = np.deg2rad(rng.uniform(55.0, 80.0))
        f = 0.5 * width_px / half_fov  # r_d = f theta at the image's side edge
        fy = f * (1 + rng.normal(0, 0.002))
        cx = width_px / 2 + rng.normal(0, 0.01 * width_px)
        cy = height_px / 2 + rng.normal(0, 0.01 * height_px)
        k = [rng.uniform(-0.05, 0.1), rng.uniform(-0.05, 0.03), rng.uniform(-0.01, 0.01), rng.uniform(-0.003, 0.003)]
        cam = CameraModel(width_px, height_px, [[f, 0, cx], [0, fy, cy], [0, 0, 1.0]], k, name=name, fisheye=True)
        th = np.linspace(0, 1.15 * np.hypot(width_px, height_px) / (2 * f), 400)
        t2 = th * th
        g = 1 + t2 * (3 * k[0] + t2 * (5 * k[1] + t2 * (7 * k[2] + t2 * 9 * k[3])))
        if g.min() > 0.25:
            return cam
    raise RuntimeError("could not sample a fisheye lens")  # practically unreachable


def _sample_lens(rng, width_px, height_px, name, scale, lens):
    if lens == "fisheye":
        return sample_fisheye_intrinsics(rng, width_px, height_px, name, scale)
    return sample_intrinsics(rng, width_px, height_px, name, scale)


def sample_rig(rng: np.random.Generator, n_cameras: int, width_px: int, height_px: int,
               scale: float = 1.0, lens: str = "") -> Rig:
    """Sonar at the origin (small random tilt); one camera anywhere 0.3-1 m from it, or the
    paper's stereo rig (baseline ~0.74 m, each camera ~0.86 m below-beside the sonar), and for
    three cameras a third 0.25-0.45 m above the pair's middle.
    ``lens``: "" (pinhole + plumb_bob) or "fisheye" (equidistant)."""
    R_ws = _rot(rng.uniform(-4, 4), rng.uniform(-4, 4), rng.uniform(-2, 2))
    rig = Rig(make_T(R_ws, [0, 0, 0]))
    if n_cameras == 1:
        while True:
            eye = np.array([rng.uniform(-0.2, 0.2), rng.uniform(-0.6, 0.6), -rng.uniform(0.15, 0.9)])
            if 0.3 <= np.linalg.norm(eye) <= 1.0:
                break
        target = np.array([rng.uniform(2.0, 4.0), rng.uniform(-0.6, 0.6), eye[2] + rng.uniform(-0.3, 0.5)])
        rig.cams["cam1"] = (_sample_lens(rng, width_px, height_px, "cam1", scale, lens), look_at_pose(rng, eye, target))
        return rig
    b = rng.uniform(0.68, 0.80)
    h = np.sqrt(max(0.86**2 - (b / 2) ** 2, 0.1)) + rng.uniform(-0.05, 0.05)
    dx = rng.uniform(-0.1, 0.1)
    look = np.array([rng.uniform(2.5, 4.0), rng.uniform(-0.2, 0.2), -h + rng.uniform(-0.2, 0.3)])
    for name, side in (("cam1", 1.0), ("cam2", -1.0)):
        eye = np.array([dx + rng.normal(0, 0.01), side * b / 2, -h + rng.normal(0, 0.01)])
        target = look + rng.normal(0, 0.15, 3)
        rig.cams[name] = (_sample_lens(rng, width_px, height_px, name, scale, lens), look_at_pose(rng, eye, target))
    if n_cameras == 3:  # a third camera above the middle of the stereo pair (drawn last: pairs unchanged)
        eye = np.array([dx + rng.normal(0, 0.02), rng.normal(0, 0.05), -h + rng.uniform(0.25, 0.45)])
        rig.cams["cam3"] = (_sample_lens(rng, width_px, height_px, "cam3", scale, lens),
                            look_at_pose(rng, eye, look + rng.normal(0, 0.15, 3)))
    return rig


def silhouette_uv(cam: CameraModel, center_cam_m: np.ndarray, radius_m: float, n: int = 72) -> np.ndarray:
    """Raw pixels (n,2) of the sphere's outline (the tangent cone); NaN if behind the camera."""
    C = np.asarray(center_cam_m, float)
    dist = np.linalg.norm(C)
    if dist <= radius_m:
        return np.full((n, 2), np.nan)
    w = C / dist
    a = np.arcsin(radius_m / dist)
    e1 = np.cross(w, [0, 1.0, 0]) if abs(w[1]) < 0.9 else np.cross(w, [1.0, 0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(w, e1)
    phi = np.linspace(0, 2 * np.pi, n, endpoint=False)
    v = np.cos(a) * w[None] + np.sin(a) * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
    if (v[:, 2] <= 1e-6).any():
        return np.full((n, 2), np.nan)
    return cam.project(v)


def sphere_in_image(cam: CameraModel, T_cam_world: np.ndarray, center_world_m, radius_m: float,
                    margin_px: float = 0.0) -> bool:
    """True when the whole silhouette lies inside the image (and in front of the camera)."""
    C = transform_points(T_cam_world, np.asarray(center_world_m, float)[None])[0]
    uv = silhouette_uv(cam, C, radius_m)
    return bool(np.isfinite(uv).all() and cam.in_image(uv, margin_px).all())


def in_sonar_field(T_world_sonar, center_world_m, radius_m, pan_span_deg=90.0, fan_deg=90.0,
                   min_range_m=0.7, max_range_m=8.0, margin_deg=3.0) -> bool:
    """The whole sphere inside the scanned volume of the sonar (with an angular margin)."""
    p = transform_points(invert_T(T_world_sonar), np.asarray(center_world_m, float)[None])[0]
    rng_m = np.linalg.norm(p)
    if not min_range_m <= rng_m <= max_range_m:
        return False
    ang = np.rad2deg(np.arcsin(radius_m / rng_m)) + margin_deg
    az = np.rad2deg(np.arctan2(p[1], p[0]))
    el = np.rad2deg(np.arcsin(p[2] / rng_m))
    return abs(az) + ang <= pan_span_deg / 2 and abs(el) + ang <= fan_deg / 2


def sample_target_center(rng, rig: Rig, radius_m: float, ref_cam: str, corner: bool,
                         ok_extra=lambda c: True, dist_range=(1.0, 4.0), tries: int = 400, z_range=None):
    """A world-frame sphere centre aimed at a random pixel of ``ref_cam`` (near a corner if
    asked), 1-4 m away, fully inside every camera's image when possible and inside the
    sonar's scanned volume. ``z_range`` (world z of the centre, metres), if given, limits the
    distance drawn along the pixel's ray to where the centre's height lies in that range.
    Returns (center_world_m, visible_in_all_cameras)."""
    cam, T_wc = rig.cams[ref_cam]
    W, H = cam.width_px, cam.height_px
    fallback = None
    for i in range(tries):
        if corner:
            u = rng.choice([rng.uniform(0.05, 0.2), rng.uniform(0.8, 0.95)]) * W
            v = rng.choice([rng.uniform(0.06, 0.22), rng.uniform(0.78, 0.94)]) * H
        else:
            u, v = rng.uniform(0.12, 0.88) * W, rng.uniform(0.12, 0.88) * H
        ray = camera_rays(cam, np.array([[u, v]]))[0]
        lo, hi = dist_range if z_range is None else _dist_for_height(T_wc, ray, dist_range, z_range)
        if lo > hi:
            continue
        d = rng.uniform(lo, hi)
        c_world = transform_points(T_wc, (d * ray)[None])[0]
        if not in_sonar_field(rig.T_world_sonar, c_world, radius_m) or not ok_extra(c_world):
            continue
        if any(np.linalg.norm(c_world - T[:3, 3]) < max(0.9, 8 * radius_m) for _, T in rig.cams.values()):
            continue
        vis = [sphere_in_image(m, invert_T(T), c_world, radius_m, 2.0) for m, T in rig.cams.values()]
        if all(vis):
            return c_world, True
        if vis[list(rig.cams).index(ref_cam)] and fallback is None:
            fallback = c_world
        if corner and i > tries // 2:
            corner = False  # corners of one camera may be outside the other: relax
    if fallback is None:
        raise RuntimeError(f"could not place the target in view of the sonar and the camera in {tries} tries")
    return fallback, False


def _dist_for_height(T_world_cam, ray_cam, dist_range, z_range):
    """The distances along a camera ray (within ``dist_range``) whose world point has its
    height in ``z_range``; an empty interval has lo > hi."""
    z0 = T_world_cam[2, 3]
    dz = float((T_world_cam[:3, :3] @ ray_cam)[2])
    lo, hi = dist_range
    if abs(dz) < 1e-9:
        return (lo, hi) if z_range[0] <= z0 <= z_range[1] else (1.0, 0.0)
    a, b = sorted(((z_range[0] - z0) / dz, (z_range[1] - z0) / dz))
    return max(lo, a), min(hi, b)


def sample_in_sensor_view(rng, rig: Rig, radius_m: float, ok_extra, z_range, dist_range=(1.0, 4.5),
                          tries: int = 20000):
    """A world-frame sphere centre drawn in the range sensor's view (azimuth and elevation
    within +-45 deg, ``dist_range`` away, centre height in ``z_range``) that passes ``ok_extra``,
    is fully inside every camera's image and not too close to any camera. For rigs where
    aiming at a camera pixel rarely lands in the sensor's (narrow) field.
    Raises RuntimeError after ``tries`` draws."""
    R, t = rig.T_world_sonar[:3, :3], rig.T_world_sonar[:3, 3]
    for _ in range(tries):
        az, el = np.deg2rad(rng.uniform(-45, 45, 2))
        d = rng.uniform(*dist_range)
        c = t + R @ (d * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)]))
        if not z_range[0] <= c[2] <= z_range[1] or not in_sonar_field(rig.T_world_sonar, c, radius_m):
            continue
        if any(np.linalg.norm(c - T[:3, 3]) < max(0.9, 8 * radius_m) for _, T in rig.cams.values()):
            continue
        if all(sphere_in_image(m, invert_T(T), c, radius_m, 2.0) for m, T in rig.cams.values()) and ok_extra(c):
            return c
    raise RuntimeError(f"could not place the target in view of the range sensor and the camera in {tries} tries")
