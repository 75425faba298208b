"""Opt-in photographic effects for the camera renderer: what real photographs of a ball have
and plain Lambertian renders lack.

A :class:`Photo` passed to :func:`calib_core.synth.camera_render.render_radiance` and
:func:`~calib_core.synth.camera_render.finish_image` switches them on; without one the
renderer is unchanged (byte-identical sessions). The model, per effect:

- Key light: one distant light from unit direction ``key_dir`` (world, towards the light)
  replaces the "from above" diffuse term: ``diffuse * max(0, n . key) * vis``.
- Cast shadow (``vis``): each ``occluders`` sphere (centre, radius) blocks the key light. A
  point p sees the light past a sphere if the ray p + s key (s > 0) misses it; the penumbra
  is linear in the ray's clearance ``(dist(ray, c) - r) / (softness * s)`` (an area light of
  angular radius ~``softness`` rad).
- Contact shadow (ambient occlusion of a sphere): the ambient term is scaled by
  ``1 - ao * r^2 / |c - p|^2 * max(0, n . (c - p) / |c - p|)`` (the exact form factor of a
  sphere seen from a surface element), so the surface right under a resting ball goes dark
  and meets its lower outline.
- Specular highlight (glossy ball, Blinn-Phong): ``ks * max(0, n . h)^shininess * vis`` of the
  light's colour added to the ball's radiance, h = unit(key + view). Radiance above the
  sensor's range is clipped at 255 by the 8-bit step, after a bloom: the excess over 255 is
  Gaussian-blurred (``bloom_px``) and added back (a halo around the highlight).
- Ball markings (:class:`BallLook`, in the ball's own frame: pole ``axis``): ``panels``
  longitudinal gores coloured from ``panel_rgb`` (a beach ball) with white polar caps;
  a dark seam line along the great circle normal to ``seam_dir``; a logo: a patch of text-like
  dark stripes around ``logo_dir``; a valve: a small disc around ``valve_dir``.
- Lens vignetting: radiance times ``1 - vignette * (r / r_corner)^2`` (r from the image
  centre), a cos^4-like fall-off reaching ``1 - vignette`` in the corners.
- Auto-exposure / white balance: radiance times ``exposure * wb_gains`` (per channel) before
  the 8-bit step; the case generator meters the exposure on the frame, as a camera does.
- Sports-ball prints (``BallLook.pattern``: football, basketball, tennis, volleyball; model in
  :mod:`calib_core.synth.photo.ball_patterns`) and a felt's fuzz (``sheen``): the ball's radiance
  gains ``sheen * (1 - |n . v|)^2 * albedo * ambient`` (fibres catching light at grazing view).
- Underwater light (``caustic``, ``spot_*``; with ``Water.attenuation_rgb`` and
  ``Water.spot_veil``): caustics on the key light and a dive light, model in
  :mod:`calib_core.synth.photo.water`.
- Camera artefacts (``defocus_px``, ``shake_px``, ``jpeg_quality``): applied after the bloom and
  after the 8-bit step, model in :mod:`calib_core.synth.photo.artefacts`.
- Motion blur of a carried ball (:func:`motion_composite`): the ball's radiance and its
  coverage are convolved with a centred line kernel ``motion_px`` (dx, dy) and composited over
  a render of the scene without the ball; the true centre is the ball's mid-exposure position.

Everything is vectorised numpy / OpenCV.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from calib_core.synth.photo import ball_patterns
from calib_core.synth.photo import water as photo_water

WHITE = (0.92, 0.92, 0.90)


@dataclass(frozen=True)
class BallLook:
    """Surface of the ball: gloss and markings (all off by default)."""

    centre_m: tuple = (0.0, 0.0, 0.0)
    radius_m: float = 0.1
    ks: float = 0.0  # specular strength (0 = matte)
    shininess: float = 60.0
    axis: tuple = (0.0, 0.0, 1.0)  # pole of the panels
    panels: int = 0  # number of gores (0 = none)
    panel_rgb: tuple = ()  # albedo of each gore, cycled
    cap_deg: float = 12.0  # white polar caps (degrees from the pole)
    seam_dir: tuple | None = None  # normal of the seam's great circle
    seam_width_m: float = 0.004
    logo_dir: tuple | None = None
    logo_deg: float = 18.0
    valve_dir: tuple | None = None
    valve_deg: float = 3.0
    pattern: str = ""  # a sports ball's print (calib_core.synth.photo.ball_patterns), "" = none
    pattern_w: float = 0.02  # its seam half width (rad on the ball)
    pattern_rgb: tuple = ()  # its panel colours where it has several (volleyball)
    sheen: float = 0.0  # felt fuzz: grazing-angle brightening (tennis ball)


@dataclass(frozen=True)
class Photo:
    """Photographic effects of one image (see the module docstring for the model)."""

    key_dir: tuple = (0.0, 0.0, 1.0)
    softness: float = 0.05
    occluders: tuple = ()  # ((centre xyz), radius), ...
    ao: float = 0.9
    ball: BallLook = field(default_factory=BallLook)
    vignette: float = 0.0
    exposure: float = 1.0
    wb_gains: tuple = (1.0, 1.0, 1.0)
    bloom_px: float = 0.0
    bloom_gain: float = 0.6
    caustic: float = 0.0  # strength of the caustic network on the key light (0 = none)
    caustic_scale_m: float = 0.3
    caustic_seed: int = 0
    spot_gain: float = 0.0  # a dive light's irradiance at 1 m on its axis (0 = none)
    spot_pos: tuple = (0.0, 0.0, 0.0)  # world
    spot_dir: tuple = (1.0, 0.0, 0.0)  # world, unit
    spot_power: float = 10.0  # cos^power fall-off off the axis
    defocus_px: float = 0.0  # radius of the defocus disc (0 = in focus)
    shake_px: tuple = ()  # (dx, dy) of the whole frame during the exposure ("" = still)
    jpeg_quality: int = 0  # JPEG round trip at this quality (0 = none)


def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def key_visibility(photo: Photo, p: np.ndarray) -> np.ndarray:
    """Fraction (N,) of the key light reaching points p (N,3) past the occluder spheres."""
    key = _unit(photo.key_dir)
    vis = np.ones(len(p))
    for c, r in photo.occluders:
        cp = np.asarray(c, float)[None, :] - p
        along = cp @ key
        perp = np.linalg.norm(cp - along[:, None] * key[None, :], axis=1)
        width = photo.softness * np.clip(along, 1e-3, None) + 1e-4
        v = np.clip(0.5 + (perp - r) / (2 * width), 0.0, 1.0)
        vis *= np.where(along > 0, v, 1.0)
    return vis


def ambient_occlusion(photo: Photo, p: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Ambient light fraction (N,) left at points p with normals n near the occluder spheres."""
    keep = np.ones(len(p))
    for c, r in photo.occluders:
        cp = np.asarray(c, float)[None, :] - p
        d2 = np.einsum("ij,ij->i", cp, cp)
        cosn = np.einsum("ij,ij->i", n, cp) / np.sqrt(np.maximum(d2, 1e-12))
        f = np.clip(r * r / np.maximum(d2, r * r) * np.clip(cosn, 0, None), 0, 1)
        keep *= 1.0 - photo.ao * f
    return keep


def _ball_frame(look: BallLook):
    a = _unit(look.axis)
    e1 = np.cross(a, [1.0, 0, 0] if abs(a[0]) < 0.9 else [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    return a, e1, np.cross(a, e1)


def marking_albedo(look: BallLook, p: np.ndarray, albedo: np.ndarray) -> np.ndarray:
    """Albedo (N,3) of ball points p (N,3) with the markings of ``look`` painted over."""
    q = (p - np.asarray(look.centre_m, float)[None, :]) / look.radius_m
    out = albedo.copy()
    a, e1, e2 = _ball_frame(look)
    if look.panels > 0 and look.panel_rgb:
        lon = np.arctan2(q @ e2, q @ e1)
        k = np.floor((lon + np.pi) / (2 * np.pi / look.panels)).astype(int) % look.panels
        cols = np.asarray(look.panel_rgb, float)[k % len(look.panel_rgb)]
        cap = np.abs(q @ a) > np.cos(np.deg2rad(look.cap_deg))
        out = np.where(cap[:, None], np.asarray(WHITE)[None, :], cols)
    if look.seam_dir is not None:
        seam = np.abs(q @ _unit(look.seam_dir)) < look.seam_width_m / look.radius_m
        out[seam] *= 0.45
    if look.logo_dir is not None:
        out = _logo(look, q, out)
    if look.valve_dir is not None:
        valve = q @ _unit(look.valve_dir) > np.cos(np.deg2rad(look.valve_deg))
        out[valve] = np.asarray(WHITE) * 0.35
    if look.pattern:
        qb = np.column_stack([q @ e1, q @ e2, q @ a])
        qb /= np.maximum(np.linalg.norm(qb, axis=1, keepdims=True), 1e-12)
        out = ball_patterns.pattern_albedo(look.pattern, qb, out, look.pattern_w, look.pattern_rgb)
    return out


def _logo(look: BallLook, q: np.ndarray, out: np.ndarray) -> np.ndarray:
    """A text-like patch: dark strokes in a band around ``logo_dir``."""
    l = _unit(look.logo_dir)
    t1 = np.cross(l, [0, 0, 1.0] if abs(l[2]) < 0.9 else [1.0, 0, 0])
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(l, t1)
    half = np.sin(np.deg2rad(look.logo_deg))
    x, y = q @ t1 / half, q @ t2 / half
    inside = (q @ l > 0) & (np.abs(x) < 1) & (np.abs(y) < 0.35)
    strokes = (np.sin(x * 9 * np.pi) > 0.2) | (np.abs(y) > 0.25)
    out = out.copy()
    out[inside & strokes] = np.array([0.08, 0.08, 0.10])
    return out


def shade_lit(photo: Photo, alb, p, n, view_dirs, is_ball, ambient, diffuse, light_rgb) -> np.ndarray:
    """Object radiance (N,3) under the key light: Lambert + shadows, Blinn-Phong on the ball."""
    key = _unit(photo.key_dir)
    vis = np.where(is_ball, 1.0, key_visibility(photo, p))
    amb = np.where(is_ball, 1.0, ambient_occlusion(photo, p, n))
    direct = diffuse * np.clip(n @ key, 0, None) * vis
    if photo.caustic > 0:
        direct = direct * photo_water.caustic_factor(photo, p)
    lam = ambient * amb + direct
    light = np.asarray(light_rgb, float)[None, :]
    L = alb * lam[:, None] * light
    if photo.ball.sheen > 0 and is_ball.any():
        grazing = 1.0 - np.abs(np.einsum("ij,ij->i", n[is_ball], view_dirs[is_ball]))
        L[is_ball] += photo.ball.sheen * (grazing ** 2)[:, None] * alb[is_ball] * light * ambient
    if photo.ball.ks > 0 and is_ball.any():
        h = key[None, :] - view_dirs[is_ball]
        h /= np.linalg.norm(h, axis=1, keepdims=True)
        spec = photo.ball.ks * np.clip(np.einsum("ij,ij->i", n[is_ball], h), 0, None) ** photo.ball.shininess
        L[is_ball] += spec[:, None] * light
    return L


def apply_lens_and_exposure(radiance: np.ndarray, photo: Photo) -> np.ndarray:
    """Vignetting, exposure and white balance of a linear radiance image (H,W,3) -> float32."""
    H, W = radiance.shape[:2]
    v, u = np.mgrid[0:H, 0:W].astype(np.float32)
    r2 = ((u - (W - 1) / 2) ** 2 + (v - (H - 1) / 2) ** 2) / (((W - 1) / 2) ** 2 + ((H - 1) / 2) ** 2)
    gain = (1.0 - photo.vignette * r2)[:, :, None] * (photo.exposure * np.asarray(photo.wb_gains, np.float32))
    return radiance.astype(np.float32) * gain.astype(np.float32)


def bloom(img_dn: np.ndarray, photo: Photo) -> np.ndarray:
    """Add the blurred excess over 255 DN back around saturated pixels (halo of a highlight)."""
    if photo.bloom_px <= 0:
        return img_dn
    excess = np.clip(img_dn - 255.0, 0, None)
    return img_dn + photo.bloom_gain * cv2.GaussianBlur(excess, (0, 0), photo.bloom_px)


def motion_kernel(motion_px) -> np.ndarray:
    """Centred normalised line kernel of displacement ``motion_px`` (dx, dy)."""
    dx, dy = (float(x) for x in motion_px)
    n = int(np.ceil(max(abs(dx), abs(dy)))) * 2 + 3
    k = np.zeros((n, n), np.float32)
    c = n // 2
    steps = max(8, int(4 * np.hypot(dx, dy)))
    for s in np.linspace(-0.5, 0.5, steps):  # splat the segment, bilinear
        x, y = c + s * dx, c + s * dy
        x0, y0 = int(np.floor(x)), int(np.floor(y))
        fx, fy = x - x0, y - y0
        k[y0, x0] += (1 - fx) * (1 - fy)
        k[y0, x0 + 1] += fx * (1 - fy)
        k[y0 + 1, x0] += (1 - fx) * fy
        k[y0 + 1, x0 + 1] += fx * fy
    return k / k.sum()


def motion_composite(L: np.ndarray, L_without: np.ndarray, ball_mask: np.ndarray, motion_px) -> np.ndarray:
    """Radiance (H,W,3) of a ball moving by ``motion_px`` during the exposure over a still scene.

    ``L``: render with the ball; ``L_without``: the same scene without it; ``ball_mask``: (H,W)
    coverage of the ball in ``L`` (0-1)."""
    k = motion_kernel(motion_px)
    m = ball_mask.astype(np.float32)
    a = cv2.filter2D(m, -1, k, borderType=cv2.BORDER_CONSTANT)
    ball = cv2.filter2D(L.astype(np.float32) * m[:, :, None], -1, k, borderType=cv2.BORDER_CONSTANT)
    return ball + (1.0 - a)[:, :, None] * L_without.astype(np.float32)
