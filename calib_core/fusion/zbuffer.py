"""Z-buffers for occlusion in :mod:`calib_core.fusion`: nearest depth per pixel, splatted.

Points are snapped to their nearest pixel; each pixel keeps the nearest depth
(``np.minimum.at``); splatting (an erosion of the depth image, OpenCV) grows each point
to a disk/square so a surface has no holes for farther points to show through. The
"auto" splat adapts the radius to the local spacing of the nearest surface (per 32-px cell).
:func:`visibility_bound` turns them into the farthest depth a point may have at each pixel and
still be seen (splatted and unsplatted tests; :func:`calib_core.fusion.cloud.visible_points`).
Depths are camera-frame z in metres (float32); pixel coordinates raw, centres at integers.
"""

from __future__ import annotations

import cv2
import numpy as np


def pixel_index(uv_px: np.ndarray, valid: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest pixel (ui, vi) of each point and its flat index (``width*height`` for invalid points)."""
    with np.errstate(invalid="ignore"):
        ui = (uv_px[:, 0] + np.float32(0.5)).astype(np.int32)
        vi = (uv_px[:, 1] + np.float32(0.5)).astype(np.int32)
    np.clip(ui, 0, width - 1, out=ui)
    np.clip(vi, 0, height - 1, out=vi)
    big = width * height >= 2**31 - 1
    pix = vi.astype(np.int64) * width if big else vi * np.int32(width)  # int32 halves the memory traffic
    pix += ui
    pix[~valid] = width * height
    return ui, vi, pix


def disk_kernel(radius_px: float) -> np.ndarray:
    """Structuring element: the pixel offsets within ``radius_px`` (Euclidean)."""
    r = int(np.floor(radius_px))
    yy, xx = np.mgrid[-r:r + 1, -r:r + 1]
    return (xx * xx + yy * yy <= radius_px * radius_px + 1e-9).astype(np.uint8)


def depth_buffer(uv_px: np.ndarray, depth_m: np.ndarray, valid: np.ndarray, width: int, height: int,
                 splat_radius_px="auto", layer_m: float = 0.05) -> np.ndarray:
    """(H,W) float32 nearest depth (m) per pixel (inf where empty), splatted.

    ``splat_radius_px``: a number splats every point by that radius (a disk up to 2 px, a
    square beyond: see :func:`_splat_kernel`); "auto" adapts it to the local spacing of the
    nearest surface (:func:`_adaptive_splat`, with ``layer_m`` its depth layer).
    """
    uv = np.asarray(uv_px).reshape(-1, 2)
    valid = np.asarray(valid, bool)
    _, _, pix = pixel_index(uv, valid, width, height)
    z, _ = splatted_zbuffer(pix, np.asarray(depth_m, np.float32), width, height, splat_radius_px, layer_m)
    return z[:-1].reshape(height, width)


def zimage(pix, depth32, width, height) -> np.ndarray:
    """Flat (H*W+1,) nearest depth per pixel, unsplatted (inf where empty and in the last slot)."""
    z = np.full(height * width + 1, np.inf, np.float32)
    np.minimum.at(z, pix, depth32)
    return z


def _splat_kernel(r: int) -> np.ndarray:
    """Splat footprint: a disk up to 2 px, a square beyond (OpenCV erodes squares ~5x faster;
    the square's corners reach 1.41 r, which only makes occlusion a little more conservative)."""
    return disk_kernel(r) if r <= 2 else np.ones((2 * r + 1, 2 * r + 1), np.uint8)


_RADII = np.array([1, 2, 3, 4, 6, 8, 11, 16, 24])
CELL_SHIFT = 5  # 32-px cells


def splatted_zbuffer(pix, depth32, width, height, splat_radius_px, layer_m) -> tuple[np.ndarray, np.ndarray | None]:
    """Flat (H*W+1,) splatted z-buffer (the last slot, for invalid points, is inf) and the
    per-cell radius grid of the adaptive splat (None for a fixed radius)."""
    z = zimage(pix, depth32, width, height)
    return z, splat_zimage(z, width, height, splat_radius_px, layer_m)


OWN_REACH_PX = float(np.sqrt(2.0))  # farthest two points snapped into one pixel can be
NEAR_REACH_PX = 2.0 * np.sqrt(2.0)  # farthest two points snapped into a 3x3 block of pixels can be


def _reach_factor(reach_px, slope_per_px):
    """1 / (1 - slope_per_px x reach_px) (float32, inf where that reaches 1): d <= z + tol + k d
    <=> d <= (z + tol) / (1 - k), exactly, for the reach term k = slope_per_px x reach_px."""
    k = np.asarray(reach_px, np.float64) * slope_per_px
    with np.errstate(divide="ignore"):
        return np.where(k < 1.0, 1.0 / (1.0 - k), np.inf).astype(np.float32)


def visibility_bound(pix, depth32, width, height, splat_radius_px, tolerance_m: float,
                     slope_per_px: float) -> np.ndarray:
    """Flat (H*W+1,) farthest depth (m) a point snapped to each pixel may have and still be seen
    (inf in the last slot, for invalid points).

    A point at depth d is seen when d <= z + tolerance_m + slope_per_px x reach_px x d for each of:
    the unsplatted nearest depth z of its own pixel (reach :data:`OWN_REACH_PX`), of its 3x3
    block (reach :data:`NEAR_REACH_PX`) and the splatted depth (reach: the splat radius of the
    point's cell, or the fixed one). The first two keep a wide splat's reach from letting
    through a back surface right behind a front point."""
    tol = np.float32(tolerance_m)
    z = zimage(pix, depth32, width, height)
    img = z[:-1].reshape(height, width)
    out = np.empty_like(z)
    bound = out[:-1].reshape(height, width)
    np.add(img, tol, out=bound)
    bound *= _reach_factor(OWN_REACH_PX, slope_per_px)
    near = cv2.erode(img, np.ones((3, 3), np.uint8), borderType=cv2.BORDER_CONSTANT, borderValue=np.inf)
    near += tol
    near *= _reach_factor(NEAR_REACH_PX, slope_per_px)
    np.minimum(bound, near, out=bound)
    r_cell = splat_zimage(z, width, height, splat_radius_px, tolerance_m)
    if r_cell is None:
        factor = _reach_factor(max(0, int(splat_radius_px)), slope_per_px)
    else:
        g = 1 << CELL_SHIFT
        f_cell = _reach_factor(r_cell, slope_per_px)
        factor = cv2.resize(f_cell, (f_cell.shape[1] * g, f_cell.shape[0] * g), interpolation=cv2.INTER_NEAREST)
        factor = factor[:height, :width]
    img += tol
    img *= factor
    np.minimum(bound, img, out=bound)
    out[-1] = np.inf
    return out


def splat_zimage(z, width, height, splat_radius_px, layer_m) -> np.ndarray | None:
    """Splat a flat (H*W+1,) z-image in place; returns the adaptive splat's per-cell radius grid
    (None for a fixed radius)."""
    img = z[:-1].reshape(height, width)
    r_cell = None
    if isinstance(splat_radius_px, str):
        if splat_radius_px != "auto":
            raise ValueError(f"splat_radius_px must be a number or 'auto', got {splat_radius_px!r}")
        r_cell = _adaptive_splat(img, layer_m)
    elif int(splat_radius_px) > 0:
        img[:] = cv2.erode(img, _splat_kernel(int(splat_radius_px)), borderType=cv2.BORDER_CONSTANT, borderValue=np.inf)
    z[-1] = np.inf
    return r_cell


def _front_counts(padded: np.ndarray, g: int, layer_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Per g-px cell of a padded z-image: (occupied pixels within layer_m of the cell's nearest
    depth, that nearest depth)."""
    gh, gw = padded.shape[0] // g, padded.shape[1] // g
    blocks = padded[:gh * g, :gw * g].reshape(gh, g, gw, g)
    zc = blocks.min(axis=(1, 3))
    with np.errstate(invalid="ignore"):
        front = blocks <= (zc + np.float32(layer_m))[:, None, :, None]
    front &= np.isfinite(zc)[:, None, :, None]
    return np.count_nonzero(front, axis=(1, 3)), zc


def _coarse_counts(n: np.ndarray, zc: np.ndarray, layer_m: float) -> np.ndarray:
    """Front-layer counts on cells twice as large, from the fine cells' counts: the fine cells
    whose own front lies within layer_m of the coarse cell's front (an approximation of a
    recount that saves a pass over the image). Returned at the fine cells' resolution."""
    gh, gw = n.shape
    z4 = zc.reshape(gh // 2, 2, gw // 2, 2)
    n4 = n.reshape(gh // 2, 2, gw // 2, 2)
    z2 = z4.min(axis=(1, 3))
    with np.errstate(invalid="ignore"):
        near = z4 <= (z2 + np.float32(layer_m))[:, None, :, None]
    n2 = np.where(near, n4, 0).sum(axis=(1, 3))
    return np.repeat(np.repeat(n2, 2, axis=0), 2, axis=1)


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
    g = 1 << CELL_SHIFT
    gw, gh = -(-width // g) + 1, -(-height // g) + 1  # one spare row/column: the 64-px grid fits
    gw, gh = gw + gw % 2, gh + gh % 2
    padded = np.full((gh * g, gw * g), np.inf, np.float32)
    padded[:height, :width] = img
    blocks = padded.reshape(gh, g, gw, g)
    n, zc = _front_counts(padded, g, layer_m)
    n64 = _coarse_counts(n, zc, layer_m)
    spacing = np.where(n >= 3, g / np.sqrt(np.maximum(n, 1)), 2 * g / np.sqrt(np.maximum(n64, 1)))
    want = np.where((n >= 3) | (n64 >= 3), np.ceil(0.75 * spacing), 1)
    r_cell = _RADII[np.minimum(np.searchsorted(_RADII, want), len(_RADII) - 1)]
    r_cell[n == 0] = 0
    # the commonest small radius splats the whole image in one pass (cells that wanted less get
    # it too: slightly conservative); larger radii follow per cell (few) or per bounding box
    radii, counts = np.unique(r_cell[r_cell > 0], return_counts=True)
    base = int(radii[np.argmax(counts)]) if len(radii) else 1
    base = base if base <= 3 else 1
    src = padded[:height, :width]  # untouched by the per-cell passes below (they write into img)
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
