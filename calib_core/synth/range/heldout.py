"""Held-out range sensors: physics the detector was never developed against.

Three sensors unlike the 16-ring LiDAR and the Kinect-like camera of :mod:`.sim`, to
measure the range-side detector on data it was not tuned to. Same conventions: the cloud in
the SENSOR frame (x forward, y left, z up, metres), one optical ray per return through the
shared scene (:func:`calib_core.synth.scene.raycast`).

- :class:`Lidar128Config` / :func:`simulate_lidar128`: a 128-ring spinning LiDAR (Ouster
  OS1-128-like). Rings 0.35 deg apart over 45 deg, unevenly (each beam's elevation carries a
  factory-calibration offset), 0.35 deg azimuth steps. Each ring has its own range-noise sigma
  (1-3 cm: the 128 lasers and detectors differ) and its own constant range offset (a few mm),
  and returns drop out independently of the surface's intensity (multi-return and
  ambient-light losses, plus whole azimuth columns lost with lost packets).
- :class:`LivoxConfig` / :func:`simulate_livox`: a solid-state non-repetitive-scan LiDAR
  (Livox Mid-40/Avia-like). Two counter-rotating Risley prisms draw a rosette over a circular
  field; the sweep is accumulated over ``integration_s`` (0.1-1 s, 100k returns/s), so the
  middle of the field is dense and its edges sparse. Range noise a few mm, a small fraction of
  returns dropped.
- :class:`StereoConfig` / :func:`simulate_stereo`: an active-stereo depth camera (RealSense
  D435-like, decimated). Depth from disparity ``d = f b / z``: matching noise of a fraction of
  a pixel in disparity (so depth noise grows with range squared), disparity quantised to
  sub-pixel steps (depth comes in visible steps at range), edge fattening (the matching window
  spreads a foreground surface over 1-2 pixels of background beside it) and flying pixels
  between the two, invalid pixels in the occlusion band the second camera cannot see (left of
  every foreground edge), and holes where the surface is dark (no projected pattern comes back)
  or specular (a surface facing the camera head-on mirrors the projector away).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_core.io.clouds import Cloud
from calib_core.synth.range.sim import cast_rays
from calib_core.synth.scene import Scene, raycast


@dataclass(frozen=True)
class Lidar128Config:
    n_rings: int = 128
    el_min_deg: float = -22.5
    el_max_deg: float = 22.5
    el_jitter_deg: float = 0.05  # per-beam elevation calibration offset (sigma)
    az_step_deg: float = 0.352  # 1024 columns per turn
    az_span_deg: float = 120.0
    noise_min_m: float = 0.01  # per-ring range sigma drawn in [noise_min_m, noise_max_m]
    noise_max_m: float = 0.03
    ring_bias_m: float = 0.004  # per-ring constant range offset (sigma)
    dropout: float = 0.08  # independent of intensity
    column_loss: float = 0.01  # whole azimuth columns lost (packets)
    min_range_m: float = 0.3
    max_range_m: float = 60.0


@dataclass(frozen=True)
class LivoxConfig:
    fov_deg: float = 70.0  # circular field (full angle)
    rate_hz: float = 100_000.0
    integration_s: float = 0.3
    prism_hz: float = 143.0  # outer prism turn rate; the inner one counter-rotates
    prism_ratio: float = -0.93  # inner / outer turn rate: non-commensurate, so the rosette never repeats
    range_noise_m: float = 0.003
    dropout: float = 0.02
    min_range_m: float = 0.5
    max_range_m: float = 40.0


@dataclass(frozen=True)
class StereoConfig:
    width: int = 212  # 848 x 480 decimated by 4
    height: int = 120
    hfov_deg: float = 87.0
    baseline_m: float = 0.05
    subpixel_px: float = 0.03  # disparity matching noise (sigma, decimated pixels)
    disparity_step_px: float = 1.0 / 32.0  # quantisation of the disparity
    fatten_px: int = 1  # edge fattening: foreground spread over this many background pixels
    fatten_rate: float = 0.6
    flying_rate: float = 0.4
    dark_albedo: float = 0.08  # mean albedo under which no pattern comes back (hole)
    specular_cos: float = 0.995  # a surface facing the camera this squarely ...
    specular_rate: float = 0.5  # ... is a hole with this probability
    hole_rate: float = 0.01
    min_range_m: float = 0.3
    max_range_m: float = 6.0


# ---- 128-ring spinning LiDAR --------------------------------------------------------------
def lidar128_directions(cfg: Lidar128Config, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(rings * azimuths, 3) unit rays (sensor frame) and each ray's ring index."""
    el = np.linspace(cfg.el_min_deg, cfg.el_max_deg, cfg.n_rings) + cfg.el_jitter_deg * rng.standard_normal(cfg.n_rings)
    n_az = int(round(cfg.az_span_deg / cfg.az_step_deg)) + 1
    az = np.deg2rad(cfg.az_step_deg * (np.arange(n_az) - (n_az - 1) / 2))
    A, E = np.meshgrid(az, np.deg2rad(el), indexing="ij")
    D = np.stack([np.cos(E) * np.cos(A), np.cos(E) * np.sin(A), np.sin(E)], -1).reshape(-1, 3)
    ring = np.broadcast_to(np.arange(cfg.n_rings), (n_az, cfg.n_rings)).ravel()
    return D, ring


def simulate_lidar128(scene: Scene, T_world_sensor: np.ndarray, cfg: Lidar128Config,
                      rng: np.random.Generator) -> Cloud:
    """One sweep of a 128-ring LiDAR; the cloud in the sensor frame, metres."""
    D, ring = lidar128_directions(cfg, rng)
    sigma = rng.uniform(cfg.noise_min_m, cfg.noise_max_m, cfg.n_rings)
    bias = cfg.ring_bias_m * rng.standard_normal(cfg.n_rings)
    t, refl, cosi = cast_rays(scene, T_world_sensor, D, cfg.max_range_m)
    n_az = len(D) // cfg.n_rings
    column_lost = np.repeat(rng.random(n_az) < cfg.column_loss, cfg.n_rings)
    ok = (np.isfinite(t) & (t >= cfg.min_range_m) & (refl > 0) & ~column_lost
          & (rng.random(len(t)) >= cfg.dropout))
    r = t[ok] + bias[ring[ok]] + sigma[ring[ok]] * rng.standard_normal(int(ok.sum()))
    return Cloud(D[ok] * r[:, None], np.clip(refl[ok] * (0.3 + 0.7 * cosi[ok]), 0, None))


# ---- solid-state rosette LiDAR ----------------------------------------------------------
def livox_directions(cfg: LivoxConfig, rng: np.random.Generator) -> np.ndarray:
    """(N, 3) unit rays of one accumulated rosette scan (sensor frame)."""
    n = int(round(cfg.rate_hz * cfg.integration_s))
    t = rng.uniform(0.0, 1.0) + np.arange(n) / cfg.rate_hz  # the scan starts anywhere in the pattern
    w1 = 2 * np.pi * cfg.prism_hz
    w2 = w1 * cfg.prism_ratio
    half = np.deg2rad(cfg.fov_deg / 2) / 2  # each prism deflects by half the field's radius
    ay = half * (np.cos(w1 * t) + np.cos(w2 * t))
    az = half * (np.sin(w1 * t) + np.sin(w2 * t))
    D = np.stack([np.ones(n), np.tan(ay), np.tan(az)], -1)
    return D / np.linalg.norm(D, axis=1, keepdims=True)


def simulate_livox(scene: Scene, T_world_sensor: np.ndarray, cfg: LivoxConfig,
                   rng: np.random.Generator) -> Cloud:
    """One accumulated rosette scan; the cloud in the sensor frame, metres."""
    D = livox_directions(cfg, rng)
    t, refl, cosi = cast_rays(scene, T_world_sensor, D, cfg.max_range_m)
    ok = (np.isfinite(t) & (t >= cfg.min_range_m) & (refl > 0) & (rng.random(len(t)) >= cfg.dropout))
    r = t[ok] + cfg.range_noise_m * rng.standard_normal(int(ok.sum()))
    return Cloud(D[ok] * r[:, None], np.clip(refl[ok] * (0.3 + 0.7 * cosi[ok]), 0, None))


# ---- active-stereo depth camera ---------------------------------------------------------
def stereo_rays(cfg: StereoConfig) -> tuple[np.ndarray, np.ndarray, float]:
    """(H*W, 3) unit rays (sensor frame), their forward component, the focal length (px)."""
    f = 0.5 * cfg.width / np.tan(np.deg2rad(cfg.hfov_deg) / 2)
    u = np.arange(cfg.width) - (cfg.width - 1) / 2
    v = np.arange(cfg.height) - (cfg.height - 1) / 2
    U, V = np.meshgrid(u, v)
    rays = np.stack([np.full(U.shape, f), -U, -V], -1).reshape(-1, 3)
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    return rays, rays[:, 0], float(f)


def _occlusion_band(disp: np.ndarray, max_shift: int = 24) -> np.ndarray:
    """(H, W) bool: pixels the second camera cannot see. Image columns run from the sensor's
    left (+y) to its right; the second camera sits to the right, so a pixel is hidden when a
    pixel k columns to its right is nearer by at least k pixels of disparity."""
    hidden = np.zeros(disp.shape, bool)
    d = np.nan_to_num(disp, nan=-1e9)
    for k in range(1, max_shift + 1):
        right = np.full(d.shape, -1e9)
        right[:, :-k] = d[:, k:]
        hidden |= right - d >= k - 0.5
    return hidden


def _shifted(img: np.ndarray, shift: int, axis: int) -> np.ndarray:
    """``img`` moved by ``shift`` pixels along ``axis``, the uncovered border -1 (no wrap)."""
    out = np.full(img.shape, -1.0)
    src = [slice(None)] * 2
    dst = [slice(None)] * 2
    src[axis] = slice(None, -shift) if shift > 0 else slice(-shift, None)
    dst[axis] = slice(shift, None) if shift > 0 else slice(None, shift)
    out[tuple(dst)] = img[tuple(src)]
    return out


def _fatten_and_fly(disp: np.ndarray, cfg: StereoConfig, rng: np.random.Generator) -> np.ndarray:
    """Edge fattening (background pixels next to a foreground edge take its disparity) and
    flying pixels (a disparity between the two)."""
    out = disp.copy()
    d = np.nan_to_num(disp, nan=-1.0)
    for axis in (0, 1):
        for shift in range(-cfg.fatten_px, cfg.fatten_px + 1):
            if shift == 0:
                continue
            nb = _shifted(d, shift, axis)
            edge = (nb - d > 1.0) & (d > 0)  # a clearly nearer neighbour
            fat = edge & (rng.random(d.shape) < cfg.fatten_rate / 2)
            out = np.where(fat, nb, out)
            fly = edge & ~fat & (rng.random(d.shape) < cfg.flying_rate / 2)
            out = np.where(fly, d + rng.random(d.shape) * (nb - d), out)
    return out


def simulate_stereo(scene: Scene, T_world_sensor: np.ndarray, cfg: StereoConfig,
                    rng: np.random.Generator) -> Cloud:
    """One active-stereo depth frame back-projected to a cloud in the sensor frame, metres."""
    D, fwd, f = stereo_rays(cfg)
    R, origin = T_world_sensor[:3, :3], T_world_sensor[:3, 3]
    t, hit, n = raycast(scene, origin, D @ R.T, acoustic=False, max_range_m=cfg.max_range_m / max(fwd.min(), 0.1))
    z = t * fwd
    valid = np.isfinite(z) & (z >= cfg.min_range_m) & (z <= cfg.max_range_m)
    disp = np.where(valid, f * cfg.baseline_m / np.where(valid, z, 1.0), np.nan)
    disp = disp + cfg.subpixel_px * rng.standard_normal(len(disp))
    albedo = scene.albedo()[hit].mean(axis=1)
    cosi = np.abs(np.einsum("ij,ij->i", n, D @ R.T))
    hole = (albedo < cfg.dark_albedo) | ((cosi > cfg.specular_cos) & (rng.random(len(z)) < cfg.specular_rate))
    disp = np.where(hole | (rng.random(len(z)) < cfg.hole_rate), np.nan, disp)
    img = disp.reshape(cfg.height, cfg.width)
    hidden = _occlusion_band(img)
    img = _fatten_and_fly(img, cfg, rng)
    img[hidden] = np.nan
    q = np.round(img / cfg.disparity_step_px) * cfg.disparity_step_px
    zq = (f * cfg.baseline_m / np.where(q > 0, q, np.nan)).ravel()
    ok = np.isfinite(zq) & (zq >= cfg.min_range_m) & (zq <= cfg.max_range_m)
    refl = scene.reflectivity()[hit]
    return Cloud(D[ok] * (zq[ok] / fwd[ok])[:, None], np.clip(refl[ok] * (0.3 + 0.7 * cosi[ok]), 0, None))
