"""Synthetic image ranges (the sphere's apparent size) for the scale's tests and benchmark.

The range a camera reports is ``R / sin(a)`` with ``a`` the half-angle of the silhouette cone the
image detector fits. An outline bias is injected the way it arises, independently of the
solver's model of it: the true silhouette is drawn in raw pixels (lens distortion included),
every outline point is moved by ``outline_px`` along the outline's outward normal in the image,
and the detector's own cone fit (:func:`calib_core.detect.image.cone.fit_cone`) measures the
half-angle. A relative diameter error (every range times ``k``) and Gaussian range noise
(``rel_sigma`` of the range) are added on top.
"""

from __future__ import annotations

import numpy as np

from calib_core.camera import CameraModel
from calib_core.detect.image.cone import fit_cone, silhouette_uv


def biased_half_angle(cam: CameraModel, P_cam_m: np.ndarray, radius_m: float, outline_px: float,
                      n: int = 180) -> float:
    """Half-angle (rad) the cone fit finds for a sphere at ``P_cam_m`` whose outline is moved
    ``outline_px`` outwards (negative: inwards) in the image."""
    d = float(np.linalg.norm(P_cam_m))
    w, a = P_cam_m / d, float(np.arcsin(radius_m / d))
    if outline_px == 0.0:
        return a
    uv = silhouette_uv(cam, w, a, n=n)
    tang = np.roll(uv, -1, axis=0) - np.roll(uv, 1, axis=0)
    nrm = np.column_stack([tang[:, 1], -tang[:, 0]])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    outward = silhouette_uv(cam, w, a, n=n, offset_rad=1e-4) - uv
    nrm *= np.sign(np.sum(nrm * outward, axis=1))[:, None]
    fit = fit_cone(cam, cam.normalize(uv + outline_px * nrm, iterations=20), start=(w, a))
    return float(fit.a_rad)


def image_ranges(cam: CameraModel, P_cam_m: np.ndarray, radius_m: float, outline_px: float = 0.0, k: float = 1.0,
                 rel_sigma: float = 0.003, rng: np.random.Generator | None = None):
    """(range_m (N,), range_sigma_m (N,)) a camera would report for sphere centres ``P_cam_m`` (N,3)."""
    rng = rng or np.random.default_rng(0)
    a = np.array([biased_half_angle(cam, P, radius_m, outline_px) for P in np.asarray(P_cam_m, float)])
    true = np.linalg.norm(P_cam_m, axis=1)
    sig = rel_sigma * true
    return k * radius_m / np.sin(a) + rng.normal(0, 1, len(a)) * sig, sig
