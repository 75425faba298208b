"""One range capture without a whole session: a ball on a holder in front of a sensor.

For detector tests and benchmarks that need many varied clouds with exact ground truth and
no camera rendering. The sensor sits at the world origin with the world axes (x forward,
y left, z up), ``height_m`` above the floor; the ball is placed 1.2-4 m ahead, inside the
sensor's field. Sensors: "lidar16", "rgbd" (:mod:`.sim`) or "sonar"
(:mod:`..sonar_sim`, BV5000-like, 1 deg beams, coarse pan to stay fast), and the held-out ones
the detector was not developed against (:mod:`.heldout`): "lidar128" (Ouster-like),
"livox" (solid-state rosette) and "stereo" (RealSense-like active stereo).
"""

from __future__ import annotations

import numpy as np

from calib_core.synth.range import scenes as range_scenes
from calib_core.synth.range.heldout import (
    Lidar128Config, LivoxConfig, StereoConfig, simulate_lidar128, simulate_livox, simulate_stereo)
from calib_core.synth.range.sim import LidarConfig, RgbdConfig, simulate_lidar, simulate_rgbd
from calib_core.synth.scene import Scene
from calib_core.synth.sonar_sim import SonarConfig, simulate_scan

SENSORS = ("lidar16", "rgbd", "sonar", "lidar128", "livox", "stereo")  # append only: the index seeds
HELDOUT = ("lidar128", "livox", "stereo")
# ball radii used with each sensor: a 16-ring LiDAR needs a big ball (0.5-0.7 m gym balls;
# its rings are 2 deg apart), RGB-D and sonar targets are smaller
RADIUS_RANGE_M = {"lidar16": (0.25, 0.35), "rgbd": (0.15, 0.3), "sonar": (0.1, 0.3),
                  "lidar128": (0.15, 0.35), "livox": (0.1, 0.3), "stereo": (0.1, 0.3)}


def sensor_config(sensor: str, rng: np.random.Generator):
    """A seed-varied configuration of ``sensor``."""
    if sensor == "lidar16":
        return LidarConfig(range_noise_m=float(rng.uniform(0.01, 0.02)))
    if sensor == "rgbd":
        return RgbdConfig(depth_noise_k=float(rng.uniform(0.001, 0.002)))
    if sensor == "sonar":
        return SonarConfig(pan_step_deg=1.0, pan_span_deg=60.0, fan_deg=60.0, n_beams=120,
                           sub_rays=13, range_noise_m=float(rng.uniform(0.002, 0.006)))
    if sensor in HELDOUT:
        return heldout_config(sensor, rng)
    raise ValueError(f"unknown range sensor {sensor!r}; use one of {SENSORS}")


def heldout_config(sensor: str, rng: np.random.Generator):
    """A seed-varied configuration of a held-out sensor."""
    if sensor == "lidar128":
        return Lidar128Config(noise_max_m=float(rng.uniform(0.02, 0.04)), dropout=float(rng.uniform(0.03, 0.15)))
    if sensor == "livox":
        return LivoxConfig(integration_s=float(rng.uniform(0.1, 1.0)), range_noise_m=float(rng.uniform(0.002, 0.006)))
    # D435: 0.05-0.1 px matching noise at 848 x 480, i.e. 0.015-0.04 px after decimation by 4
    return StereoConfig(subpixel_px=float(rng.uniform(0.015, 0.04)), fatten_px=int(rng.integers(1, 3)))


def simulate_range(sensor: str, scene: Scene, T_world_sensor: np.ndarray, cfg, rng):
    """Cloud of one capture by ``sensor`` (sensor frame, metres)."""
    if sensor == "lidar16":
        return simulate_lidar(scene, T_world_sensor, cfg, rng)
    if sensor == "rgbd":
        return simulate_rgbd(scene, T_world_sensor, cfg, rng)
    heldout = {"lidar128": simulate_lidar128, "livox": simulate_livox, "stereo": simulate_stereo}.get(sensor)
    if heldout is not None:
        return heldout(scene, T_world_sensor, cfg, rng)
    return simulate_scan(scene, T_world_sensor, cfg, rng)


def in_field(sensor: str, center_sensor_m: np.ndarray, radius_m: float, cfg) -> bool:
    """The whole ball inside the sensor's field (with a small margin)."""
    c = np.asarray(center_sensor_m, float)
    d = float(np.linalg.norm(c))
    ang = np.degrees(np.arcsin(min(radius_m / d, 1.0))) + 1.0
    az = np.degrees(np.arctan2(c[1], c[0]))
    el = np.degrees(np.arcsin(c[2] / d))
    if sensor == "lidar16":
        return abs(az) + ang <= cfg.az_span_deg / 2 and cfg.el_min_deg <= el - ang and el + ang <= cfg.el_max_deg
    if sensor in ("lidar128", "livox", "stereo"):
        return _in_heldout_field(sensor, az, el, ang, c, radius_m, cfg)
    if sensor == "rgbd":
        half_v = np.degrees(np.arctan(np.tan(np.radians(cfg.hfov_deg / 2)) * cfg.height / cfg.width))
        return (abs(az) + ang <= cfg.hfov_deg / 2 and abs(el) + ang <= half_v
                and c[0] + radius_m <= cfg.max_range_m - 0.2)
    return abs(az) + ang <= cfg.pan_span_deg / 2 and abs(el) + ang <= cfg.fan_deg / 2


def _in_heldout_field(sensor, az, el, ang, c, radius_m, cfg) -> bool:
    if sensor == "lidar128":
        return abs(az) + ang <= cfg.az_span_deg / 2 and cfg.el_min_deg <= el - ang and el + ang <= cfg.el_max_deg
    if sensor == "livox":
        return np.hypot(az, el) + ang <= cfg.fov_deg / 2
    half_v = np.degrees(np.arctan(np.tan(np.radians(cfg.hfov_deg / 2)) * cfg.height / cfg.width))
    return abs(az) + ang <= cfg.hfov_deg / 2 and abs(el) + ang <= half_v and c[0] + radius_m <= 4.0


def range_capture(seed: int, sensor: str, holder: str, radius_m: float | None = None,
                  height_m: float | None = None, near_far_m: tuple | None = None):
    """(points_sensor_m (N,3), center_sensor_m (3,), radius_m) of one synthetic capture;
    ``near_far_m``: the range of the ball's horizontal distance (m; default 1.2 m to 3.8 m for a
    depth camera, 4 m otherwise)."""
    rng = np.random.default_rng([int(seed), 4243, SENSORS.index(sensor), range_scenes.HOLDERS.index(holder)])
    cfg = sensor_config(sensor, rng)
    r = float(radius_m if radius_m is not None else rng.uniform(*RADIUS_RANGE_M[sensor]))
    h = float(height_m if height_m is not None else rng.uniform(0.8, 1.3))
    floor_z = -h
    # ball ranges: a depth camera to 3.8 m (a stereo one to 3 m, its specified ideal range)
    near, far = near_far_m or (1.2, {"rgbd": 3.8, "stereo": 3.0}.get(sensor, 4.0))
    for _ in range(500):
        d = rng.uniform(near, far)
        az = np.radians(rng.uniform(-25, 25))
        lo, hi = {"stick": (0.5, 1.4), "hand": (0.4, 1.1)}.get(holder, (0.3, 0.8))
        z = floor_z + r + rng.uniform(lo, hi)
        c = np.array([d * np.cos(az), d * np.sin(az), z])
        if in_field(sensor, c, r, cfg):
            break
    else:
        raise RuntimeError("could not place the ball in the sensor's field")
    prims = range_scenes.room(rng, floor_z)
    prims.append(range_scenes.solid_ball(c, r, yellow=holder == "stick"))
    prims += range_scenes.holder_parts(rng, holder, c, r, floor_z, np.zeros(3))
    cloud = simulate_range(sensor, Scene(tuple(prims)), np.eye(4), cfg, rng)
    return cloud.points_m, c, r
