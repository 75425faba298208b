"""A tiny analytic image maker for the image detector's tests (independent of calib_core.synth).

Every pixel is supersampled; a sub-sample belongs to the sphere when its viewing ray (through
the full CameraModel, distortion included) makes an angle below asin(r/d) with the direction
to the centre: the exact silhouette. The sphere is an open mesh (wires in the sphere colour,
holes showing a darkened background), a chain runs up from its top, and the background holds
low-frequency texture and optional distractor discs.
"""

from __future__ import annotations

import cv2
import numpy as np

from calib_core.camera import CameraModel


def make_camera(width=1920, height=1080, f=1200.0, dist=(0, 0, 0, 0, 0)) -> CameraModel:
    K = [[f, 0, width / 2 - 0.5 + 3.2], [0, f, height / 2 - 0.5 - 2.1], [0, 0, 1]]
    return CameraModel(width, height, K, np.array(dist, float), "test")


def make_background(cam: CameraModel, rng: np.random.Generator, texture=12.0) -> np.ndarray:
    """float32 (H,W,3): water-like colour gradient + low-frequency texture."""
    H, W = cam.height_px, cam.width_px
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    base = np.array([40, 110, 100], np.float32) * (0.8 + 0.4 * (1 - yy / H))[..., None]
    base += (xx / W)[..., None] * np.array([10, -10, 5], np.float32)
    small = rng.normal(0, 1, (H // 32 + 2, W // 32 + 2, 3)).astype(np.float32)
    tex = cv2.resize(cv2.GaussianBlur(small, (0, 0), 1.0), (W, H), interpolation=cv2.INTER_CUBIC)
    return np.clip(base + texture * tex, 0, 255).astype(np.float32)


def sphere_pose_at(cam: CameraModel, uv_px, distance_m) -> np.ndarray:
    """Camera-frame centre (3,) whose projection is the raw pixel uv at the given range."""
    ray = cam.rays(np.asarray(uv_px, float)[None, :])[0]
    return ray * distance_m


def render(cam: CameraModel, background: np.ndarray, centre_cam_m, radius_m: float,
           rng: np.random.Generator, colour=(210, 90, 40), mesh=True, chain=True, ss=3,
           blur_px=0.7, noise=2.0, hole_mix=0.45, distractors=(), shading=True,
           light=None) -> tuple[np.ndarray, np.ndarray]:
    """Render one capture; returns (uint8 RGB image, true centre uv_px (2,)).

    distractors: ((u, v, radius_px, (r, g, b)), ...) flat discs drawn on the background.
    light: (unit direction towards the light (3,), camera frame; ambient share) for a matte
    (Lambertian) ball lit from one side: ambient + (1 - ambient) max(0, n . l) of its colour,
    instead of the default view-facing shading.
    """
    img = background.astype(np.float32).copy()
    for (u, v, rr, col) in distractors:
        cv2.circle(img, (int(round(u * 16)), int(round(v * 16))), int(round(rr * 16)),
                   tuple(float(c) for c in col), -1, cv2.LINE_AA, shift=4)
    C = np.asarray(centre_cam_m, float)
    d = np.linalg.norm(C)
    w, a = C / d, np.arcsin(radius_m / d)
    e1 = np.cross(w, [1.0, 0, 0]); e1 /= np.linalg.norm(e1); e2 = np.cross(w, e1)
    phi = np.linspace(0, 2 * np.pi, 360, endpoint=False)
    ring = np.cos(a * 1.02) * w + np.sin(a * 1.02) * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
    sil = cam.project(ring)
    H, W = cam.height_px, cam.width_px
    x0, y0 = np.floor(np.nanmin(sil, axis=0) - 3).astype(int)
    x1, y1 = np.ceil(np.nanmax(sil, axis=0) + 3).astype(int)
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, W - 1), min(y1, H - 1)
    if x1 > x0 and y1 > y0:
        off = (np.arange(ss) + 0.5) / ss - 0.5
        ys, xs = np.mgrid[y0:y1 + 1, x0:x1 + 1]
        su = (xs[..., None, None] + off[None, None, None, :]).repeat(ss, axis=2)
        sv = (ys[..., None, None] + off[None, None, :, None]).repeat(ss, axis=3)
        uv = np.column_stack([su.ravel(), sv.ravel()])
        # exact lens inverse on the pixel-corner grid, bilinear inside each pixel (the
        # distortion is smooth: the interpolation error is ~1e-6 px)
        gy, gx = np.mgrid[y0 - 0.5:y1 + 1.0:1.0, x0 - 0.5:x1 + 1.0:1.0]
        gxy = cam.normalize(np.column_stack([gx.ravel(), gy.ravel()])).reshape(gx.shape + (2,))
        fx, fy = uv[:, 0] - (x0 - 0.5), uv[:, 1] - (y0 - 0.5)
        ix = np.clip(np.floor(fx).astype(int), 0, gx.shape[1] - 2)
        iy = np.clip(np.floor(fy).astype(int), 0, gx.shape[0] - 2)
        tx, ty = (fx - ix)[:, None], (fy - iy)[:, None]
        xy = ((1 - ty) * ((1 - tx) * gxy[iy, ix] + tx * gxy[iy, ix + 1])
              + ty * ((1 - tx) * gxy[iy + 1, ix] + tx * gxy[iy + 1, ix + 1]))
        rays = np.column_stack([xy, np.ones(len(xy))])
        rays /= np.linalg.norm(rays, axis=1, keepdims=True)
        inside = rays @ w > np.cos(a)
        col = np.zeros((len(uv), 3))
        bgpix = img[np.clip(np.round(uv[:, 1]).astype(int), 0, H - 1),
                    np.clip(np.round(uv[:, 0]).astype(int), 0, W - 1)]
        col[:] = bgpix
        if inside.any():
            rv = rays[inside]
            b = rv @ C
            t = b - np.sqrt(np.maximum(b * b - (d * d - radius_m ** 2), 0))
            P = rv * t[:, None] - C
            lon = np.arctan2(P[:, 0], P[:, 2])
            lat = np.arcsin(np.clip(-P[:, 1] / radius_m, -1, 1))
            shade = 0.75 + 0.25 * np.clip(-(P @ w) / radius_m, 0, 1) if shading else np.ones(len(P))
            if light is not None:
                to_light, ambient = np.asarray(light[0], float), float(light[1])
                shade = ambient + (1 - ambient) * np.clip(P @ to_light / radius_m, 0, None)
            sph = np.asarray(colour, float)[None, :] * shade[:, None]
            if mesh:
                sp = np.deg2rad(15.0)
                wire = (np.abs(((lon / sp) + 0.5) % 1 - 0.5) < 0.12) | (np.abs(((lat / sp) + 0.5) % 1 - 0.5) < 0.12)
                hole = hole_mix * np.asarray(colour, float) * 0.5 + (1 - hole_mix) * bgpix[inside] * 0.8
                sph = np.where(wire[:, None], sph, hole)
            col[inside] = sph
        col = col.reshape(y1 - y0 + 1, x1 - x0 + 1, ss * ss, 3).mean(axis=2)
        img[y0:y1 + 1, x0:x1 + 1] = col
    if chain:
        top = cam.project((C + np.array([0, -radius_m, 0]))[None, :])[0]
        if np.isfinite(top).all():
            p0 = (int(round(top[0] * 16)), int(round((top[1] + 2) * 16)))
            p1 = (int(round((top[0] + 15) * 16)), -16)
            cv2.line(img, p0, p1, (25.0, 25.0, 30.0), 3, cv2.LINE_AA, shift=4)
    if blur_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur_px)
    img = img + rng.normal(0, noise, img.shape).astype(np.float32)
    return np.clip(np.round(img), 0, 255).astype(np.uint8), cam.project(C[None, :])[0]


def test_render_silhouette_matches_cone():
    """The maker's coverage edge lies on the exact cone (so the detector tests are meaningful)."""
    rng = np.random.default_rng(1)
    cam = make_camera(640, 480, 500.0, (-0.2, 0.05, 0, 0, 0))
    bg = np.zeros((480, 640, 3), np.float32)
    C = sphere_pose_at(cam, (480, 120), 1.5)
    img, uv = render(cam, bg, C, 0.11, rng, colour=(255, 255, 255), mesh=False, chain=False,
                     blur_px=0, noise=0, ss=4, shading=False)
    assert np.allclose(uv, cam.project(C[None, :])[0])
    # total coverage ~ area of the projected silhouette (shoelace on the distorted outline)
    d = np.linalg.norm(C); w = C / d; a = np.arcsin(0.11 / d)
    e1 = np.cross(w, [1.0, 0, 0]); e1 /= np.linalg.norm(e1); e2 = np.cross(w, e1)
    phi = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
    sil = cam.project(np.cos(a) * w + np.sin(a) * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2))
    area = 0.5 * abs(np.dot(sil[:, 0], np.roll(sil[:, 1], 1)) - np.dot(sil[:, 1], np.roll(sil[:, 0], 1)))
    cover = img[..., 0].astype(float).sum() / 255.0
    assert abs(cover - area) / area < 0.01
