"""BlueView BV5000-2250-like mechanically scanned 3D imaging sonar.

SONAR FRAME (what the simulated sonar software writes the cloud in): origin at the
acoustic centre, x forward (the middle of the pan sweep), y left, z up (right-handed).
This is deliberately not the camera convention.

One ping is a vertical fan of ``n_beams`` (256) beams, each ``beam_width_deg`` (1 deg)
wide, centre lines spread evenly over ``fan_deg`` (90 deg) of elevation; the head pans
about the sonar z axis in steps of ``pan_step_deg`` over ``pan_span_deg``. All beams start
at the sonar origin (the pan axis passes through the acoustic centre).

Acoustic model (approximate, on purpose simple): each beam casts ``sub_rays`` rays spread
uniformly over its cone (half angle beam_width/2) through the SAME scene and ray caster
as the cameras (:func:`calib_core.synth.scene.raycast`, acoustic view); a sub-ray hit counts
if the primitive's reflectivity reaches ``min_reflectivity``. The beam reports the
NEAREST such hit and places it along the beam's CENTRE line, so a sphere blooms (looks
bigger and closer). No multipath, no side lobes, no beam pattern weighting, no
incidence-angle dependence of detection; intensity is reflectivity times an incidence
factor plus noise. Reported range = (true range + noise) * range_scale, quantised.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_core.io.clouds import Cloud
from calib_core.synth.scene import Scene, raycast


@dataclass(frozen=True)
class SonarConfig:
    """Scan parameters (degrees for angles, metres for ranges)."""

    n_beams: int = 256
    fan_deg: float = 90.0
    beam_width_deg: float = 1.0
    pan_span_deg: float = 90.0
    pan_step_deg: float = 0.5
    pan_center_deg: float = 0.0
    sub_rays: int = 19
    min_reflectivity: float = 0.3
    min_range_m: float = 0.3
    max_range_m: float = 12.0
    range_noise_m: float = 0.003
    range_quantum_m: float = 0.002
    range_scale: float = 1.0
    spurious_rate: float = 0.002
    intensity_noise: float = 0.05


def _ring_sizes(m: int) -> list[int]:
    """Points per concentric ring for m off-axis rays: in proportion to each ring's share of
    the disc's area, at least 3 per ring (fewer only when m < 3)."""
    rings = max(1, int(np.sqrt(m / 3.0)))
    sizes = [max(3, int(m * (2 * j - 1) / rings**2)) for j in range(1, rings + 1)]
    sizes[-1] = m - sum(sizes[:-1])
    return sizes


def cone_offsets(n: int, half_angle_rad: float) -> np.ndarray:
    """(n,2) angular offsets (rad) filling a cone evenly and isotropically: the centre ray when n
    is odd, then concentric rings of evenly spaced rays (each ring's share of the disc's area,
    the outer ring on the cone's edge). A ring of k >= 3 evenly spaced rays averages exactly on
    the axis and spreads equally in every direction; a plain sunflower's few points average
    0.01-0.03 deg off the axis (tilting every simulated beam, and the truth, by that much) and
    a point-symmetric sunflower of 13 still spreads 1.6x more along one axis than the other."""
    if n <= 1:
        return np.zeros((1, 2))
    sizes = _ring_sizes(n - n % 2)
    cum = np.cumsum(sizes)
    parts = [np.zeros((n % 2, 2))]
    for j, (k, c) in enumerate(zip(sizes, cum)):
        r = half_angle_rad * np.sqrt(c / cum[-1])
        a = 2 * np.pi * np.arange(k) / k + j * np.pi * (3 - np.sqrt(5))
        parts.append(np.column_stack([r * np.cos(a), r * np.sin(a)]))
    return np.vstack(parts)


def beam_directions(azimuth_rad: np.ndarray, elevation_rad: np.ndarray) -> np.ndarray:
    """Unit sonar-frame directions for azimuth (about z, from x towards y) and elevation."""
    az, el = np.broadcast_arrays(azimuth_rad, elevation_rad)
    ce = np.cos(el)
    return np.stack([ce * np.cos(az), ce * np.sin(az), np.sin(el)], axis=-1)


def scan_angles(cfg: SonarConfig) -> tuple[np.ndarray, np.ndarray]:
    """(azimuths (P,), elevations (B,)) in radians of the pan steps and beam centre lines."""
    half = cfg.fan_deg / 2 - cfg.fan_deg / (2 * cfg.n_beams)
    el = np.deg2rad(np.linspace(-half, half, cfg.n_beams))
    n_pan = int(round(cfg.pan_span_deg / cfg.pan_step_deg)) + 1
    az = np.deg2rad(cfg.pan_center_deg + cfg.pan_step_deg * (np.arange(n_pan) - (n_pan - 1) / 2))
    return az, el


def _sub_rays(A: np.ndarray, centre: np.ndarray, offs: np.ndarray) -> np.ndarray:
    """(P*B*S,3) unit sonar-frame sub-ray directions: each beam centre line (azimuths ``A``)
    tilted by the cone offsets ``offs`` in the beam's local (azimuth, elevation) tangent frame."""
    e_az = np.stack([-np.sin(A), np.cos(A), np.zeros_like(A)], -1).reshape(-1, 3)
    e_el = np.cross(centre, e_az)  # d centre / d elevation
    e_el /= np.linalg.norm(e_el, axis=1, keepdims=True)
    sub = (np.cos(np.hypot(offs[:, 0], offs[:, 1]))[None, :, None] * centre[:, None, :]
           + np.sinc(np.hypot(offs[:, 0], offs[:, 1]) / np.pi)[None, :, None]
           * (offs[None, :, 0, None] * e_az[:, None, :] + offs[None, :, 1, None] * e_el[:, None, :]))
    sub /= np.linalg.norm(sub, axis=2, keepdims=True)
    return sub.reshape(-1, 3)


def _beam_returns(t, hit, n, d_world, refl, n_beams: int, n_sub: int, cfg: SonarConfig, rng) -> tuple:
    """One batch of beams: the first strong return among each beam's sub-rays, plus spurious
    returns. Returns (kept beams mask, their reported ranges, their intensities)."""
    strong = (hit >= 0) & (refl[hit] >= cfg.min_reflectivity) & (t >= cfg.min_range_m)
    t = np.where(strong, t, np.inf).reshape(n_beams, n_sub)
    j = np.argmin(t, axis=1)
    rows = np.arange(n_beams)
    rng_m = t[rows, j]
    ok = np.isfinite(rng_m)
    hid = hit.reshape(n_beams, n_sub)[rows, j]
    nn = n.reshape(n_beams, n_sub, 3)[rows, j]
    dsub = d_world.reshape(n_beams, n_sub, 3)[rows, j]
    cosi = np.abs(np.einsum("ij,ij->i", nn, dsub))
    i_val = refl[hid] * (0.3 + 0.7 * cosi)
    # spurious returns (noise, fish, bubbles): random beams, random ranges
    spur = (~ok) & (rng.random(n_beams) < cfg.spurious_rate)
    rng_m = np.where(spur, rng.uniform(cfg.min_range_m, cfg.max_range_m, n_beams), rng_m)
    i_val = np.where(spur, rng.uniform(0.05, 0.5, n_beams), i_val)
    keep = ok | spur
    r_rep = (rng_m[keep] + cfg.range_noise_m * rng.standard_normal(int(keep.sum()))) * cfg.range_scale
    if cfg.range_quantum_m > 0:
        r_rep = np.round(r_rep / cfg.range_quantum_m) * cfg.range_quantum_m
    return keep, r_rep, np.clip(i_val[keep] + cfg.intensity_noise * rng.standard_normal(int(keep.sum())), 0, None)


def simulate_scan(scene: Scene, T_world_sonar: np.ndarray, cfg: SonarConfig, rng: np.random.Generator,
                  progress=None) -> Cloud:
    """Simulate one full pan scan; returns the cloud in the SONAR frame (x fwd, y left, z up).

    ``T_world_sonar`` maps sonar-frame points to the world frame (metres).
    ``progress(done, total, label)`` is called per pan step batch.
    """
    az, el = scan_angles(cfg)
    offs = cone_offsets(cfg.sub_rays, np.deg2rad(cfg.beam_width_deg) / 2)  # (S,2)
    refl = scene.reflectivity()
    pts, inten = [], []
    batch = max(1, 40_000 // (cfg.n_beams * len(offs)) * 10)
    for s in range(0, len(az), batch):
        A, E = np.meshgrid(az[s:s + batch], el, indexing="ij")  # (P,B)
        centre = beam_directions(A, E).reshape(-1, 3)  # (P*B,3)
        d_world = _sub_rays(A, centre, offs) @ T_world_sonar[:3, :3].T
        t, hit, n = raycast(scene, T_world_sonar[:3, 3], d_world, acoustic=True, max_range_m=cfg.max_range_m)
        keep, r_rep, i_kept = _beam_returns(t, hit, n, d_world, refl, len(centre), len(offs), cfg, rng)
        pts.append(centre[keep] * r_rep[:, None])
        inten.append(i_kept)
        if progress is not None:
            progress(min(s + batch, len(az)), len(az), "sonar scan")
    P = np.concatenate(pts) if pts else np.zeros((0, 3))
    I = np.concatenate(inten) if inten else np.zeros(0)
    return Cloud(P, I)
