"""Pictures for the HTML report, drawn with numpy/OpenCV only (no GUI, no matplotlib).

- :func:`oblique_view`: a virtual pinhole camera looking at a cloud from beside a real one.
- :func:`render_points`: z-buffered splat rendering of a coloured point cloud.
- :func:`crop_thumbnail`: a square crop of an image around a pixel.
- :func:`data_uri`: an RGB image as an inline ``data:image/...;base64`` URI.

Frames: ``points_m`` are in any frame F; ``T_view_F`` maps them into the virtual camera's
OpenCV frame (x right, y down, z forward). Images are RGB uint8.
"""

from __future__ import annotations

import base64

import cv2
import numpy as np

from calib_core.camera import CameraModel
from calib_core.geometry import invert_T, look_at_T_cam_world, transform_points


def data_uri(image_rgb: np.ndarray, fmt: str = "jpeg", quality: int = 85) -> str:
    """Encode an RGB uint8 image as a data URI (fmt "jpeg" or "png")."""
    bgr = cv2.cvtColor(np.ascontiguousarray(image_rgb, np.uint8), cv2.COLOR_RGB2BGR)
    ext, params, mime = (".png", [cv2.IMWRITE_PNG_COMPRESSION, 6], "image/png") if fmt == "png" else \
        (".jpg", [cv2.IMWRITE_JPEG_QUALITY, int(quality)], "image/jpeg")
    ok, buf = cv2.imencode(ext, bgr, params)
    if not ok:  # cannot happen for uint8 RGB; keeps the report going if it does
        raise ValueError("image encoding failed")
    return f"data:{mime};base64," + base64.b64encode(buf.tobytes()).decode("ascii")


def fit_width(image_rgb: np.ndarray, max_width: int) -> np.ndarray:
    """Downscale (area filter) so the width is at most ``max_width`` px."""
    h, w = image_rgb.shape[:2]
    if w <= max_width:
        return image_rgb
    s = max_width / w
    return cv2.resize(image_rgb, (max_width, max(1, round(h * s))), interpolation=cv2.INTER_AREA)


def crop_thumbnail(image_rgb: np.ndarray, center_uv_px, half_size_px: float, out_px: int = 200) -> np.ndarray:
    """Square crop (``2*half_size_px`` wide, padded with black outside the image) around a raw
    pixel, resized to ``out_px``; the whole image (letterboxed) when the centre is unknown."""
    h, w = image_rgb.shape[:2]
    if center_uv_px is None or not np.all(np.isfinite(np.asarray(center_uv_px, float))):
        s = out_px / max(h, w)
        small = cv2.resize(image_rgb, (max(1, round(w * s)), max(1, round(h * s))), interpolation=cv2.INTER_AREA)
        out = np.zeros((out_px, out_px, 3), np.uint8)
        y0, x0 = (out_px - small.shape[0]) // 2, (out_px - small.shape[1]) // 2
        out[y0:y0 + small.shape[0], x0:x0 + small.shape[1]] = small
        return out
    hs = max(8.0, float(half_size_px))
    u, v = float(center_uv_px[0]), float(center_uv_px[1])
    s = out_px / (2 * hs)
    # affine map (pixel centres at integers): input u_in -> output x = s (u_in - u + hs) - 0.5,
    # so the crop's centre (out_px / 2 - 0.5) is the given pixel
    M = np.array([[s, 0, s * (hs - u) - 0.5], [0, s, s * (hs - v) - 0.5]])
    interp = cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR
    return cv2.warpAffine(np.ascontiguousarray(image_rgb), M, (out_px, out_px), flags=interp,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0))


def oblique_view(points_m: np.ndarray, T_cam_F: np.ndarray | None, width_px: int = 960, height_px: int = 600,
                 angle_deg: float = 35.0, elevation_deg: float = 15.0) -> tuple[CameraModel, np.ndarray]:
    """A virtual camera that sees the whole cloud from beside a real camera.

    The eye is the real camera's centre rotated by ``angle_deg`` about the cloud's median
    point (around the camera's up axis) and raised by ``elevation_deg``; without a camera
    (``T_cam_F`` None) the eye is placed along the cloud's smallest principal axis.
    The focal length puts the 10th-90th percentile extent of the points in the middle 65 % of the view.
    Returns (camera model, T_view_F).
    """
    P = np.asarray(points_m, float).reshape(-1, 3)
    P = P[np.isfinite(P).all(axis=1)]
    if len(P) == 0:
        P = np.zeros((1, 3))
    c = np.median(P, axis=0)
    if T_cam_F is not None:
        T = np.asarray(T_cam_F, float)
        eye0 = invert_T(T)[:3, 3]
        up = -T[1, :3]  # the camera's -y axis in frame F
    else:
        _, _, vt = np.linalg.svd(P[:: max(1, len(P) // 5000)] - c, full_matrices=False)
        eye0 = c + vt[2] * 3.0 * max(np.ptp(P, axis=0).max(), 0.5)
        up = vt[1]
    d = eye0 - c
    if np.linalg.norm(d) < 1e-6:
        d = np.array([0.0, 0.0, -1.0])
    up = up / max(np.linalg.norm(up), 1e-12)
    d = _rotate(d, up, np.radians(angle_deg))
    side = np.cross(up, d)
    if np.linalg.norm(side) > 1e-9:
        d = _rotate(d, side / np.linalg.norm(side), -np.radians(elevation_deg))
    eye = c + d
    T_view_F = look_at_T_cam_world(eye, c, up)
    X = transform_points(T_view_F, P)
    X = X[X[:, 2] > 1e-3]
    if len(X) == 0:
        f = float(width_px)
        K = [[f, 0, width_px / 2 - 0.5], [0, f, height_px / 2 - 0.5], [0, 0, 1]]
        return CameraModel(width_px, height_px, K, name="view"), T_view_F
    x, y = X[:, 0] / X[:, 2], X[:, 1] / X[:, 2]
    x0, x1 = np.percentile(x, [10, 90])  # the bulk of the points, not the stray returns
    y0, y1 = np.percentile(y, [10, 90])
    f = 0.65 * min(width_px / max(x1 - x0, 1e-6), height_px / max(y1 - y0, 1e-6))
    cx = width_px / 2 - 0.5 - f * (x0 + x1) / 2
    cy = height_px / 2 - 0.5 - f * (y0 + y1) / 2
    return CameraModel(width_px, height_px, [[f, 0, cx], [0, f, cy], [0, 0, 1]], name="view"), T_view_F


def _rotate(v: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues rotation of v about a unit axis."""
    return v * np.cos(angle) + np.cross(axis, v) * np.sin(angle) + axis * (axis @ v) * (1 - np.cos(angle))


def render_points(points_m: np.ndarray, colours_rgb: np.ndarray, cam: CameraModel, T_view_F: np.ndarray,
                  splat_radius_px: int = 1, background=(250, 250, 250), depth_shading: float = 0.35) -> np.ndarray:
    """Render a coloured cloud: each pixel shows the nearest point (z-buffer), points drawn
    as disks of ``splat_radius_px``; ``depth_shading`` darkens far points (0 = none) so shape
    reads without normals. Returns RGB uint8 (H, W, 3)."""
    from calib_core.fusion import project_cloud

    w, h = cam.width_px, cam.height_px
    P = np.asarray(points_m, float).reshape(-1, 3)
    cols = np.asarray(colours_rgb, np.uint8).reshape(-1, 3)
    uv, depth, valid = project_cloud(P, T_view_F, cam)
    out = np.empty((h, w, 3), np.uint8)
    out[:] = np.asarray(background, np.uint8)
    if not valid.any():
        return out
    rows = np.flatnonzero(valid)
    ui = np.clip(np.rint(uv[rows, 0]).astype(np.int64), 0, w - 1)
    vi = np.clip(np.rint(uv[rows, 1]).astype(np.int64), 0, h - 1)
    d = depth[rows].astype(np.float32)
    lo, hi = np.percentile(d, [2, 98])
    shade = 1.0 - depth_shading * np.clip((d - lo) / max(hi - lo, 1e-6), 0, 1)
    c = (cols[rows] * shade[:, None]).astype(np.uint8)
    zimg = np.full(h * w, np.inf, np.float32)
    cimg = np.zeros((h * w, 3), np.uint8)
    r = int(max(0, splat_radius_px))
    offsets = [(dy, dx) for dy in range(-r, r + 1) for dx in range(-r, r + 1) if dx * dx + dy * dy <= r * r + r]
    for dy, dx in offsets:  # splat: every offset of the disk competes in the same z-buffer
        uu, vv = ui + dx, vi + dy
        ok = (uu >= 0) & (uu < w) & (vv >= 0) & (vv < h)
        pix = vv[ok] * w + uu[ok]
        dd = d[ok]
        np.minimum.at(zimg, pix, dd)
        win = dd <= zimg[pix]
        cimg[pix[win]] = c[ok][win]
    hit = np.isfinite(zimg)
    out.reshape(-1, 3)[hit] = cimg[hit]
    return out


def colourise(values: np.ndarray, lo: float | None = None, hi: float | None = None) -> np.ndarray:
    """(N,3) RGB uint8 from scalar values through OpenCV's TURBO colour map."""
    v = np.asarray(values, float).ravel()
    if v.size == 0:
        return np.zeros((0, 3), np.uint8)
    lo = float(np.nanpercentile(v, 2)) if lo is None else lo
    hi = float(np.nanpercentile(v, 98)) if hi is None else hi
    t = np.clip((v - lo) / max(hi - lo, 1e-9), 0, 1)
    idx = np.nan_to_num(t * 255).astype(np.uint8).reshape(-1, 1)
    bgr = cv2.applyColorMap(idx, cv2.COLORMAP_TURBO).reshape(-1, 3)
    return bgr[:, ::-1].copy()
