"""Fuse sonar clouds and camera images with a calibration (the paper's Figs. 3-5).

- :func:`project_cloud`: sonar points -> raw pixels of one camera (eq. 11).
- :func:`segmentation_mask`: pixels within a radius of a reprojected point (Fig. 3).
- :func:`overlay` and the ``draw_*`` helpers: images for people (cv2, anti-aliased).
- :func:`colour_cloud`: each point takes the colour of its pixel, with a splatted
  z-buffer so back surfaces stay uncoloured (Figs. 4 and 5);
  :func:`colour_cloud_multi` picks, per point, the best of several cameras.

Frames and units: ``points_sonar_m`` (N,3) metres in the sonar frame; ``T_cam_sonar``
maps them into the OpenCV camera frame; ``uv_px`` are raw (distorted) pixel
coordinates with pixel centres at integers; ``depth_m`` is the camera-frame z.
Images are RGB uint8 (H,W,3). Everything is vectorised numpy/OpenCV so that a
1M-point cloud at 1920x1080 takes tens of milliseconds (benchmarks/bench_fusion.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from calib_core.camera import CameraModel
from calib_core.fusion_draw import draw_detection, draw_ellipse, draw_marker, overlay  # noqa: F401  (public API)

_MAX_REMAP_COLS = 4096  # cv2.remap needs maps smaller than SHRT_MAX per side


# ---------------------------------------------------------------- projection
def _r2_limit(cam: CameraModel) -> float:
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
        k1, k2, p1, p2, k3 = (f32(c) for c in cam.dist)
        ok = front
        if np.any(cam.dist):
            r2 = x * x
            r2 += y * y
            ok = ok & (r2 <= f32(min(_r2_limit(cam), 1e30)))
            radial = r2 * k3
            radial += k2
            radial *= r2
            radial += k1
            radial *= r2
            radial += f32(1.0)
            xy2 = x * y
            xy2 *= f32(2.0)
            xd = x * radial
            xd += p1 * xy2
            xd += p2 * (r2 + f32(2.0) * x * x)
            yd = y * radial
            yd += p2 * xy2
            yd += p1 * (r2 + f32(2.0) * y * y)
        else:
            xd, yd = x, y
        u = xd * f32(cam.fx)
        u += f32(cam.cx)
        if cam.K[0, 1] != 0:
            u += f32(cam.K[0, 1]) * yd
        v = yd * f32(cam.fy)
        v += f32(cam.cy)
        lo = f32(-0.5 + margin_px)
        valid = ok & (u >= lo) & (u <= f32(cam.width_px - 0.5 - margin_px)) & (v >= lo) & (v <= f32(cam.height_px - 0.5 - margin_px))
    return u, v, z, valid, x, y


def _pixels(uv_px: np.ndarray, valid: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest pixel (ui, vi) of each point and its flat index (``width*height`` for invalid points)."""
    with np.errstate(invalid="ignore"):
        ui = (uv_px[:, 0] + np.float32(0.5)).astype(np.int32)
        vi = (uv_px[:, 1] + np.float32(0.5)).astype(np.int32)
    np.clip(ui, 0, width - 1, out=ui)
    np.clip(vi, 0, height - 1, out=vi)
    pix = vi.astype(np.int64) * width + ui
    pix[~valid] = width * height
    return ui, vi, pix


def _disk(radius_px: float) -> np.ndarray:
    """Structuring element: the pixel offsets within ``radius_px`` (Euclidean)."""
    r = int(np.floor(radius_px))
    yy, xx = np.mgrid[-r:r + 1, -r:r + 1]
    return (xx * xx + yy * yy <= radius_px * radius_px + 1e-9).astype(np.uint8)


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
    _, _, pix = _pixels(uv, ok, w, h)
    occ = np.zeros(h * w + 1, np.uint8)
    occ[pix] = 1
    occ = occ[:-1].reshape(h, w)
    r = max(0.0, float(radius_px))
    if r < 1.0:
        return occ.astype(bool)
    if r <= 8.0:
        return cv2.dilate(occ, _disk(r)).view(bool)
    dist = cv2.distanceTransform(np.where(occ > 0, 0, 255).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_5)
    return dist <= r


# ------------------------------------------------------------------ colouring
def depth_buffer(uv_px: np.ndarray, depth_m: np.ndarray, valid: np.ndarray, width: int, height: int,
                 splat_radius_px="auto", layer_m: float = 0.05) -> np.ndarray:
    """(H,W) float32 nearest depth (m) per pixel (inf where empty), splatted.

    ``splat_radius_px``: a number splats every point by that radius (a disk up to 2 px, a
    square beyond: see :func:`_splat_kernel`); "auto" adapts it to the local spacing of the
    nearest surface (:func:`_adaptive_splat`, with ``layer_m`` its depth layer).
    """
    uv = np.asarray(uv_px).reshape(-1, 2)
    valid = np.asarray(valid, bool)
    _, _, pix = _pixels(uv, valid, width, height)
    z, _ = _splatted(pix, np.asarray(depth_m, np.float32), width, height, splat_radius_px, layer_m)
    return z[:-1].reshape(height, width)


def _zimage(pix, depth32, width, height) -> np.ndarray:
    z = np.full(height * width + 1, np.inf, np.float32)
    np.minimum.at(z, pix, depth32)
    return z


def _splat_kernel(r: int) -> np.ndarray:
    """Splat footprint: a disk up to 2 px, a square beyond (OpenCV erodes squares ~5x faster;
    the square's corners reach 1.41 r, which only makes occlusion a little more conservative)."""
    return _disk(r) if r <= 2 else np.ones((2 * r + 1, 2 * r + 1), np.uint8)


_RADII = np.array([1, 2, 3, 4, 6, 8, 11, 16, 24])
_CELL_SHIFT = 5  # 32-px cells


def _splatted(pix, depth32, width, height, splat_radius_px, layer_m) -> tuple[np.ndarray, np.ndarray | None]:
    """Flat (H*W+1,) splatted z-buffer (the last slot, for invalid points, is inf) and the
    per-cell radius grid of the adaptive splat (None for a fixed radius)."""
    z = _zimage(pix, depth32, width, height)
    img = z[:-1].reshape(height, width)
    r_cell = None
    if isinstance(splat_radius_px, str):
        if splat_radius_px != "auto":
            raise ValueError(f"splat_radius_px must be a number or 'auto', got {splat_radius_px!r}")
        r_cell = _adaptive_splat(img, layer_m)
    elif int(splat_radius_px) > 0:
        img[:] = cv2.erode(img, _splat_kernel(int(splat_radius_px)), borderType=cv2.BORDER_CONSTANT, borderValue=np.inf)
    z[-1] = np.inf
    return z, r_cell


def _front_counts(padded: np.ndarray, g: int, layer_m: float) -> np.ndarray:
    """Per g-px cell of a padded z-image: occupied pixels within layer_m of the cell's nearest depth."""
    gh, gw = padded.shape[0] // g, padded.shape[1] // g
    blocks = padded[:gh * g, :gw * g].reshape(gh, g, gw, g)
    zc = blocks.min(axis=(1, 3))
    with np.errstate(invalid="ignore"):
        front = blocks <= (zc + np.float32(layer_m))[:, None, :, None]
    front &= np.isfinite(zc)[:, None, :, None]
    return np.count_nonzero(front, axis=(1, 3))


def _adaptive_splat(img, layer_m) -> np.ndarray:
    """Splat the (H,W) z-image in place with a radius that follows the nearest surface's
    spacing; returns the radius per 32-px cell (0: empty cell).

    Per 32-px cell, the occupied pixels within ``layer_m`` of the cell's nearest depth form
    the front layer; their spacing is ~ 32 / sqrt(count), and the cell's pixels are splatted
    by 0.75 x that spacing (a square grid's widest hole is 0.71 x spacing), rounded up to a
    few fixed radii (1-24 px). So a sparse front surface is closed even with a dense wall
    behind it. Fewer than 3 front pixels: the spacing is read on 64-px cells; fewer than 3
    there too, the points are isolated (noise, spurious returns) and get radius 1, so they
    do not hide what lies behind them.
    Approximations: a front surface covering only part of a cell (silhouettes, thin parts)
    looks sparser and is splatted wider, hiding a few more background points near its edges;
    points sharing a pixel count once (dense surfaces get radius 1); the commonest radius
    (if <= 3 px) is applied to every cell in one pass, for speed.
    """
    height, width = img.shape
    g = 1 << _CELL_SHIFT
    gw, gh = -(-width // g) + 1, -(-height // g) + 1  # one spare row/column: the 64-px grid fits
    gw, gh = gw + gw % 2, gh + gh % 2
    padded = np.full((gh * g, gw * g), np.inf, np.float32)
    padded[:height, :width] = img
    blocks = padded.reshape(gh, g, gw, g)
    n = _front_counts(padded, g, layer_m)
    n64 = np.repeat(np.repeat(_front_counts(padded, 2 * g, layer_m), 2, axis=0), 2, axis=1)
    spacing = np.where(n >= 3, g / np.sqrt(np.maximum(n, 1)), 2 * g / np.sqrt(np.maximum(n64, 1)))
    want = np.where((n >= 3) | (n64 >= 3), np.ceil(0.75 * spacing), 1)
    r_cell = _RADII[np.minimum(np.searchsorted(_RADII, want), len(_RADII) - 1)]
    r_cell[n == 0] = 0
    # the commonest small radius splats the whole image in one pass (cells that wanted less get
    # it too: slightly conservative); larger radii follow per cell (few) or per bounding box
    radii, counts = np.unique(r_cell[r_cell > 0], return_counts=True)
    base = int(radii[np.argmax(counts)]) if len(radii) else 1
    base = base if base <= 3 else 1
    src = padded[:height, :width].copy()
    for r in radii[radii > base]:
        rows, cols = np.nonzero(r_cell == r)
        boxes = zip(rows, rows + 1, cols, cols + 1) if len(rows) <= 64 else \
            [(rows.min(), rows.max() + 1, cols.min(), cols.max() + 1)]
        for r0, r1, c0, c1 in boxes:
            _splat_cells(img, blocks, r_cell, int(r), r0, r1, c0, c1)
    np.minimum(img, cv2.erode(src, _splat_kernel(base), borderType=cv2.BORDER_CONSTANT, borderValue=np.inf), out=img)
    r_cell[(r_cell > 0) & (r_cell < base)] = base
    return r_cell


def _splat_cells(img, blocks, r_cell, r, r0, r1, c0, c1) -> None:
    """Erode the pixels of cells [r0:r1, c0:c1] whose radius is r, by r, into img (min)."""
    height, width = img.shape
    g = blocks.shape[1]
    y0, y1 = max(r0 * g - r, 0), min(r1 * g + r, height)
    x0, x1 = max(c0 * g - r, 0), min(c1 * g + r, width)
    part = np.full((y1 - y0, x1 - x0), np.inf, np.float32)
    sel = (r_cell[r0:r1, c0:c1] == r)[:, None, :, None]
    blk = np.where(sel, blocks[r0:r1, :, c0:c1, :], np.float32(np.inf)).reshape((r1 - r0) * g, (c1 - c0) * g)
    oy, ox = r0 * g - y0, c0 * g - x0
    hh, ww = min(blk.shape[0], height - r0 * g), min(blk.shape[1], width - c0 * g)
    part[oy:oy + hh, ox:ox + ww] = blk[:hh, :ww]
    ero = cv2.erode(part, _splat_kernel(r), borderType=cv2.BORDER_CONSTANT, borderValue=np.inf)
    np.minimum(img[y0:y1, x0:x1], ero, out=img[y0:y1, x0:x1])


def visible_points(uv_px, depth_m, valid, cam: CameraModel, splat_radius_px="auto",
                   depth_tolerance_m: float = 0.05, slope: float = 1.0) -> np.ndarray:
    """(N,) bool: valid points within a depth tolerance of the splatted nearest depth
    (``splat_radius_px``: a number of pixels, or "auto", see :func:`depth_buffer`).

    The tolerance is ``depth_tolerance_m`` plus ``slope`` x the splat's lateral reach in metres
    (radius_px x depth / fx): a surface inclined by atan(slope) (45 deg by default) must not
    hide its own points under its splats. Approximation: the radius used is the one of the
    cell (or the fixed one) where the point falls, not the occluder's.
    """
    w, h = cam.width_px, cam.height_px
    uv = np.asarray(uv_px).reshape(-1, 2)
    valid = np.asarray(valid, bool)
    depth32 = np.asarray(depth_m, np.float32)
    ui, vi, pix = _pixels(uv, valid, w, h)
    z, r_cell = _splatted(pix, depth32, w, h, splat_radius_px, depth_tolerance_m)
    if r_cell is None:
        r_pt = np.float32(max(0, int(splat_radius_px)))
    else:
        cell = vi >> _CELL_SHIFT
        cell *= r_cell.shape[1]
        cell += ui >> _CELL_SHIFT
        r_pt = r_cell.astype(np.float32).ravel()[cell]
    zp = z[pix]
    with np.errstate(invalid="ignore"):
        zp += np.float32(depth_tolerance_m) + np.float32(slope / cam.fx) * r_pt * depth32
        vis = depth32 <= zp
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
    samples = sample_bilinear(image_rgb, uv)[:, :3]
    colours = np.where(coloured[:, None], samples, np.asarray(fallback, np.uint8)).astype(np.uint8, copy=False)
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
