"""Procedural surface textures for the camera renderer (brick, tiles, noise, foam).

A :class:`~calib_core.synth.primitives.Material` with ``texture`` set multiplies its albedo
by a factor computed from the world position of each hit (and its normal, to pick the two
surface coordinates): real scenes are textured and cluttered, and a detector tested on
flat-coloured scenes only learns to find round blobs on smooth backgrounds.

Approximations: the surface coordinates are the two world axes most orthogonal to the
normal (exact on axis-aligned planes, a projection elsewhere); the noise is a sum of
randomly oriented sinusoids (smooth, band-limited), not Perlin noise. All functions are
vectorised and deterministic (a per-material integer seed).
"""

from __future__ import annotations

import numpy as np

KINDS = ("brick", "tiles", "noise", "foam")


def _surface_uv(p: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two in-surface coordinates (m) per point from the world axes least aligned with n."""
    a = np.abs(n)
    drop = np.argmax(a, axis=1)
    keep = np.array([[1, 2], [0, 2], [0, 1]])[drop]
    u = np.take_along_axis(p, keep[:, :1], axis=1)[:, 0]
    v = np.take_along_axis(p, keep[:, 1:], axis=1)[:, 0]
    return u, v


def _hash01(i: np.ndarray, j: np.ndarray, seed: int) -> np.ndarray:
    """Deterministic pseudo-random [0,1) per integer cell (i, j)."""
    h = (i.astype(np.int64) * 73856093) ^ (j.astype(np.int64) * 19349663) ^ (seed * 83492791)
    h = (h ^ (h >> 13)) * 1274126177
    return ((h ^ (h >> 16)) & 0xFFFF) / 65536.0


def _sines(p: np.ndarray, scale_m: float, seed: int, n: int = 6) -> np.ndarray:
    rng = np.random.default_rng(seed)
    out = np.zeros(len(p))
    for k in range(n):
        d = rng.normal(0, 1, 3)
        d /= np.linalg.norm(d)
        f = 2 * np.pi / (scale_m * rng.uniform(0.3, 1.0))
        out += np.sin(p @ d * f + rng.uniform(0, 2 * np.pi)) / np.sqrt(n)
    return out


def texture_factor(kind: str, p_world: np.ndarray, n_world: np.ndarray, scale_m: float,
                   contrast: float, seed: int) -> np.ndarray:
    """Albedo factor (N,) of texture ``kind`` at world points (N,3) with normals (N,3).

    ``scale_m``: brick height / tile side / noise wavelength; ``contrast``: 0 = flat, 1 = full.
    """
    if kind not in KINDS:
        raise ValueError(f"unknown texture {kind!r}; use one of {KINDS}")
    if kind in ("noise", "foam"):
        f = 1.0 + 0.5 * contrast * np.tanh(_sines(p_world, scale_m, seed))
        return np.clip(f, 0.05, None)
    u, v = _surface_uv(p_world, n_world)
    if kind == "brick":
        row = np.floor(v / scale_m)
        uu = u / (2 * scale_m) + 0.5 * (row % 2)
        col = np.floor(uu)
        mortar = (np.abs(v / scale_m - row - 0.5) > 0.42) | (np.abs(uu - col - 0.5) > 0.46)
        tone = 1.0 + contrast * (0.6 * _hash01(row, col, seed) - 0.3)
        return np.where(mortar, 1.0 + 0.8 * contrast, tone)
    i, j = np.floor(u / scale_m), np.floor(v / scale_m)
    grout = (np.abs(u / scale_m - i - 0.5) > 0.46) | (np.abs(v / scale_m - j - 0.5) > 0.46)
    tone = 1.0 + contrast * (0.4 * _hash01(i, j, seed) - 0.2 + 0.3 * ((i + j) % 2 - 0.5))
    return np.where(grout, 1.0 - 0.6 * contrast, tone)
