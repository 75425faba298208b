"""Coverage pictures (RGB uint8 images) and numbers: image area per camera, depth spread, sonar fan.

Captured sphere centres are filled dots, suggestions hollow numbered rings. Image coverage is
the share of a 4 x 3 grid of image cells holding at least one capture; fan coverage the share
of a 4 x 4 grid of (azimuth, elevation) cells of the sonar field; depth spread the range
(max - min) and standard deviation of the capture ranges from the sonar.
"""

from __future__ import annotations

import cv2
import numpy as np

FONT = cv2.FONT_HERSHEY_SIMPLEX
TAKEN, SUGGESTED, EMPTY, FILLED, GRID = (0, 110, 220), (230, 90, 0), (250, 225, 225), (225, 245, 225), (190, 190, 190)


def _cells(u: np.ndarray, v: np.ndarray, nx: int, ny: int) -> np.ndarray:
    """(ny, nx) counts of points with u, v in [0, 1)."""
    ok = (u >= 0) & (u < 1) & (v >= 0) & (v < 1)
    H = np.zeros((ny, nx), int)
    np.add.at(H, ((v[ok] * ny).astype(int), (u[ok] * nx).astype(int)), 1)
    return H


def _shade(img, H, x0, y0, w, h) -> None:
    ny, nx = H.shape
    for j in range(ny):
        for i in range(nx):
            p0 = (int(x0 + i * w / nx), int(y0 + j * h / ny))
            p1 = (int(x0 + (i + 1) * w / nx), int(y0 + (j + 1) * h / ny))
            cv2.rectangle(img, p0, p1, FILLED if H[j, i] else EMPTY, -1)
            cv2.rectangle(img, p0, p1, GRID, 1)


def _ring(img, p, r, k: int) -> None:
    cv2.circle(img, p, max(r, 5), SUGGESTED, 2, cv2.LINE_AA)
    cv2.putText(img, str(k), (p[0] - 4, p[1] + 4), FONT, 0.4, SUGGESTED, 1, cv2.LINE_AA)


def image_coverage(cam, taken_uv_px: np.ndarray, suggested_uv: list, width: int = 320) -> tuple[np.ndarray, float]:
    """Thumbnail of one camera's image area and the share of 4 x 3 cells holding a capture."""
    s = width / cam.width_px
    h = int(round(cam.height_px * s))
    img = np.full((h + 22, width, 3), 255, np.uint8)
    uv = np.asarray(taken_uv_px, float).reshape(-1, 2)
    H = _cells(uv[:, 0] / cam.width_px, uv[:, 1] / cam.height_px, 4, 3)
    _shade(img, H, 0, 22, width - 1, h - 1)
    for u, v in uv:
        cv2.circle(img, (int(u * s), int(22 + v * s)), 4, TAKEN, -1, cv2.LINE_AA)
    for k, (u, v, r) in enumerate(suggested_uv, 1):
        _ring(img, (int(u * s), int(22 + v * s)), int(r * s), k)
    frac = float((H > 0).mean())
    cv2.putText(img, f"{cam.name}: image cells covered {100 * frac:.0f} %", (4, 15), FONT, 0.42, (0, 0, 0), 1, cv2.LINE_AA)
    return img, frac


def depth_spread(ranges_m: np.ndarray, suggested_m: list, working_m: tuple, width: int = 320,
                 height: int = 120) -> tuple[np.ndarray, float]:
    """Histogram of capture ranges from the sonar over the working range (suggestions as rings)."""
    img = np.full((height, width, 3), 255, np.uint8)
    lo, hi = working_m
    r = np.asarray(ranges_m, float)
    x = lambda d: int(10 + (width - 20) * (d - lo) / max(hi - lo, 1e-9))  # noqa: E731
    bins = np.linspace(lo, hi, 13)
    cnt, _ = np.histogram(np.clip(r, lo, hi), bins)
    top, base = 28, height - 26
    for i, c in enumerate(cnt):
        y = int(base - (base - top) * c / max(cnt.max(), 1))
        cv2.rectangle(img, (x(bins[i]) + 1, y), (x(bins[i + 1]) - 1, base), FILLED if c else EMPTY, -1)
        cv2.rectangle(img, (x(bins[i]) + 1, y), (x(bins[i + 1]) - 1, base), GRID, 1)
    for d in r:
        cv2.circle(img, (x(min(max(d, lo), hi)), base + 8), 3, TAKEN, -1, cv2.LINE_AA)
    for k, d in enumerate(suggested_m, 1):
        _ring(img, (x(min(max(d, lo), hi)), base + 8), 6, k)
    cv2.putText(img, f"{lo:.1f} m", (2, height - 3), FONT, 0.38, (60, 60, 60), 1, cv2.LINE_AA)
    cv2.putText(img, f"{hi:.1f} m", (width - 48, height - 3), FONT, 0.38, (60, 60, 60), 1, cv2.LINE_AA)
    spread = float(r.max() - r.min()) if len(r) else 0.0
    sd = float(r.std()) if len(r) else 0.0
    cv2.putText(img, f"range from sonar: spread {spread:.2f} m, sd {sd:.2f} m", (4, 15), FONT, 0.42, (0, 0, 0), 1,
                cv2.LINE_AA)
    return img, spread


def fan_spread(field, taken_sonar_m: np.ndarray, suggested_sonar_m: list, width: int = 320,
               height: int = 240) -> tuple[np.ndarray, float]:
    """Azimuth x elevation of the captures inside the sonar field (seen from behind the sonar, up at the
    top), and the share of 4 x 4 cells used."""
    img = np.full((height, width, 3), 255, np.uint8)
    (a0, a1), (e0, e1) = field.azimuth_deg, field.elevation_deg
    X = np.asarray(taken_sonar_m, float).reshape(-1, 3)
    az, el, _ = field.angles(X)
    u, v = (a1 - az) / (a1 - a0), (e1 - el) / (e1 - e0)  # seen from behind the sonar: its left on the left
    H = _cells(u, v, 4, 4)
    y0, w, h = 22, width - 1, height - 23
    _shade(img, H, 0, y0, w, h)
    for uu, vv in zip(u, v):
        cv2.circle(img, (int(uu * w), int(y0 + vv * h)), 4, TAKEN, -1, cv2.LINE_AA)
    for k, Xs in enumerate(suggested_sonar_m, 1):
        sa, se, _ = field.angles(np.asarray(Xs)[None])
        _ring(img, (int((a1 - sa[0]) / (a1 - a0) * w), int(y0 + (e1 - se[0]) / (e1 - e0) * h)), 7, k)
    frac = float((H > 0).mean())
    cv2.putText(img, "left", (3, height - 5), FONT, 0.38, (60, 60, 60), 1, cv2.LINE_AA)
    cv2.putText(img, "right", (width - 36, height - 5), FONT, 0.38, (60, 60, 60), 1, cv2.LINE_AA)
    cv2.putText(img, f"sonar fan (az x el) cells covered {100 * frac:.0f} %", (4, 15), FONT, 0.42, (0, 0, 0), 1,
                cv2.LINE_AA)
    return img, frac


def coverage(sp, cameras: dict) -> dict:
    """{name: (image, number)} for a SessionPlan: one image-area picture per planned camera
    (``cameras[name]`` = CameraModel), 'depth' and 'fan'."""
    sugg = sp.plan.suggestions
    out = {}
    for c in sp.cameras:
        uvs = [(*s.uv_px[c], s.radius_px[c]) for s in sugg if c in s.uv_px]
        out[c] = image_coverage(cameras[c], sp.taken_uv_px.get(c, np.zeros((0, 2))), uvs)
    r = np.linalg.norm(sp.taken_sonar_m, axis=1)
    out["depth"] = depth_spread(r, [float(np.linalg.norm(s.X_sonar_m)) for s in sugg], sp.limits.working_range_m)
    out["fan"] = fan_spread(sp.field, sp.taken_sonar_m, [s.X_sonar_m for s in sugg])
    return out


def suggestions_on_image(image_rgb: np.ndarray, cam_name: str, plan, max_width: int = 640) -> np.ndarray:
    """A copy of a camera image (downscaled to ``max_width``) with each suggestion drawn as a
    numbered ring of the sphere's outline radius, and a legend of the predicted worst-axis 1-sigma
    of this camera after each (cumulative)."""
    img = np.ascontiguousarray(image_rgb[..., :3] if image_rgb.ndim == 3 else np.repeat(image_rgb[..., None], 3, 2))
    s = min(1.0, max_width / img.shape[1])
    if s < 1.0:
        img = cv2.resize(img, (max_width, max(1, int(round(img.shape[0] * s)))), interpolation=cv2.INTER_AREA)
    else:
        img = img.copy()
    legend = []
    fs = float(np.clip(0.45 * img.shape[1] / 400, 0.4, 0.9))  # readable once the panel shrinks the image
    for k, sug in enumerate(plan.suggestions, 1):
        if cam_name not in sug.uv_px:
            continue
        u, v = sug.uv_px[cam_name] * s
        r = max(int(sug.radius_px[cam_name] * s), 6)
        cv2.circle(img, (int(u), int(v)), r, (255, 255, 255), 4, cv2.LINE_AA)
        cv2.circle(img, (int(u), int(v)), r, SUGGESTED, 2, cv2.LINE_AA)
        _tag(img, str(k), (int(u) + int(0.7 * r), int(v) - int(0.7 * r)), fs)
        rot, tr = sug.sigma_after[cam_name]
        legend.append(f"{k}: then {rot.max():.3f} deg / {tr.max():.1f} mm")
    for i, text in enumerate(reversed(legend)):
        _tag(img, text, (6, img.shape[0] - 8 - int(44 * fs) * i), fs)
    return img


def _tag(img, text: str, org, scale: float = 0.45) -> None:
    """White text on a dark box at ``org`` (bottom-left), kept inside the image."""
    (w, h), _ = cv2.getTextSize(text, FONT, scale, 1)
    x = int(min(max(org[0], 2), img.shape[1] - w - 4))
    y = int(min(max(org[1], h + 4), img.shape[0] - 4))
    cv2.rectangle(img, (x - 3, y - h - 4), (x + w + 3, y + 4), (40, 40, 40), -1)
    cv2.putText(img, text, (x, y), FONT, scale, (255, 255, 255), 1, cv2.LINE_AA)
