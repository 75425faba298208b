"""An ROV's on-screen display burned into the video, for the held-out kind "rov"
(:mod:`calib_core.synth.photo.rov`).

- Text (:func:`draw_text`): white or yellow Hershey characters with a dark outline (drawn
  thicker in black first): depth, heading, altitude, date and time, a dive name, in two or
  three corners, their size scaled with the frame height.
- A compass tape (:func:`draw_compass`): a line of ticks every 5 deg (a long one every 10) and
  labels every 30 deg, centred on the heading, along the top or bottom edge.
- A centre mark (:func:`draw_reticle`): a crosshair with a gap, or a circle reticle (a round
  overlay of radius 6-25 % of the height: a perfect circle at a fixed place), or both.
- Laser scaler dots (:func:`laser_dots`): two red spots (a small bright core and a glow) in
  the radiance, 20-120 px apart (at PAL size) either side of a point near the centre: where
  the two parallel lasers meet the scene (on the ball when it is there).

Every mark is drawn with OpenCV on the 8-bit frame (the dots: in the linear radiance, so they
get the optics' blur and the sensor's noise), before the video's chroma subsampling and
compression, as a camera's overlay generator does.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

YELLOW = (255, 230, 40)
WHITE = (245, 245, 245)


@dataclass(frozen=True)
class Osd:
    """What the display shows on one frame (all drawn by :func:`draw_osd`)."""

    colour: tuple = WHITE
    lines: tuple = ()  # ((text, corner), ...) corner in "tl", "tr", "bl", "br"
    heading_deg: float = 0.0
    compass: str = ""  # "", "top" or "bottom"
    crosshair: bool = False
    reticle_px: float = 0.0  # radius of the circle reticle (0: none)


def sample_osd(rng, height_px: int) -> Osd:
    """The display of one frame: text in two to four corners, a compass tape on half, a
    crosshair, a circle reticle or both on most."""
    depth, hdg, alt = rng.uniform(2, 900), rng.uniform(0, 360), rng.uniform(0.2, 8)
    day = f"20{int(rng.integers(10, 27)):02d}-{int(rng.integers(1, 13)):02d}-{int(rng.integers(1, 29)):02d}"
    clock = f"{int(rng.integers(0, 24)):02d}:{int(rng.integers(0, 60)):02d}:{int(rng.integers(0, 60)):02d}"
    texts = [f"DEPTH {depth:6.1f} M", f"HDG {hdg:03.0f}", f"ALT {alt:4.1f} M", f"{day} {clock}",
             f"DIVE {int(rng.integers(1, 400)):03d}", f"TURNS {rng.uniform(-3, 3):+.1f}"]
    corners = ["tl", "tr", "bl", "br"]
    k = int(rng.integers(2, 5))
    chosen = rng.choice(len(texts), k, replace=False)
    lines = tuple((texts[i], corners[j]) for j, i in enumerate(chosen))
    mark = rng.random()
    return Osd(colour=YELLOW if rng.random() < 0.4 else WHITE, lines=lines, heading_deg=float(hdg),
               compass=str(rng.choice(["", "top", "bottom"], p=[0.5, 0.35, 0.15])),
               crosshair=mark < 0.6, reticle_px=float(rng.uniform(0.06, 0.25)) * height_px if mark > 0.35 else 0.0)


def _outlined_text(img, text, org, size, colour, thick) -> None:
    cv2.putText(img, text, org, cv2.FONT_HERSHEY_SIMPLEX, size, (0, 0, 0), thick + 2, cv2.LINE_AA)
    cv2.putText(img, text, org, cv2.FONT_HERSHEY_SIMPLEX, size, colour, thick, cv2.LINE_AA)


def draw_text(img: np.ndarray, osd: Osd) -> None:
    """The text lines in their corners (in place)."""
    H, W = img.shape[:2]
    size = H / 900.0
    thick = max(1, int(round(H / 400)))
    rows = {c: 0 for c in ("tl", "tr", "bl", "br")}
    for text, corner in osd.lines:
        (tw, th), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, size, thick)
        step = int(th * 1.8)
        x = int(0.04 * W) if corner[1] == "l" else int(0.96 * W) - tw
        y = int(0.06 * H) + th + rows[corner] * step if corner[0] == "t" else int(0.94 * H) - rows[corner] * step
        rows[corner] += 1
        _outlined_text(img, text, (x, y), size, osd.colour, thick)


def draw_compass(img: np.ndarray, osd: Osd) -> None:
    """A compass tape centred on the heading, along the top or bottom (in place)."""
    if not osd.compass:
        return
    H, W = img.shape[:2]
    y = int(0.03 * H) if osd.compass == "top" else int(0.86 * H)
    px_per_deg = W / 180.0
    size, thick = H / 1400.0, max(1, int(round(H / 500)))
    for shade, t in (((0, 0, 0), thick + 2), (osd.colour, thick)):
        cv2.line(img, (int(0.2 * W), y), (int(0.8 * W), y), shade, t, cv2.LINE_AA)
        first = int(np.ceil((osd.heading_deg - 54) / 5.0)) * 5
        for deg in range(first, int(osd.heading_deg + 54) + 1, 5):
            x = int(W / 2 + (deg - osd.heading_deg) * px_per_deg)
            tick = int(0.025 * H) if deg % 10 == 0 else int(0.012 * H)
            cv2.line(img, (x, y), (x, y + tick), shade, t, cv2.LINE_AA)
            if deg % 30 == 0:
                label = {0: "N", 90: "E", 180: "S", 270: "W"}.get(deg % 360, f"{deg % 360:03d}")
                cv2.putText(img, label, (x - int(0.012 * W), y + tick + int(0.035 * H)), cv2.FONT_HERSHEY_SIMPLEX,
                            size, shade, t, cv2.LINE_AA)


def draw_reticle(img: np.ndarray, osd: Osd) -> None:
    """A centre crosshair with a gap and / or a circle reticle (in place)."""
    H, W = img.shape[:2]
    c = (W // 2, H // 2)
    thick = max(1, int(round(H / 450)))
    arm, gap = int(0.05 * H), int(0.015 * H)
    for shade, t in (((0, 0, 0), thick + 2), (osd.colour, thick)):
        if osd.crosshair:
            for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                cv2.line(img, (c[0] + dx * gap, c[1] + dy * gap), (c[0] + dx * (gap + arm), c[1] + dy * (gap + arm)),
                         shade, t, cv2.LINE_AA)
        if osd.reticle_px > 0:
            cv2.circle(img, (c[0] * 4, c[1] * 4), int(osd.reticle_px * 4), shade, t, cv2.LINE_AA, shift=2)


def broken_reticle(img: np.ndarray, drawn_share: float, radius_share: float = 0.32, arcs: int = 4) -> np.ndarray:
    """A copy of the RGB uint8 frame with a circle reticle drawn as ``arcs`` arcs (a reticle with
    gaps, as many OSDs draw it) covering ``drawn_share`` (0-1) of the circle: white with a dark
    outline, at the frame's centre, of radius ``radius_share`` x the frame height (px)."""
    out = np.ascontiguousarray(img.copy())
    H, W = img.shape[:2]
    c, r = (W // 2 * 4, H // 2 * 4), int(radius_share * H * 4)  # 2 bits of sub-pixel position
    for shade, t in (((0, 0, 0), 3), ((255, 255, 255), 1)):
        for k in range(arcs):
            a0 = k * 360.0 / arcs + 10
            cv2.ellipse(out, c, (r, r), 0, a0, a0 + drawn_share * 360.0 / arcs, shade, t, cv2.LINE_AA, shift=2)
    return out


def draw_osd(img: np.ndarray, osd: Osd) -> np.ndarray:
    """A copy of the RGB uint8 frame with the display burned in."""
    out = np.ascontiguousarray(img.copy())
    draw_reticle(out, osd)
    draw_compass(out, osd)
    draw_text(out, osd)
    return out


def laser_dots(radiance: np.ndarray, rng, scale: float) -> np.ndarray:
    """Radiance (H,W,3) with a laser scaler's two red dots (see the module doc)."""
    H, W = radiance.shape[:2]
    s = scale / 0.5
    half = float(rng.uniform(10, 60)) * s
    mid = np.array([W / 2, H / 2]) + rng.normal(0, 0.05, 2) * [W, H]
    glow = np.zeros((H, W), np.float32)
    core = float(rng.uniform(0.6, 1.6)) * s
    for sx in (-1.0, 1.0):
        u, v = mid[0] + sx * half, mid[1] + rng.normal(0, 0.3)
        cv2.circle(glow, (int(u * 4), int(v * 4)), max(1, int(core * 4)), 1.0, -1, cv2.LINE_AA, shift=2)
    glow = cv2.GaussianBlur(glow, (0, 0), 0.8 * s) * 4.0 + cv2.GaussianBlur(glow, (0, 0), 3.0 * s) * 1.5
    out = radiance.astype(np.float32).copy()
    out += glow[:, :, None] * np.array([1.0, 0.08, 0.05], np.float32)[None, None, :]
    return out
