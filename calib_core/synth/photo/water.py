"""Underwater light of the photographic renderer (opt-in through
:class:`~calib_core.synth.photo.effects.Photo` and :class:`~calib_core.synth.camera_render.Water`).

The model, per effect:

- Colour attenuation growing with range: ``Water.attenuation_rgb`` (1/m per channel, red
  strongest) replaces the scalar ``attenuation_per_m`` in the camera renderer's
  ``L = L_obj exp(-c t) + B (1 - exp(-c t))``: far things turn blue-green and sink into the
  veil (backscatter), so contrast falls with range.
- Caustics: sunlight focused by surface waves. The key (sun) term is multiplied by
  ``1 + g (4 exp(-(n / 0.25)^2) - 1)`` (clipped at 0), n a band-limited noise of wavelength
  ``caustic_scale_m`` evaluated on the point projected along the key direction (the network
  lies on every surface the sun reaches: seabed and the ball's top alike).
- A dive light at ``spot_pos`` pointing along ``spot_dir``: irradiance
  ``spot_gain cos(off-axis)^spot_power max(0, n . l) / d^2 exp(-c d)`` at a surface point d
  away (inverse square, Lambert, the water's attenuation on the way in; the way back out is the
  renderer's); its light scattered by the water column is a veil term
  ``Water.spot_veil cos(view, spot_dir)^spot_power`` times the water colour (the hot spot).
- Marine snow (:func:`marine_snow`): particles near the camera lit by the light: small
  bright discs (defocused: blurred) composited over the radiance, in front of everything.
"""

from __future__ import annotations

import cv2
import numpy as np

from calib_core.synth.textures import band_noise


def caustic_factor(photo, p: np.ndarray) -> np.ndarray:
    """Factor (N,) on the key light at world points p (N,3) for the caustic network."""
    key = np.asarray(photo.key_dir, float)
    key = key / np.linalg.norm(key)
    q = p - np.outer(p @ key, key)
    n = band_noise(q, photo.caustic_scale_m, photo.caustic_seed)
    ridge = np.exp(-(n / 0.25) ** 2)
    return np.clip(1.0 + photo.caustic * (4.0 * ridge - 1.0), 0.0, None)


def attenuation(water, dist_m: np.ndarray) -> np.ndarray:
    """Transmittance (N,3) over path lengths (N,) in ``water`` (per channel when it has one)."""
    c = water.attenuation_rgb if water.attenuation_rgb is not None else (water.attenuation_per_m,) * 3
    return np.exp(-np.asarray(c, float)[None, :] * np.asarray(dist_m, float)[:, None])


def spot_radiance(photo, water, alb: np.ndarray, p: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Radiance (N,3) the dive light adds at surface points p (N,3), normals n, albedo alb."""
    l = np.asarray(photo.spot_pos, float)[None, :] - p
    d = np.maximum(np.linalg.norm(l, axis=1), 0.05)
    lh = l / d[:, None]
    axis = np.asarray(photo.spot_dir, float)
    off = np.clip(-(lh @ (axis / np.linalg.norm(axis))), 0, None) ** photo.spot_power
    e = photo.spot_gain * off * np.clip(np.einsum("ij,ij->i", n, lh), 0, None) / d ** 2
    return alb * e[:, None] * attenuation(water, d)


def marine_snow(L: np.ndarray, rng: np.random.Generator, count: int, radius_px: tuple, level: float,
                blur_px: float) -> np.ndarray:
    """Radiance (H,W,3) with ``count`` particles (radius drawn in ``radius_px``, brightness up
    to ``level``) composited in front; a third sharp, the rest defocused up to ``blur_px``."""
    H, W = L.shape[:2]
    out = L.astype(np.float32).copy()
    for share, blur in ((0.34, 0.0), (0.33, 0.5 * blur_px), (0.33, blur_px)):
        alpha = np.zeros((H, W), np.float32)
        k = int(round(count * share))
        for u, v, r in zip(rng.uniform(0, W, k), rng.uniform(0, H, k), rng.uniform(*radius_px, k)):
            cv2.circle(alpha, (int(u * 4), int(v * 4)), max(1, int(r * 4)), float(rng.uniform(0.3, 1.0)),
                       -1, cv2.LINE_AA, shift=2)
        if blur > 0:
            alpha = cv2.GaussianBlur(alpha, (0, 0), blur)
        alpha = np.clip(alpha, 0, 1)[:, :, None]
        out = out * (1 - alpha) + alpha * np.float32(level)
    return out
