"""Fuse sonar clouds and camera images with a calibration (the paper's Figs. 3-5).

- :func:`project_cloud`: sonar points -> raw pixels of one camera (eq. 11).
- :func:`segmentation_mask`: pixels within a radius of a reprojected point (Fig. 3).
- :func:`~calib_core.fusion.draw.overlay` and the ``draw_*`` helpers (:mod:`calib_core.fusion.draw`):
  images for people (cv2, anti-aliased).
- :func:`colour_cloud`: each point takes the colour of its pixel, with a splatted
  z-buffer so back surfaces stay uncoloured (Figs. 4 and 5);
  :func:`colour_cloud_multi` picks, per point, the best of several cameras.

Frames and units: ``points_sonar_m`` (N,3) metres in the sonar frame; ``T_cam_sonar``
maps them into the OpenCV camera frame; ``uv_px`` are raw (distorted) pixel
coordinates with pixel centres at integers; ``depth_m`` is the camera-frame z.
Images are RGB uint8 (H,W,3). Everything is vectorised numpy/OpenCV so that a
1M-point cloud at 1920x1080 takes tens of milliseconds (benchmarks/bench_fusion.py).
The z-buffer machinery lives in :mod:`calib_core.fusion.zbuffer`, drawing in :mod:`calib_core.fusion.draw`.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from calib_core.camera import CameraModel
from calib_core.fusion.zbuffer import disk_kernel, pixel_index, visibility_bound

_MAX_REMAP_COLS = 4096  # cv2.remap needs maps smaller than SHRT_MAX per side


# ---------------------------------------------------------------- projection
def _r2_limit(cam: CameraModel) -> float:
    """Cached :func:`_r2_limit_uncached` (thread-safe enough: a race only recomputes)."""
    key = (cam.width_px, cam.height_px, cam.K.tobytes(), cam.dist.tobytes(), cam.fisheye)
    value = _R2_CACHE.get(key)
    if value is None:
        if len(_R2_CACHE) > 64:
            _R2_CACHE.clear()
        value = _R2_CACHE[key] = _r2_limit_uncached(cam)
    return value


_R2_CACHE: dict = {}


def _r2_limit_uncached(cam: CameraModel) -> float:
    """Largest normalised r^2 that any pixel of the image sees (plus 5 %).

    Polynomial distortion folds points far outside the field of view back into
    the image; points beyond this radius cannot be inside the image, so they are
    refused before that fold can happen.
    """
    if not np.any(cam.dist):
        return np.inf
    w, h = cam.width_px, cam.height_px
    s = np.linspace(0.0, 1.0, 33)
    border = np.concatenate([
        np.column_stack([s * (w - 1), np.zeros_like(s)]), np.column_stack([s * (w - 1), np.full_like(s, h - 1)]),
        np.column_stack([np.zeros_like(s), s * (h - 1)]), np.column_stack([np.full_like(s, w - 1), s * (h - 1)]),
    ])
    xy = cam.normalize(border)
    r2 = np.sum(xy * xy, axis=1)
    r2 = r2[np.isfinite(r2)]
    return float(r2.max() * 1.05) if r2.size else np.inf


def _fisheye_scale32(x: np.ndarray, y: np.ndarray, k1234) -> np.ndarray:
    """theta_d / r (float32) of OpenCV's fisheye model at normalised (x, y); 1 on the axis."""
    k1, k2, k3, k4 = (np.float32(c) for c in k1234)
    r = np.sqrt(x * x + y * y)
    th = np.arctan(r)
    t2 = th * th
    poly = t2 * k4
    poly += k3
    poly *= t2
    poly += k2
    poly *= t2
    poly += k1
    poly *= t2
    poly += np.float32(1.0)
    poly *= th
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(r > np.float32(1e-7), poly / r, np.float32(1.0)).astype(np.float32)


def _rational_denominator(r2: np.ndarray, k456) -> np.ndarray:
    """1 + k4 r^2 + k5 r^4 + k6 r^6 (float32) of OpenCV's rational model."""
    k4, k5, k6 = (np.float32(c) for c in k456)
    den = r2 * k6
    den += k5
    den *= r2
    den += k4
    den *= r2
    den += np.float32(1.0)
    return den


def project_cloud(points_sonar_m: np.ndarray, T_cam_sonar: np.ndarray, cam: CameraModel,
                  margin_px: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Project sonar-frame points into a camera's raw image (the paper's eq. 11).

    Args:
        points_sonar_m: (N,3) points in the sonar frame, metres.
        T_cam_sonar: 4x4 transform sonar -> camera.
        cam: camera intrinsics (plumb_bob distortion).
        margin_px: shrink the accepted image area by this many pixels.

    Returns:
        uv_px (N,2) float32 raw pixels (NaN where not valid), depth_m (N,) float32
        camera-frame z in metres, valid (N,) bool: in front of the camera (z > 1 mm),
        inside the image and inside the radius the lens really images.

    For speed the rigid transform runs in float64 and the lens model in float32:
    pixels agree with :meth:`CameraModel.project` to ~1e-3 px (use that for single points).
    """
    u, v, z, valid, _, _ = _project(points_sonar_m, T_cam_sonar, cam, margin_px)
    uv = np.empty((len(z), 2), np.float32)
    uv[:, 0] = np.where(valid, u, np.nan)
    uv[:, 1] = np.where(valid, v, np.nan)
    return uv, z, valid


def _distort32(x: np.ndarray, y: np.ndarray, cam: CameraModel) -> tuple[np.ndarray, np.ndarray]:
    """Distorted normalised (xd, yd), float32, of normalised undistorted (x, y): the lens model
    of ``cam`` (fisheye, or plumb_bob / rational), in place where it can for speed."""
    f32 = np.float32
    if cam.fisheye:
        s = _fisheye_scale32(x, y, cam.dist)
        return x * s, y * s
    k1, k2, p1, p2, k3 = (f32(c) for c in cam.dist[:5])
    r2 = x * x
    r2 += y * y
    radial = r2 * k3
    radial += k2
    radial *= r2
    radial += k1
    radial *= r2
    radial += f32(1.0)
    if cam.rational:
        radial /= _rational_denominator(r2, cam.dist[5:])
    xy2 = x * y
    xy2 *= f32(2.0)
    xd = x * radial
    xd += p1 * xy2
    xd += p2 * (r2 + f32(2.0) * x * x)
    yd = y * radial
    yd += p2 * xy2
    yd += p1 * (r2 + f32(2.0) * y * y)
    return xd, yd


def _project(points_sonar_m, T_cam_sonar, cam: CameraModel, margin_px: float = 0.0):
    """float32 (u, v, z, valid, x, y): raw pixels, depth, validity, normalised undistorted coords."""
    P = np.ascontiguousarray(points_sonar_m, dtype=np.float64).reshape(-1, 1, 3)
    T = np.asarray(T_cam_sonar, dtype=np.float64)
    Pc = cv2.transform(P, T[:3, :4]).reshape(-1, 3) if len(P) else np.zeros((0, 3))
    z = Pc[:, 2].astype(np.float32)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        front = z > 1e-3
        inv = np.float32(1.0) / z
        x = Pc[:, 0].astype(np.float32)
        x *= inv
        y = Pc[:, 1].astype(np.float32)
        y *= inv
        f32 = np.float32
        if cam.fisheye or np.any(cam.dist):
            # points beyond the image's largest radius: refused before the polynomial can fold them back in
            ok = front & (x * x + y * y <= f32(min(_r2_limit(cam), 1e30)))
            xd, yd = _distort32(x, y, cam)
        else:
            ok, xd, yd = front, x, y
        u = xd * f32(cam.fx)
        u += f32(cam.cx)
        if cam.K[0, 1] != 0:
            u += f32(cam.K[0, 1]) * yd
        v = yd * f32(cam.fy)
        v += f32(cam.cy)
        lo = f32(-0.5 + margin_px)
        valid = ok & (u >= lo) & (u <= f32(cam.width_px - 0.5 - margin_px)) & (v >= lo) & (v <= f32(cam.height_px - 0.5 - margin_px))
    return u, v, z, valid, x, y


# -------------------------------------------------------------- segmentation
def segmentation_mask(cam: CameraModel, uv_px: np.ndarray, radius_px: float,
                      valid: np.ndarray | None = None) -> np.ndarray:
    """Pixels within ``radius_px`` of a reprojected point (the paper's Fig. 3).

    Args:
        cam: gives the image size.
        uv_px: (N,2) raw pixels, e.g. from :func:`project_cloud` (NaN/outside entries are ignored).
        radius_px: radius in pixels (>= 0).
        valid: optional (N,) mask of points to use (``project_cloud``'s, which saves a check).

    Returns: bool (H,W). Points are snapped to their nearest pixel centre first
    (an approximation of at most 0.71 px), then grown by an exact disk (radius <= 8 px)
    or by a Euclidean distance transform (larger radii, ~2 % accurate).
    """
    w, h = cam.width_px, cam.height_px
    uv = np.asarray(uv_px).reshape(-1, 2)
    ok = cam.in_image(uv) if valid is None else np.asarray(valid, bool).reshape(-1) & np.isfinite(uv[:, 0])
    _, _, pix = pixel_index(uv, ok, w, h)
    occ = np.zeros(h * w + 1, np.uint8)
    occ[pix] = 1
    occ = occ[:-1].reshape(h, w)
    r = max(0.0, float(radius_px))
    if r < 1.0:
        return occ.astype(bool)
    if r <= 8.0:
        return cv2.dilate(occ, disk_kernel(r)).view(bool)
    dist = cv2.distanceTransform(np.where(occ > 0, 0, 255).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_5)
    return dist <= r


# ------------------------------------------------------------------ colouring
def visible_points(uv_px, depth_m, valid, cam: CameraModel, splat_radius_px="auto",
                   depth_tolerance_m: float = 0.05, slope: float = 1.0) -> np.ndarray:
    """(N,) bool: valid points within a depth tolerance of the splatted nearest depth
    (``splat_radius_px``: a number of pixels, or "auto", see :func:`calib_core.fusion.zbuffer.depth_buffer`).

    The tolerance is ``depth_tolerance_m`` plus ``slope`` x the occluder's lateral reach in metres
    (reach_px x depth / fx): a surface inclined by atan(slope) (45 deg by default) must not
    hide its own points under its splats. Three tests, all must pass: against the splatted
    depth with the splat radius as reach, and against the unsplatted nearest depth of the
    point's own pixel (reach 1.4 px) and of its 3x3 pixel block (reach 2.8 px). The last two
    keep a wide splat's tolerance (24 px at 4.5 m and fx 385: 0.33 m) from letting through a
    back surface right behind a front point. Approximation: the splat radius used is the one
    of the cell (or the fixed one) where the point falls, not the occluder's.
    """
    w, h = cam.width_px, cam.height_px
    uv = np.asarray(uv_px).reshape(-1, 2)
    valid = np.asarray(valid, bool)
    depth32 = np.asarray(depth_m, np.float32)
    _, _, pix = pixel_index(uv, valid, w, h)
    bound = visibility_bound(pix, depth32, w, h, splat_radius_px, depth_tolerance_m, slope / cam.fx)
    with np.errstate(invalid="ignore"):
        vis = depth32 <= bound[pix]
    vis &= valid
    return vis


def sample_bilinear(image_rgb: np.ndarray, uv_px: np.ndarray) -> np.ndarray:
    """(N,C) uint8 bilinear samples of an image at raw pixels (border pixels replicated;
    NaN pixels sample pixel (0, 0))."""
    uv = np.asarray(uv_px, np.float32).reshape(-1, 2)
    n = len(uv)
    cols = min(_MAX_REMAP_COLS, max(n, 1))
    rows = -(-max(n, 1) // cols)
    pad = np.zeros((rows * cols, 2), np.float32)
    pad[:n] = uv
    np.nan_to_num(pad[:n], copy=False, nan=0.0)
    img = np.ascontiguousarray(image_rgb)
    out = cv2.remap(img, pad.reshape(rows, cols, 2), None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return out.reshape(rows * cols, -1)[:n]


def colour_cloud(points_sonar_m: np.ndarray, image_rgb: np.ndarray, cam: CameraModel, T_cam_sonar: np.ndarray,
                 occlusion: bool = True, splat_radius_px="auto", depth_tolerance_m: float = 0.05,
                 fallback=(0, 0, 0), projection=None) -> tuple[np.ndarray, np.ndarray]:
    """Colour each sonar point from one camera image (the paper's Figs. 4 and 5).

    Args:
        points_sonar_m: (N,3) sonar-frame points, metres.
        image_rgb: (H,W,3) uint8 image of ``cam`` (raw, distorted).
        occlusion: if True, a point takes a colour only when it is (within
            ``depth_tolerance_m``) the nearest surface at its pixel; the z-buffer is
            splatted by ``splat_radius_px`` (px, or "auto": adapted to the local spacing of
            the nearest surface) so back surfaces cannot be seen through the front's gaps.
        projection: optional ``project_cloud(points_sonar_m, T_cam_sonar, cam)`` result,
            to skip projecting again (the workbench projects once for mask and colours).

    Returns: colours (N,3) uint8 (``fallback`` where not coloured) and coloured (N,) bool.
    """
    uv, depth, valid = projection if projection is not None else project_cloud(points_sonar_m, T_cam_sonar, cam)
    coloured = visible_points(uv, depth, valid, cam, splat_radius_px, depth_tolerance_m) if occlusion else valid
    n = len(coloured)
    k = int(np.count_nonzero(coloured))
    if 2 * k >= n:  # most points coloured: sample all (no gather), then select
        samples = sample_bilinear(image_rgb, uv)[:, :3]
        colours = np.where(coloured[:, None], samples, np.asarray(fallback, np.uint8)).astype(np.uint8, copy=False)
    else:
        colours = np.empty((n, 3), np.uint8)
        colours[:] = np.asarray(fallback, np.uint8)
        if k:
            colours[coloured] = sample_bilinear(image_rgb, uv[coloured])[:, :3]
    return colours, coloured


@dataclass(frozen=True)
class CameraView:
    """One camera's image and calibration, for :func:`colour_cloud_multi`."""

    name: str
    image_rgb: np.ndarray
    cam: CameraModel
    T_cam_sonar: np.ndarray


def colour_cloud_multi(points_sonar_m: np.ndarray, views: list[CameraView], occlusion: bool = True,
                       splat_radius_px="auto", depth_tolerance_m: float = 0.05,
                       normals_sonar: np.ndarray | None = None,
                       fallback=(0, 0, 0)) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Colour a cloud from several cameras; per point the best camera that sees it wins.

    "Best": with ``normals_sonar`` (N,3) the most frontal view (largest |cos| between the
    normal and the viewing ray); without normals the nearest camera, range weighted by
    how far off-axis the point is (range / cos(off-axis angle)).

    Returns colours (N,3) uint8, coloured (N,) bool and view_index (N,) int (-1: none).
    """
    P = np.ascontiguousarray(points_sonar_m, np.float64).reshape(-1, 3)
    n = len(P)
    best = np.full(n, np.inf, np.float32)
    view_index = np.full(n, -1, np.int64)
    colours = np.empty((n, 3), np.uint8)
    colours[:] = np.asarray(fallback, np.uint8)
    nrm = None if normals_sonar is None else np.ascontiguousarray(normals_sonar, np.float64).reshape(-1, 1, 3)
    for k, view in enumerate(views):
        u, v, depth, valid, x, y = _project(P, view.T_cam_sonar, view.cam)
        uv = np.column_stack([np.where(valid, u, np.nan), np.where(valid, v, np.nan)])
        seen = visible_points(uv, depth, valid, view.cam, splat_radius_px, depth_tolerance_m) if occlusion else valid
        if not seen.any():
            continue
        q = np.float32(1.0) + x * x + y * y  # |ray|^2 / z^2 for the ray (x, y, 1) z
        if nrm is not None:
            n_cam = cv2.transform(nrm, np.asarray(view.T_cam_sonar, float)[:3, :3]).reshape(-1, 3).astype(np.float32)
            cos = np.abs(n_cam[:, 0] * x + n_cam[:, 1] * y + n_cam[:, 2])
            cos /= np.sqrt(q) * np.linalg.norm(n_cam, axis=1) + np.float32(1e-12)
            score = np.float32(2.0) - cos + np.float32(1e-6) * depth * np.sqrt(q)  # frontal first; range breaks ties
        else:
            score = depth * q  # range^2 / z = range / cos(off-axis angle)
        with np.errstate(invalid="ignore"):
            win = seen & (score < best)
        best = np.where(win, score, best)
        view_index[win] = k
        colours = np.where(win[:, None], sample_bilinear(view.image_rgb, uv)[:, :3], colours)
    return colours, view_index >= 0, view_index
