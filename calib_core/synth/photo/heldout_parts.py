"""Shared pieces of the held-out image kinds (:mod:`calib_core.synth.photo.heldout`): a
placement by apparent size, a hand holding the ball, and the camera artefacts drawn per image.

- :func:`place_by_size`: the ball's apparent radius is drawn log-uniform from ``r_px`` (the
  issue's range: about 15 px at 960x540 up to half the frame height), then a pixel where the
  whole outline stays 2 px inside the image; the centre lies on that pixel's ray at the
  distance giving that radius (exact cone: r_px = f tan(asin(R / d))), at least ``min_dist_m``
  from the camera (no camera focuses closer).
- :func:`hand_blob`: a palm (sphere) and three or four fingers (capsules) lying on the ball's
  surface at its outline, on its lower or lateral side as the camera sees it, tilted towards
  the camera so that they hide part of the outline (at most ``max_hidden`` of it, checked with
  :func:`calib_core.synth.occlusion.occluded_fraction`; the hand is shrunk until it is), and
  a forearm leaving the ball away from the camera. Skin tones vary.
- :func:`camera_artefacts`: on about half the images a JPEG round trip at quality 60-90; on
  about a third high sensor gain (read noise 4-10 DN, shot-noise scale 0.5-2); on about a
  third a defocus disc of 1-3 px or a frame shake of 2-6 px (at 960x540; scaled with the
  image).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from calib_core.geometry import transform_points
from calib_core.synth.camera_render import RenderOptions, camera_rays
from calib_core.synth.occlusion import occluded_fraction
from calib_core.synth.rig import look_at_pose, silhouette_uv
from calib_core.synth.scene import Capsule, Group, Material, Scene, Sphere


def place_by_size(rng, cam, T_wc, radius_m: float, r_px: tuple, ok=lambda c: True, min_dist_m: float = 0.3,
                  v_range=(0.0, 1.0), tries: int = 600, u_range=(0.0, 1.0)):
    """World centre of a ball of ``radius_m`` seen with a radius in ``r_px`` (log-uniform), whole
    in the image, its pixel's row in ``v_range`` and column in ``u_range`` (fractions of the
    height and width), passing ``ok``."""
    f = 0.5 * (cam.fx + cam.fy)
    W, H = cam.width_px, cam.height_px
    hi = min(r_px[1], f * np.tan(np.arcsin(min(radius_m / min_dist_m, 0.99))))
    lo = min(r_px[0], hi)
    for _ in range(tries):
        r = float(np.exp(rng.uniform(np.log(lo), np.log(hi))))
        d = radius_m / np.sin(np.arctan(r / f))
        m = 1.15 * r + 2
        if W <= 2 * m or H <= 2 * m:
            continue
        u_lo, u_hi = max(m, u_range[0] * W), min(W - m, u_range[1] * W)
        v_lo, v_hi = max(m, v_range[0] * H), min(H - m, v_range[1] * H)
        if u_lo > u_hi or (v_lo > v_hi and v_range[0] * H < H - m):
            continue  # the ball at this size does not fit in the asked part of the frame
        u = rng.uniform(u_lo, u_hi)
        v = rng.uniform(v_lo, v_hi) if v_range[0] * H < H - m else H / 2
        ray = camera_rays(cam, np.array([[u, v]]))[0]
        sil = silhouette_uv(cam, d * ray, radius_m)
        c = transform_points(T_wc, (d * ray)[None])[0]
        if np.isfinite(sil).all() and cam.in_image(sil, margin_px=2.0).all() and ok(c):
            return c
    raise RuntimeError("could not place the ball at the drawn size")


def _hand(rng, c, radius_m: float, eye, size: float, skin) -> Group:
    """Palm (a capsule across), fingers (capsules) curling over the ball towards the camera,
    and a forearm leaving away from the camera; ``size`` 1 = an adult hand."""
    view = c - np.asarray(eye, float)
    view /= np.linalg.norm(view)
    side = np.cross(view, [0, 0, 1.0])
    side /= max(np.linalg.norm(side), 1e-9)
    up = np.cross(side, view)  # image "up" as seen from the eye, across the view
    ang = np.deg2rad(rng.uniform(-80, 80))
    u = -np.cos(ang) * up + np.sin(ang) * side  # from the centre towards the held outline point
    t = np.cross(u, view)
    t /= np.linalg.norm(t)
    half_w, palm_r, finger_r = 0.035 * size, 0.018 * size, 0.008 * size
    palm = c + u * (radius_m + palm_r) + view * 0.2 * radius_m
    parts = [Capsule(tuple(palm - t * half_w), tuple(palm + t * half_w), palm_r)]
    n_f = int(rng.integers(3, 5))
    reach = float(rng.uniform(0.5, 1.1))  # how far the fingers curl over the front (rad)
    for k in range(n_f):
        off = (k - (n_f - 1) / 2) / max(n_f - 1, 1) * 2 * half_w
        tip = c + (u * np.cos(reach) - view * np.sin(reach)) * (radius_m + finger_r) + t * off
        parts.append(Capsule(tuple(palm + t * off), tuple(tip), finger_r))
    arm_end = palm + u * 0.2 + view * 0.25 + np.array([0, 0, -0.1])
    parts.append(Capsule(tuple(palm), tuple(arm_end), 1.3 * palm_r))
    return Group(tuple(parts), Material(tuple(skin), 0.6), tag="stand")


def hand_blob(rng, c, radius_m: float, eye, T_wc, ball, max_hidden: float = 0.35) -> Group:
    """A hand on the ball hiding at most ``max_hidden`` of it (see the module doc)."""
    skin = np.array([0.85, 0.66, 0.54]) * rng.uniform(0.35, 1.05)
    size = float(np.clip(rng.uniform(0.8, 1.1) * radius_m / 0.11, 0.6, 1.3))
    state = rng.bit_generator.state
    for _ in range(8):
        rng.bit_generator.state = state
        hand = _hand(rng, np.asarray(c, float), radius_m, eye, size, np.clip(skin, 0, 1))
        if occluded_fraction(Scene((ball, hand)), 0, T_wc, c, radius_m) <= max_hidden:
            return hand
        size *= 0.75
    return hand


def camera_artefacts(rng, photo, opts: RenderOptions, scale: float):
    """(photo, opts) with the camera artefacts of this image (see the module doc)."""
    s = scale / 0.5
    jpeg_q = int(rng.integers(60, 91)) if rng.random() < 0.5 else 0
    if rng.random() < 0.33:
        opts = replace(opts, noise_dn=float(rng.uniform(4.0, 10.0)), shot_gain=float(rng.uniform(0.5, 2.0)))
    defocus, shake = 0.0, ()
    r = rng.random()
    if r < 0.17:
        defocus = float(rng.uniform(1.0, 3.0)) * s
    elif r < 0.33:
        a, length = rng.uniform(0, 2 * np.pi), float(rng.uniform(2.0, 6.0)) * s
        shake = (length * np.cos(a), length * np.sin(a))
    return replace(photo, jpeg_quality=jpeg_q, defocus_px=defocus, shake_px=shake), opts


def artefact_label(photo, opts) -> str:
    tags = [f"jpeg{photo.jpeg_quality}" if photo.jpeg_quality else "",
            "gain" if opts.noise_dn >= 4.0 else "",
            f"defocus{photo.defocus_px:.1f}" if photo.defocus_px else "",
            f"shake{np.hypot(*photo.shake_px):.1f}" if photo.shake_px else ""]
    return "+".join(t for t in tags if t) or "clean"


def eye_of(T_wc) -> np.ndarray:
    return np.asarray(T_wc)[:3, 3]


def camera_forward(T_wc) -> np.ndarray:
    return np.asarray(T_wc)[:3, 2]


def pose_ahead(rng, T_wc, pitch_deg: tuple) -> np.ndarray:
    """A camera at the rig's eye looking 3 m ahead along the rig's heading, pitched up by a
    uniform draw in ``pitch_deg`` (lo, hi) degrees (negative: down)."""
    eye = eye_of(T_wc)
    fwd = camera_forward(T_wc)
    yaw = np.arctan2(fwd[1], fwd[0])
    pitch = np.deg2rad(rng.uniform(*pitch_deg))
    ahead = np.array([np.cos(yaw) * np.cos(pitch), np.sin(yaw) * np.cos(pitch), np.sin(pitch)])
    return look_at_pose(rng, eye, eye + 3.0 * ahead)

