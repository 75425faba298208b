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

KINDS = ("brick", "tiles", "noise", "foam", "grass", "gravel", "asphalt", "sand")


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


def band_noise(p: np.ndarray, scale_m: float, seed: int) -> np.ndarray:
    """Smooth band-limited noise (N,), about unit variance, at points p (N,3)."""
    return _sines(p, scale_m, seed)


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
    if kind in OUTDOOR:
        return np.clip(OUTDOOR[kind](p_world, n_world, scale_m, contrast, seed), 0.05, None)
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


def _cells(u: np.ndarray, v: np.ndarray, size: float, seed: int):
    """Jittered-grid cells of side ``size``: (distance to the nearest cell point / size, its
    random tone in [0,1), second-nearest distance / size): stones, pebbles."""
    i0, j0 = np.floor(u / size), np.floor(v / size)
    d1 = np.full(len(u), np.inf)
    d2 = np.full(len(u), np.inf)
    tone = np.zeros(len(u))
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            i, j = i0 + di, j0 + dj
            cu = (i + 0.15 + 0.7 * _hash01(i, j, seed)) * size
            cv = (j + 0.15 + 0.7 * _hash01(j, i, seed + 7)) * size
            d = np.hypot(u - cu, v - cv) / size
            closer = d < d1
            d2 = np.where(closer, d1, np.minimum(d2, d))
            tone = np.where(closer, _hash01(i, j, seed + 13), tone)
            d1 = np.where(closer, d, d1)
    return d1, tone, d2


def _grass(p, n, scale_m, contrast, seed):
    """Grass: fine high-contrast blade noise (anisotropic, stretched along one ground axis)
    over a patchy lighter / darker lawn."""
    u, v = _surface_uv(p, n)
    q = np.column_stack([u * 6.0, v, np.zeros(len(u))])
    blades = np.tanh(2.0 * _sines(q, scale_m * 0.4, seed, 10))
    patch = np.tanh(_sines(p, scale_m * 20, seed + 1))
    return 1.0 + contrast * (0.45 * blades + 0.25 * patch)


def _gravel(p, n, scale_m, contrast, seed):
    """Gravel: stones of random tone (jittered-grid cells) with dark gaps between them."""
    u, v = _surface_uv(p, n)
    d1, tone, d2 = _cells(u, v, scale_m, seed)
    gap = (d2 - d1) < 0.08
    return np.where(gap, 1.0 - 0.7 * contrast, 1.0 + contrast * (0.8 * tone - 0.4))


def _asphalt(p, n, scale_m, contrast, seed):
    """Asphalt: fine grain (small bright and dark aggregate specks) on a smooth tone."""
    u, v = _surface_uv(p, n)
    d1, tone, _ = _cells(u, v, scale_m * 0.15, seed)
    speck = np.where(d1 < 0.25, 0.9 * tone - 0.45, 0.0)
    return 1.0 + contrast * (speck + 0.15 * np.tanh(_sines(p, scale_m * 10, seed + 3)))


def _sand(p, n, scale_m, contrast, seed):
    """Sand or rock seabed: wave ripples (a sinusoid across one direction, bent by noise) and
    fine grain; ``scale_m`` the ripple wavelength."""
    u, v = _surface_uv(p, n)
    bend = 0.3 * scale_m * _sines(p, scale_m * 6, seed + 5)
    ripple = np.sin(2 * np.pi * (u * 0.8 + v * 0.6 + bend) / scale_m)
    grain = np.tanh(_sines(p, scale_m * 0.08, seed + 9, 8))
    return 1.0 + contrast * (0.35 * ripple + 0.25 * grain)


OUTDOOR = {"grass": _grass, "gravel": _gravel, "asphalt": _asphalt, "sand": _sand}
