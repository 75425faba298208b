"""Drawing for people: segmentation overlays and detection markers (cv2, anti-aliased).

Sizes follow the image (2 px lines, ~23 px markers at 1920x1080). Images are RGB uint8;
pixel coordinates are raw (distorted) with pixel centres at integers. Re-exported by
:mod:`calib_core.fusion`.
"""

from __future__ import annotations

import cv2
import numpy as np


def overlay(image_rgb: np.ndarray, mask: np.ndarray, colour=(0, 255, 0), opacity: float = 0.45,
            outline: bool = True) -> np.ndarray:
    """Tint ``mask`` pixels of an RGB image with ``colour`` at ``opacity`` in [0, 1].

    With ``outline`` the mask's border is also drawn, fully opaque, so the segmentation
    reads at a glance on 1920x1080 frames. Returns a new RGB uint8 image.
    """
    img = np.ascontiguousarray(image_rgb, dtype=np.uint8)
    out = img.copy()
    m8 = np.asarray(mask, bool).view(np.uint8)
    x, y, w, h = cv2.boundingRect(m8)  # blend only where the mask is
    if w == 0 or h == 0:
        return out
    a = float(np.clip(opacity, 0.0, 1.0))
    roi = img[y:y + h, x:x + w]
    solid = np.empty_like(roi)
    solid[:] = np.asarray(colour, np.uint8)
    blended = cv2.addWeighted(roi, 1.0 - a, solid, a, 0.0)
    out_roi = out[y:y + h, x:x + w]
    cv2.copyTo(blended, np.ascontiguousarray(m8[y:y + h, x:x + w]), out_roi)
    if outline:
        contours, _ = cv2.findContours(np.ascontiguousarray(m8[y:y + h, x:x + w]), cv2.RETR_EXTERNAL,
                                       cv2.CHAIN_APPROX_SIMPLE, offset=(x, y))
        cv2.drawContours(out, contours, -1, tuple(int(c) for c in colour), _thickness(img), cv2.LINE_AA)
    return out


# ------------------------------------------------------------------- drawing
def _thickness(img: np.ndarray) -> int:
    """Line width that reads at the image's size (2 px at 1080p)."""
    return max(1, int(round(max(img.shape[:2]) / 960)))


def _pt(uv, shift=4):
    s = 1 << shift
    return int(round(float(uv[0]) * s)), int(round(float(uv[1]) * s))


def draw_marker(image_rgb: np.ndarray, uv_px, colour=(255, 0, 0), kind: str = "cross",
                size_px: float | None = None, label: str | None = None, label_below: bool = False) -> np.ndarray:
    """Draw a marker ('cross', 'x', 'circle' or 'diamond') at a raw pixel, in place; returns the image.

    ``size_px`` is the half-size (default 1.2 % of the image's larger side, ~23 px at 1080p).
    ``label`` is written up-right of the marker (down-right with ``label_below``).
    """
    if uv_px is None or not np.all(np.isfinite(np.asarray(uv_px, float))):
        return image_rgb
    u, v = float(uv_px[0]), float(uv_px[1])
    s = size_px if size_px is not None else max(6.0, 0.012 * max(image_rgb.shape[:2]))
    c = tuple(int(x) for x in colour)
    th = _thickness(image_rgb)
    if kind == "circle":
        cv2.circle(image_rgb, _pt((u, v)), int(round(s * 16)), c, th, cv2.LINE_AA, 4)
    elif kind == "diamond":
        pts = np.array([[u, v - s], [u + s, v], [u, v + s], [u - s, v]]) * 16
        cv2.polylines(image_rgb, [np.rint(pts).astype(np.int32)], True, c, th, cv2.LINE_AA, 4)
    else:
        d = s if kind == "cross" else s * 0.7071
        segs = [((u - d, v), (u + d, v)), ((u, v - d), (u, v + d))] if kind == "cross" else \
            [((u - d, v - d), (u + d, v + d)), ((u - d, v + d), (u + d, v - d))]
        for a, b in segs:
            cv2.line(image_rgb, _pt(a), _pt(b), c, th, cv2.LINE_AA, 4)
    if label:
        fs = max(0.4, max(image_rgb.shape[:2]) / 1920 * 0.9)
        (w_txt, th_txt), base = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, fs, th)
        x = u + s + 4 if u + s + 4 + w_txt <= image_rgb.shape[1] - 2 else u - s - 4 - w_txt  # flip at the edge
        y = v + s + 4 + th_txt if label_below else v - s - 4
        x = min(max(x, 2), max(image_rgb.shape[1] - w_txt - 2, 2))  # never cut at the image edge
        y = min(max(y, th_txt + 2), max(image_rgb.shape[0] - base - 2, th_txt + 2))
        org = (int(x), int(y))
        cv2.putText(image_rgb, label, org, cv2.FONT_HERSHEY_SIMPLEX, fs, (0, 0, 0), th + 2, cv2.LINE_AA)
        cv2.putText(image_rgb, label, org, cv2.FONT_HERSHEY_SIMPLEX, fs, c, th, cv2.LINE_AA)
    return image_rgb


def draw_ellipse(image_rgb: np.ndarray, ellipse_px, colour=(255, 255, 0)) -> np.ndarray:
    """Draw a detected silhouette ellipse in place.

    ``ellipse_px`` is OpenCV's RotatedRect form ((cx, cy), (full axis 1, full axis 2), angle_deg)
    as cv2.fitEllipse returns it, or the flat list [cx, cy, a, b, angle] of detections.yaml.
    """
    if ellipse_px is None:
        return image_rgb
    e = np.asarray([ellipse_px[0][0], ellipse_px[0][1], ellipse_px[1][0], ellipse_px[1][1], ellipse_px[2]]
                   if len(ellipse_px) == 3 else ellipse_px, float).ravel()
    if e.size != 5 or not np.isfinite(e).all():
        return image_rgb
    centre = _pt(e[:2])
    axes = (int(round(e[2] / 2 * 16)), int(round(e[3] / 2 * 16)))
    cv2.ellipse(image_rgb, centre, axes, float(e[4]), 0.0, 360.0, tuple(int(x) for x in colour),
                _thickness(image_rgb), cv2.LINE_AA, 4)
    return image_rgb


def draw_detection(image_rgb: np.ndarray, center_uv_px=None, ellipse_px=None, reprojected_uv_px=None,
                   labels: bool = True) -> np.ndarray:
    """Copy of the image with the detected ellipse (yellow), detected centre (red cross) and the
    reprojected sonar sphere centre (cyan x + circle)."""
    out = np.ascontiguousarray(image_rgb, dtype=np.uint8).copy()
    draw_ellipse(out, ellipse_px)
    if reprojected_uv_px is not None:
        draw_marker(out, reprojected_uv_px, (0, 230, 255), "x")
        draw_marker(out, reprojected_uv_px, (0, 230, 255), "circle", label="sonar" if labels else None, label_below=True)
    draw_marker(out, center_uv_px, (255, 40, 40), "cross", label="detected" if labels else None)  # on top
    return out
