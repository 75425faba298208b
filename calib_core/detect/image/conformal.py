"""Round-outline votes in a stereographic view of the image, where every sphere is a circle.

A sphere's silhouette is a circular cone about the camera centre: a circle on the sphere of
viewing directions. The pinhole image stretches that circle into an ellipse off the axis (by
up to 1 / cos(theta) radially, theta the angle off the axis) and the lens distortion stretches
it further; in the corners of a wide lens (90 deg and more across) a ball's outline is 1.5x
longer one way than the other, and circle votes (:mod:`.votes`) no longer meet at its centre.
The stereographic projection of the viewing directions is conformal and maps every circle on
the sphere to a circle in the plane: re-sampled into it, every sphere's outline is a circle
again, wherever it is in the frame and whatever the lens.

Conventions: a viewing direction ``d`` (unit, camera frame, z along the optical axis) maps to
``q = 2 (d_x, d_y) / (1 + d_z)`` (normalised; ``q`` equals the pinhole's normalised coordinates
to first order at the axis); view pixel = ``f_px * q + c_px`` at the scale of the downscaled
image the detector votes on. Directions 85 deg or more off the axis are left out.

:func:`view_elongation` says whether a camera needs the view (the largest aspect ratio of a
small sphere's image over the frame); :func:`stereographic_view` builds the re-sampling;
:func:`candidates_in_view` votes in it and maps each circle back to an ellipse in raw pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from calib_core.camera import CameraModel
from calib_core.detect.image.region import Candidate
from calib_core.detect.image.votes import candidates_by_votes

MAX_OFF_AXIS_RAD = np.radians(85.0)
BOUNDARY_POINTS = 48  # points of a view circle mapped back to raw pixels for its ellipse
GRID = (17, 10)  # points across and down the frame where the elongation is measured


@dataclass(frozen=True)
class StereoView:
    """A stereographic re-sampling of a downscaled image: ``map_x``/``map_y`` (view px -> px of
    the downscaled image, for ``cv2.remap``), the view's focal length and centre (view px),
    the downscale factor ``s`` and the range of the view's scale over the raw image's local
    scale (smallest, largest: view px per downscaled px, over the frame)."""

    map_x: np.ndarray
    map_y: np.ndarray
    f_px: float
    c_px: tuple[float, float]
    s: int
    scale_range: tuple[float, float]


def rays_to_view(d: np.ndarray) -> np.ndarray:
    """(N,3) unit directions -> (N,2) normalised stereographic coordinates."""
    d = np.asarray(d, float).reshape(-1, 3)
    return 2.0 * d[:, :2] / (1.0 + d[:, 2:3])


def view_to_rays(q: np.ndarray) -> np.ndarray:
    """(N,2) normalised stereographic coordinates -> (N,3) unit directions."""
    p = 0.5 * np.asarray(q, float).reshape(-1, 2)
    n2 = (p * p).sum(axis=1, keepdims=True)
    return np.hstack([2.0 * p, 1.0 - n2]) / (1.0 + n2)


def _raw_of_rays(cam: CameraModel, d: np.ndarray) -> np.ndarray:
    """Raw pixels (N,2) of directions (NaN where 85 deg or more off the axis)."""
    ok = d[:, 2] > np.cos(MAX_OFF_AXIS_RAD)
    with np.errstate(divide="ignore", invalid="ignore"):
        xy = d[:, :2] / d[:, 2:3]
    xy[~ok] = np.nan
    return cam.distort(xy)


def _local_axes(cam: CameraModel, uv_px: np.ndarray, h: float = 0.5) -> np.ndarray:
    """(N,2) singular values (largest, smallest) of d(raw px)/d(q) at raw pixels ``uv_px``:
    how much the raw image stretches a small circle of the view there, along its two axes."""
    q = rays_to_view(cam.rays(uv_px))
    step = h / cam.fx
    cols = []
    for e in (np.array([step, 0.0]), np.array([0.0, step])):
        plus = _raw_of_rays(cam, view_to_rays(q + e))
        minus = _raw_of_rays(cam, view_to_rays(q - e))
        cols.append((plus - minus) / (2 * step))
    J = np.stack(cols, axis=2)  # (N, 2 raw, 2 q)
    return np.linalg.svd(J, compute_uv=False)


def _frame_grid(cam: CameraModel) -> np.ndarray:
    u = np.linspace(0.5, cam.width_px - 1.5, GRID[0])
    v = np.linspace(0.5, cam.height_px - 1.5, GRID[1])
    return np.stack(np.meshgrid(u, v), axis=-1).reshape(-1, 2)


def elongation_at(cam: CameraModel, uv_px: np.ndarray) -> np.ndarray:
    """(N,) aspect ratio (major / minor axis) of a small sphere's raw image at raw pixels
    ``uv_px`` (1.0 on the axis of an undistorted lens; NaN where it cannot be told)."""
    sv = _local_axes(cam, np.asarray(uv_px, float).reshape(-1, 2))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(sv[:, 1] > 0, sv[:, 0] / sv[:, 1], np.nan)


def view_elongation(cam: CameraModel) -> float:
    """Largest aspect ratio of a small sphere's raw image over the frame (:func:`elongation_at`;
    1.0: round everywhere; a 90 deg lens's corners: about 1.5)."""
    e = elongation_at(cam, _frame_grid(cam))
    e = e[np.isfinite(e)]
    return float(np.max(e)) if len(e) else 1.0


def stereographic_view(cam: CameraModel, s: int) -> StereoView | None:
    """The re-sampling of the image downscaled by ``s`` (px ``(raw + 0.5) / s - 0.5``) into a
    stereographic view at the same scale on the axis; None when the frame gives no view."""
    border = _border(cam)
    q = rays_to_view(cam.rays(border))
    q = q[np.isfinite(q).all(axis=1)]
    if len(q) < 8:
        return None
    f = cam.fx / s
    lo, hi = q.min(axis=0) * f, q.max(axis=0) * f
    w, h = int(np.ceil(hi[0] - lo[0])) + 2, int(np.ceil(hi[1] - lo[1])) + 2
    if w * h > 4 * (cam.width_px // s + 2) * (cam.height_px // s + 2):
        return None  # a fisheye near 180 deg: the view would be huge
    c = (-lo[0] + 1.0, -lo[1] + 1.0)
    xs, ys = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    qv = np.column_stack([(xs.ravel() - c[0]) / f, (ys.ravel() - c[1]) / f])
    raw = _raw_of_rays(cam, view_to_rays(qv))
    small = (raw + 0.5) / s - 0.5
    small[~np.isfinite(small)] = -1e4
    sv = _local_axes(cam, _frame_grid(cam))
    sv = sv[np.isfinite(sv).all(axis=1) & (sv[:, 1] > 0)]
    # view px per raw px along the raw image's axes: q-units per raw px times f
    k = (cam.fx / sv[:, 0], cam.fx / sv[:, 1]) if len(sv) else (np.ones(1), np.ones(1))
    return StereoView(small[:, 0].reshape(h, w).astype(np.float32), small[:, 1].reshape(h, w).astype(np.float32),
                      f, c, s, (float(np.min(k[0])), float(np.max(k[1]))))


def _border(cam: CameraModel, n: int = 64) -> np.ndarray:
    W, H = cam.width_px - 1.0, cam.height_px - 1.0
    t = np.linspace(0.0, 1.0, n)
    return np.concatenate([np.column_stack([t * W, 0 * t]), np.column_stack([t * W, H + 0 * t]),
                           np.column_stack([0 * t, t * H]), np.column_stack([W + 0 * t, t * H])])


def candidates_in_view(small_rgb: np.ndarray, cam: CameraModel, view: StereoView,
                       r_bounds_px: tuple[float, float], max_candidates: int,
                       min_elongation: float = 1.0) -> list[Candidate]:
    """Round-outline vote candidates found in the stereographic view of ``small_rgb`` (the raw
    image downscaled by ``view.s``), each as the ellipse its circle is in raw pixels (source
    "votes-stereo"). ``r_bounds_px``: plausible apparent radii in raw pixels.
    ``min_elongation``: only candidates where the raw image stretches a sphere at least this
    much (:func:`elongation_at`; where it stretches less, the raw image's votes see as well)."""
    img = cv2.remap(np.ascontiguousarray(small_rgb), view.map_x, view.map_y, cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_REPLICATE)
    k_lo, k_hi = view.scale_range
    bounds = (r_bounds_px[0] * k_lo, r_bounds_px[1] * k_hi)
    out = []
    for c in candidates_by_votes(img, view.s, bounds, max_candidates=max_candidates):
        raw = _circle_in_raw(cam, view, c.centre_px / view.s, c.radius_px / view.s)
        if raw is not None and elongation_at(cam, raw[0])[0] >= min_elongation:
            out.append(Candidate(raw[0], raw[1], raw[2], raw[3], bool(raw[4]), c.strength,
                                 "votes-stereo"))
    return out


def _circle_in_raw(cam: CameraModel, view: StereoView, centre_view_px, radius_view_px: float):
    """(centre, mean radius, (major, minor) semi-axes, major axis angle, leaves the frame) in
    raw pixels of a view circle (view px), or None where it maps outside the lens's reach."""
    a = np.linspace(0.0, 2 * np.pi, BOUNDARY_POINTS, endpoint=False)
    pts = np.asarray(centre_view_px, float)[None, :] + radius_view_px * np.column_stack([np.cos(a), np.sin(a)])
    q = (pts - np.asarray(view.c_px)[None, :]) / view.f_px
    raw = _raw_of_rays(cam, view_to_rays(q))
    if not np.isfinite(raw).all():
        return None
    (cx, cy), (d1, d2), ang = cv2.fitEllipse(raw.astype(np.float32))
    major, minor = max(d1, d2) / 2.0, min(d1, d2) / 2.0
    theta = np.radians(ang) + (0.0 if d1 >= d2 else np.pi / 2)
    leaves = not cam.in_image(raw).all()
    return np.array([cx, cy], float), float(np.sqrt(major * minor)), (float(major), float(minor)), float(theta), leaves
