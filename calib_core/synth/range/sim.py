"""Optical range sensors beside the sonar: a 16-ring spinning LiDAR and an RGB-D depth camera.

Both write their cloud in the same SENSOR frame as the simulated sonar (origin at the
sensor's optical centre, x forward, y left, z up), so the rest of the pipeline treats them
as "the sonar". Both cast ONE ray per return through the shared scene
(:func:`calib_core.synth.scene.raycast`, optical view): no beam footprint, no blooming.

LiDAR (Velodyne VLP-16-like): ``n_rings`` rings evenly over [``el_min_deg``, ``el_max_deg``],
azimuth step ``az_step_deg`` over ``az_span_deg`` centred on x; range noise Gaussian
``range_noise_m`` (1-2 cm), returns dropped at random (``dropout``) and below
``min_reflectivity``.

RGB-D (Kinect-like, decimated): a ``width`` x ``height`` pinhole grid over ``hfov_deg``;
depth noise grows with the square of depth (``sigma = depth_noise_k * z^2``, Kinect v1:
~1.5e-3 /m), random holes (``hole_rate``) plus holes at depth edges (``edge_hole_rate``),
and flying pixels: at a depth jump of more than ``edge_jump_m`` a pixel is, with probability
``flying_rate``, placed at a random depth between its own and its neighbour's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_core.io.clouds import Cloud
from calib_core.synth.scene import Scene, raycast


@dataclass(frozen=True)
class LidarConfig:
    n_rings: int = 16
    el_min_deg: float = -15.0
    el_max_deg: float = 15.0
    az_step_deg: float = 0.2
    az_span_deg: float = 120.0
    range_noise_m: float = 0.015
    dropout: float = 0.02
    min_reflectivity: float = 0.02
    min_range_m: float = 0.5
    max_range_m: float = 30.0


@dataclass(frozen=True)
class RgbdConfig:
    width: int = 160
    height: int = 120
    hfov_deg: float = 58.0
    depth_noise_k: float = 0.0015
    hole_rate: float = 0.02
    edge_hole_rate: float = 0.3
    flying_rate: float = 0.5
    edge_jump_m: float = 0.08
    min_range_m: float = 0.5
    max_range_m: float = 4.5


def cast_rays(scene: Scene, T_world_sensor: np.ndarray, dirs_sensor: np.ndarray, max_range_m: float):
    R, origin = T_world_sensor[:3, :3], T_world_sensor[:3, 3]
    d_world = dirs_sensor @ R.T
    t, hit, n = raycast(scene, origin, d_world, acoustic=False, max_range_m=max_range_m)
    refl = scene.reflectivity()[hit]
    cosi = np.abs(np.einsum("ij,ij->i", n, d_world))
    return t, refl, cosi


def lidar_directions(cfg: LidarConfig) -> np.ndarray:
    """(rings * azimuths, 3) unit ray directions in the sensor frame."""
    el = np.deg2rad(np.linspace(cfg.el_min_deg, cfg.el_max_deg, cfg.n_rings))
    n_az = int(round(cfg.az_span_deg / cfg.az_step_deg)) + 1
    az = np.deg2rad(cfg.az_step_deg * (np.arange(n_az) - (n_az - 1) / 2))
    A, E = np.meshgrid(az, el, indexing="ij")
    return np.stack([np.cos(E) * np.cos(A), np.cos(E) * np.sin(A), np.sin(E)], -1).reshape(-1, 3)


def simulate_lidar(scene: Scene, T_world_sensor: np.ndarray, cfg: LidarConfig,
                   rng: np.random.Generator) -> Cloud:
    """One LiDAR sweep; the cloud in the sensor frame (x fwd, y left, z up), metres."""
    D = lidar_directions(cfg)
    t, refl, cosi = cast_rays(scene, T_world_sensor, D, cfg.max_range_m)
    ok = (np.isfinite(t) & (t >= cfg.min_range_m) & (refl >= cfg.min_reflectivity)
          & (rng.random(len(t)) >= cfg.dropout))
    r = t[ok] + cfg.range_noise_m * rng.standard_normal(int(ok.sum()))
    return Cloud(D[ok] * r[:, None], np.clip(refl[ok] * (0.3 + 0.7 * cosi[ok]), 0, None))


def rgbd_directions(cfg: RgbdConfig) -> tuple[np.ndarray, np.ndarray]:
    """(H*W,3) unit rays in the sensor frame and their (H*W,) forward component (x)."""
    f = 0.5 * cfg.width / np.tan(np.deg2rad(cfg.hfov_deg) / 2)
    u = np.arange(cfg.width) - (cfg.width - 1) / 2
    v = np.arange(cfg.height) - (cfg.height - 1) / 2
    U, V = np.meshgrid(u, v)
    rays = np.stack([np.full(U.shape, f), -U, -V], -1).reshape(-1, 3)  # x fwd, y left, z up
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    return rays, rays[:, 0]


def _flying_and_holes(z: np.ndarray, cfg: RgbdConfig, rng: np.random.Generator) -> np.ndarray:
    """Depth image (H,W) with edge holes and flying pixels applied (NaN = hole)."""
    out = z.copy()
    for axis in (0, 1):
        for shift in (1, -1):
            nb = np.roll(z, shift, axis=axis)
            jump = np.abs(nb - z) > cfg.edge_jump_m
            jump &= np.isfinite(z) & np.isfinite(nb)
            near_side = jump & (z > nb)  # the background pixel next to a foreground edge
            fly = near_side & (rng.random(z.shape) < cfg.flying_rate / 2)
            mix = rng.random(z.shape)
            out = np.where(fly, nb + mix * (z - nb), out)
            hole = jump & (rng.random(z.shape) < cfg.edge_hole_rate / 2)
            out = np.where(hole, np.nan, out)
    return out


def simulate_rgbd(scene: Scene, T_world_sensor: np.ndarray, cfg: RgbdConfig,
                  rng: np.random.Generator) -> Cloud:
    """One RGB-D depth frame back-projected to a cloud in the sensor frame, metres."""
    D, fwd = rgbd_directions(cfg)
    t, refl, cosi = cast_rays(scene, T_world_sensor, D, cfg.max_range_m / max(fwd.min(), 0.1))
    z = t * fwd  # depth along the optical axis
    z = np.where(np.isfinite(z) & (z >= cfg.min_range_m) & (z <= cfg.max_range_m), z, np.nan)
    z = z + cfg.depth_noise_k * np.nan_to_num(z) ** 2 * rng.standard_normal(len(z))
    z = _flying_and_holes(z.reshape(cfg.height, cfg.width), cfg, rng).ravel()
    z[rng.random(len(z)) < cfg.hole_rate] = np.nan
    ok = np.isfinite(z)
    pts = D[ok] * (z[ok] / fwd[ok])[:, None]
    return Cloud(pts, np.clip(refl[ok] * (0.3 + 0.7 * cosi[ok]), 0, None))
