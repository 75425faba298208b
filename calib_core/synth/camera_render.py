"""Camera renderer: one ray per pixel through the real lens model, supersampled at edges.

Pixel (u, v) is the pixel centre (OpenCV convention); a pixel covers [u-0.5, u+0.5].
Rays come from :meth:`CameraModel.normalize` (the exact inverse of the plumb_bob model),
so the sphere centre's ground-truth pixel ``cam.project(X_cam)`` is exactly where the
renderer puts it. Pixels whose 3x3 neighbourhood sees more than one primitive (or the
water) are re-rendered with ``aa x aa`` stratified sub-pixel rays and averaged, so
silhouettes are geometrically exact on average (box-filter anti-aliasing).

Image formation (approximate, the usual underwater model): an object's radiance is
``albedo * light * (ambient + diffuse * max(0, n . up))``; along a path of length t it is
attenuated by ``exp(-c t)`` and veiled by the water's own radiance ``B(direction)``
(backscatter): ``L = L_obj exp(-c t) + B (1 - exp(-c t))``. Rays that hit nothing see
``B``: bright towards the surface and the sun side (backlit), or dark (``dark_water``).
Then Gaussian blur (optics), Poisson-like + read noise, 8-bit quantisation (JPEG is
applied by the writer). By default: no shadows, no caustics, no lens vignetting, Lambertian
balls. An optional :class:`~calib_core.synth.photo.effects.Photo` adds a key light with cast and
contact shadows, a glossy highlight with bloom, ball markings, vignetting and exposure / white
balance shifts (model in :mod:`calib_core.synth.photo.effects`; without one the output is unchanged).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from calib_core.camera import CameraModel
from calib_core.synth.photo import artefacts as camera_artefacts
from calib_core.synth.photo import effects as ph
from calib_core.synth.photo import water as photo_water
from calib_core.synth.scene import Scene, Sphere, raycast
from calib_core.synth.textures import texture_factor


@dataclass(frozen=True)
class Water:
    """Optical water and lighting, world frame (z up).

    attenuation_per_m: beam attenuation c (1/m); 0 = perfectly clear.
    water_rgb: radiance of the water looking horizontally (0-1 scale, 1 = white).
    up_gain: how much brighter the water is looking straight up than horizontally.
    side_dir, side_gain: a horizontal gradient (brighter towards side_dir).
    light_rgb, ambient, diffuse: illumination of objects (from above).
    """

    attenuation_per_m: float = 0.3
    water_rgb: tuple = (0.55, 0.72, 0.70)
    up_gain: float = 0.45
    side_dir: tuple = (1.0, 0.0, 0.0)
    side_gain: float = 0.10
    light_rgb: tuple = (1.0, 1.0, 0.95)
    ambient: float = 0.35
    diffuse: float = 0.65
    attenuation_rgb: tuple | None = None  # per-channel c (1/m), replaces attenuation_per_m
    spot_veil: float = 0.0  # a dive light's glow in the water (see calib_core.synth.photo.water)
    spot_dir: tuple = (1.0, 0.0, 0.0)
    spot_power: float = 10.0

    def veil(self, dirs_world: np.ndarray) -> np.ndarray:
        """Water radiance B (N,3) seen along unit world directions."""
        up = dirs_world[:, 2]
        side = dirs_world @ np.asarray(self.side_dir, float)
        g = np.clip(1.0 + self.up_gain * up + self.side_gain * side, 0.05, None)
        if self.spot_veil > 0:
            g = g + self.spot_veil * np.clip(dirs_world @ np.asarray(self.spot_dir, float), 0, None) ** self.spot_power
        return g[:, None] * np.asarray(self.water_rgb, float)[None, :]


@dataclass(frozen=True)
class RenderOptions:
    """aa: sub-samples per side at edge pixels; blur_sigma_px: optical blur;
    noise_dn: read noise (8-bit DN, 1 sigma); shot_gain: Poisson-like noise scale
    (sigma = sqrt(shot_gain * value_dn)); exposure: multiplies radiance before 8-bit."""

    aa: int = 4
    blur_sigma_px: float = 0.8
    noise_dn: float = 1.5
    shot_gain: float = 0.15
    exposure: float = 1.0


@lru_cache(maxsize=4)  # ~50 MB per 1080p camera
def _pixel_rays_cached(w: int, h: int, K: tuple, dist: tuple, fisheye: bool = False) -> np.ndarray:
    cam = CameraModel(w, h, np.array(K).reshape(3, 3), np.array(dist), fisheye=fisheye)
    u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    return camera_rays(cam, np.column_stack([u.ravel(), v.ravel()]))


def camera_rays(cam: CameraModel, uv_px: np.ndarray) -> np.ndarray:
    """Unit camera-frame rays (N,3) through raw pixels (N,2), via the exact lens inverse.

    Far outside the image a strong distortion polynomial folds back; rays there are
    still finite (Newton from OpenCV's start), but only in-image pixels are used.
    """
    uv = np.asarray(uv_px, float).reshape(-1, 2)
    if cam.fisheye:  # its rays may look beyond 90 deg, where normalised coordinates end
        v = cam.rays(uv)
        return np.where(np.isfinite(v), v, [0.0, 0.0, -1.0])  # past the lens's fold: look backwards
    xy = cam.opencv_normalize(uv, 6)
    with np.errstate(all="ignore"):
        for _ in range(3):  # Newton on the exact forward model (quadratic convergence)
            r = cam.distort(xy) - uv
            J = cam.distort_jacobian(xy)
            det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
            xy = xy - np.column_stack([J[:, 1, 1] * r[:, 0] - J[:, 0, 1] * r[:, 1],
                                       -J[:, 1, 0] * r[:, 0] + J[:, 0, 0] * r[:, 1]]) / det[:, None]
        bad = ~(np.abs(cam.distort(xy) - uv) < 1e-7).all(axis=1)
    if bad.any():  # slow, robust path of the camera model for the few stragglers
        xy[bad] = cam.normalize(uv[bad])
    v = np.column_stack([xy, np.ones(len(xy))])
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def pixel_rays(cam: CameraModel) -> np.ndarray:
    """Camera-frame unit rays (H*W,3) of every pixel centre, row-major (cached per model)."""
    return _pixel_rays_cached(cam.width_px, cam.height_px, tuple(cam.K.ravel()), tuple(cam.dist), cam.fisheye)


def _shade(scene: Scene, water: Water, o_world, d_world, max_range_m, photo: ph.Photo | None = None):
    """Radiance (N,3) and hit ids (N,) of world rays (``photo``: optional key light, shadows,
    gloss and markings)."""
    t, hit, n = raycast(scene, o_world, d_world, acoustic=False, max_range_m=max_range_m)
    B = water.veil(d_world)
    L = B.copy()
    m = hit >= 0
    if m.any():
        alb = scene.albedo()[hit[m]]
        nn = n[m]
        flip = np.einsum("ij,ij->i", nn, d_world[m]) > 0
        nn[flip] *= -1
        p = o_world + d_world[m] * t[m, None] if np.ndim(o_world) == 1 else o_world[m] + d_world[m] * t[m, None]
        if photo is None:
            _apply_textures(scene, hit[m], p, nn, alb)
            lam = water.ambient + water.diffuse * np.clip(nn[:, 2], 0, None)
            Lo = alb * lam[:, None] * np.asarray(water.light_rgb, float)[None, :]
        else:
            Lo = _shade_photo(scene, water, photo, hit[m], p, nn, d_world[m], alb)
        if water.attenuation_rgb is None:
            tr = np.exp(-water.attenuation_per_m * t[m])[:, None]
        else:
            tr = photo_water.attenuation(water, t[m])
        L[m] = Lo * tr + B[m] * (1 - tr)
    return L, hit


def _shade_photo(scene, water, photo, hit, p, n, d, alb):
    """Object radiance under :class:`~calib_core.synth.photo.effects.Photo` lighting (markings first,
    then textures multiply them)."""
    balls = [i for i in scene.ids_with_tag("target") if isinstance(scene.primitives[i], Sphere)]
    is_ball = np.isin(hit, balls)
    if is_ball.any():
        alb[is_ball] = ph.marking_albedo(photo.ball, p[is_ball], alb[is_ball])
    _apply_textures(scene, hit, p, n, alb)
    Lo = ph.shade_lit(photo, alb, p, n, d, is_ball, water.ambient, water.diffuse, water.light_rgb)
    if photo.spot_gain > 0:
        Lo += photo_water.spot_radiance(photo, water, alb, p, n)
    return Lo


def _apply_textures(scene: Scene, hit: np.ndarray, p_world: np.ndarray, n_world: np.ndarray,
                    albedo: np.ndarray) -> None:
    """Multiply ``albedo`` (N,3, in place) by the textures of the primitives hit."""
    for i, prim in enumerate(scene.primitives):
        mat = prim.material
        if not getattr(mat, "texture", ""):
            continue
        sel = hit == i
        if sel.any():
            albedo[sel] *= texture_factor(mat.texture, p_world[sel], n_world[sel], mat.texture_scale_m,
                                          mat.texture_contrast, mat.texture_seed)[:, None]


def render_radiance(scene: Scene, cam: CameraModel, T_world_cam: np.ndarray, water: Water,
                    aa: int = 4, max_range_m: float = 60.0,
                    fine_tags: tuple = ("target", "chain", "stand", "decoy"),
                    photo: ph.Photo | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free linear radiance image (H,W,3) float and the hit-id map (H,W).

    Edge pixels touching primitives tagged ``fine_tags`` get ``aa x aa`` sub-pixel rays,
    other edges 2 x 2.

    ``T_world_cam`` maps camera-frame points (OpenCV) to the world frame.
    """
    H, W = cam.height_px, cam.width_px
    R, c = T_world_cam[:3, :3], T_world_cam[:3, 3]
    d_world = pixel_rays(cam) @ R.T
    L, hit = _shade(scene, water, c, d_world, max_range_m, photo)
    L = L.reshape(H, W, 3)
    hit = hit.reshape(H, W)
    if aa > 1:
        hf = hit.astype(np.float32)
        k = np.ones((3, 3), np.uint8)
        edge = cv2.dilate(hf, k) != cv2.erode(hf, k)
        # full aa x aa at the target's (and its chain's) edges; 2 x 2 elsewhere (cheaper)
        key = np.isin(hit, scene.ids_with_tag(*fine_tags)).astype(np.uint8)
        fine = edge & (cv2.dilate(key, k) > 0)
        for mask, n in ((fine, aa), (edge & ~fine, min(aa, 2))):
            _supersample(scene, cam, R, c, water, max_range_m, mask, n, L, photo)
    return L, hit


def _supersample(scene, cam, R, c, water, max_range_m, mask, aa, L, photo=None):
    """Replace pixels in ``mask`` of radiance image L by the mean of aa x aa sub-pixel rays."""
    vv, uu = np.nonzero(mask)
    if len(uu) == 0:
        return
    n = aa * aa
    off = (np.arange(aa) + 0.5) / aa - 0.5
    ou, ov = np.meshgrid(off, off)
    su = (uu[:, None] + ou.ravel()[None, :]).ravel()
    sv = (vv[:, None] + ov.ravel()[None, :]).ravel()
    acc = np.zeros((len(uu), 3))
    chunk = (400_000 // n) * n  # whole pixels per chunk
    for s in range(0, len(su), chunk):
        rays = camera_rays(cam, np.column_stack([su[s:s + chunk], sv[s:s + chunk]])) @ R.T
        Ls, _ = _shade(scene, water, c, rays, max_range_m, photo)
        acc[s // n: s // n + len(Ls) // n] = Ls.reshape(-1, n, 3).mean(axis=1)
    L[vv, uu] = acc


def finish_image(radiance: np.ndarray, options: RenderOptions, rng: np.random.Generator,
                 photo: ph.Photo | None = None) -> np.ndarray:
    """Blur, sensor noise and 8-bit quantisation of a linear radiance image -> RGB uint8
    (``photo``: vignetting, exposure / white balance and bloom first)."""
    if photo is not None:
        radiance = ph.bloom(ph.apply_lens_and_exposure(radiance, photo) * 255.0, photo) / 255.0
        radiance = camera_artefacts.optical_blur(radiance, photo)
    img = radiance.astype(np.float32) * (255.0 * options.exposure)
    if options.blur_sigma_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), options.blur_sigma_px)
    sigma = np.sqrt(options.noise_dn ** 2 + options.shot_gain * np.clip(img, 0, None))
    img = img + sigma * rng.standard_normal(img.shape, dtype=np.float32)
    img = np.clip(np.round(img), 0, 255).astype(np.uint8)
    return img if photo is None else camera_artefacts.jpeg(img, photo.jpeg_quality)


def render_image(scene: Scene, cam: CameraModel, T_world_cam: np.ndarray, water: Water,
                 options: RenderOptions, rng: np.random.Generator) -> np.ndarray:
    """Render one RGB uint8 image (H,W,3) of ``scene`` seen by ``cam`` at ``T_world_cam``."""
    L, _ = render_radiance(scene, cam, T_world_cam, water, aa=options.aa)
    return finish_image(L, options, rng)
