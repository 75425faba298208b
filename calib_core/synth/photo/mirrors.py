"""Flat mirrors seen from under water, for the "tank" image kind: the water surface seen from
below and a glass wall, each reflecting the tank and the ball (a second, flipped copy).

The model, per effect:

- Reflection in a plane (point p, unit normal n): what a pixel sees in the mirror is what a
  camera reflected in the plane sees at the same pixel (the pose ``M T_world_cam``, M the
  reflection ``x -> x - 2 ((x - p) . n) n``, a rotation of determinant -1). The reflected
  render uses the same scene minus the mirror itself and minus anything behind it, so the
  path length and therefore attenuation and veil are those of the folded ray.
- Fresnel reflectance of a water / air boundary (n = 1.33; a thin glass pane is taken as a
  water / air boundary too): unpolarised ``R = (Rs + Rp) / 2`` from the incidence angle;
  past the critical angle (48.8 deg from the normal) total internal reflection, R = 1.
  From under water the surface is then a perfect mirror outside Snell's window and a
  mostly transparent one (R ~ 2 %) inside it.
- Light through the boundary: ``(1 - R) n^2 L_outside`` (radiance grows by n^2 entering the
  denser medium; the whole sky hemisphere is squeezed into Snell's window, which is why it
  is bright), attenuated and veiled over the path from the camera to the boundary.
- Ripples on the surface: a small random slope field s (band-limited noise over the surface,
  amplitude ``ripple`` rad) tilts the normal; the reflected image moves by about
  ``2 f s`` px (f the focal length) and R is taken at the tilted normal, so the mirror image,
  the tiles in it and the window's edge wobble.

Pixels on the mirror take ``R L_reflected + (1 - R) (L_through T + B (1 - T))``; T and B are
the transmittance and veil of the water between the camera and the mirror.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from calib_core.synth.camera_render import pixel_rays, render_radiance
from calib_core.synth.photo import water as photo_water
from calib_core.synth.scene import Scene
from calib_core.synth.textures import band_noise

N_WATER = 1.33


@dataclass(frozen=True)
class Mirror:
    """A flat boundary of the tank: its primitive's tag, a point, the unit normal pointing into
    the water, the radiance seen through it (RGB, outside) and the ripple slope (rad)."""

    tag: str
    point: tuple
    normal: tuple
    outside_rgb: tuple
    ripple: float = 0.0
    ripple_scale_m: float = 0.3
    seed: int = 0


def reflect_pose(T_world_cam: np.ndarray, point, normal) -> np.ndarray:
    """The camera pose reflected in the plane (point, normal) (rotation of determinant -1)."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    M = np.eye(4)
    M[:3, :3] -= 2 * np.outer(n, n)
    M[:3, 3] = 2 * (np.asarray(point, float) @ n) * n
    return M @ np.asarray(T_world_cam, float)


def fresnel_reflectance(cos_i: np.ndarray, n1: float = N_WATER, n2: float = 1.0) -> np.ndarray:
    """Unpolarised reflectance from medium n1 onto n2 at incidence cosines cos_i (1 past the
    critical angle)."""
    ci = np.clip(np.abs(cos_i), 0.0, 1.0)
    st2 = (n1 / n2) ** 2 * (1 - ci * ci)
    ct = np.sqrt(np.clip(1 - st2, 0.0, None))
    rs = ((n1 * ci - n2 * ct) / np.maximum(n1 * ci + n2 * ct, 1e-12)) ** 2
    rp = ((n1 * ct - n2 * ci) / np.maximum(n1 * ct + n2 * ci, 1e-12)) ** 2
    return np.where(st2 >= 1.0, 1.0, 0.5 * (rs + rp))


def _ripple(mirror: Mirror, p_world: np.ndarray) -> np.ndarray:
    """Slope field (N,2) of the ripples at points on the mirror."""
    if mirror.ripple <= 0:
        return np.zeros((len(p_world), 2))
    return mirror.ripple * np.column_stack([band_noise(p_world, mirror.ripple_scale_m, mirror.seed),
                                            band_noise(p_world, mirror.ripple_scale_m, mirror.seed + 1)])


def _on_mirror(cam, T_wc, mirror: Mirror, mask: np.ndarray):
    """World ray directions, path lengths to the mirror and hit points of the pixels in mask."""
    d = (pixel_rays(cam) @ np.asarray(T_wc)[:3, :3].T)[mask.ravel()]
    n = np.asarray(mirror.normal, float) / np.linalg.norm(mirror.normal)
    o = np.asarray(T_wc)[:3, 3]
    t = ((np.asarray(mirror.point, float) - o) @ n) / np.minimum(d @ n, -1e-9)
    return d, t, o + d * t[:, None], n


def _tilted_normals(n: np.ndarray, slope: np.ndarray) -> np.ndarray:
    a = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    nn = n[None, :] + slope[:, :1] * a[None, :] + slope[:, 1:] * b[None, :]
    return nn / np.linalg.norm(nn, axis=1, keepdims=True)


def _warp(L: np.ndarray, mask: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """L with the pixels in mask sampled ``shift`` (N,2 px) away (the ripples' displacement)."""
    H, W = mask.shape
    mx, my = np.meshgrid(np.arange(W, dtype=np.float32), np.arange(H, dtype=np.float32))
    vv, uu = np.nonzero(mask)
    mx[vv, uu] += shift[:, 0].astype(np.float32)
    my[vv, uu] += shift[:, 1].astype(np.float32)
    return cv2.remap(L.astype(np.float32), mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)


def composite_mirror(L, hit, scene: Scene, mirror: Mirror, cam, T_wc, water, photo, aa: int = 3):
    """Radiance L (H,W,3) with the pixels that see ``mirror`` replaced by reflection and
    transmission (see the module doc); ``scene`` is the direct scene, with the mirror in it."""
    ids = scene.ids_with_tag(mirror.tag)
    mask = np.isin(hit, ids)
    if not mask.any():
        return L
    d, t, p, n = _on_mirror(cam, T_wc, mirror, mask)
    inside = Scene(tuple(q for q in scene.primitives if q.tag != mirror.tag and _in_front(q, mirror)))
    Lr, _ = render_radiance(inside, cam, reflect_pose(T_wc, mirror.point, n), water, aa=aa, photo=photo)
    slope = _ripple(mirror, p)
    if mirror.ripple > 0:
        Lr = _warp(Lr, mask, 2.0 * 0.5 * (cam.fx + cam.fy) * slope)
    R = fresnel_reflectance(np.einsum("ij,ij->i", d, _tilted_normals(n, slope)))[:, None]
    tr = photo_water.attenuation(water, t)
    through = N_WATER ** 2 * np.asarray(mirror.outside_rgb, float)[None, :] * tr + water.veil(d) * (1 - tr)
    out = L.copy()
    out[mask] = R * Lr[mask] + (1 - R) * through
    return out


def _in_front(prim, mirror: Mirror) -> bool:
    """Whether a primitive lies on the water's side of the mirror (bounded ones by their centre)."""
    b = prim.bound()
    if b is None:
        return True
    n = np.asarray(mirror.normal, float)
    return float((np.asarray(b[0]) - np.asarray(mirror.point, float)) @ n) > -1e-6
