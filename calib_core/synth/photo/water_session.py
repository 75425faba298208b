"""The "underwater" session look (``Preset.photo = "underwater"``): the held-out underwater image
kind's water and light (:mod:`calib_core.synth.photo.heldout`, :mod:`calib_core.synth.photo.water`)
in a sonar + camera session.

- per session (:func:`session_parts`): a float's colour (orange, white, yellow or dark, as the
  image kind draws it), a sand or gravel seabed texture, the water (per-channel attenuation, red
  strongest, blue ocean or green coastal; backscatter veil; the ball's distance from the cameras,
  1-4 m, stays within ln 4 / c_green so the ball stays visible), and which lights the dive has:
  caustics (half of the sessions), a dive light (half), marine snow (60 %);
- per capture (:func:`capture_photo`): sunlight from above (tilted), caustics on everything the
  sun reaches, the dive light beside the first camera aimed at the ball (a diver lights the
  target), its glow in the water, and how much snow drifts through this capture;
- per camera image: the snow particles (:func:`add_snow`) and the camera's own effects
  (vignetting, white balance, metered exposure: :func:`calib_core.synth.photo.session.render_capture`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from calib_core.synth.camera_render import Water
from calib_core.synth.photo.effects import BallLook, Photo
from calib_core.synth.photo.heldout import FLOATS
from calib_core.synth.photo.water import marine_snow
from calib_core.synth.scene import Material

MAX_BALL_DIST_M = 4.0  # the session's farthest sphere from a camera (calib_core.synth.rig: 1-4 m)


@dataclass(frozen=True)
class DiveLight:
    """The lights of one dive: caustic strength (0 = none) and scale, dive light gain (0 = none)
    and beam power, marine snow (0 = none: particles per image at 960x540)."""

    caustic: float
    caustic_scale_m: float
    spot_gain: float
    spot_power: float
    snow: float


def session_parts(rng, radius_m: float) -> tuple:
    """(ball Material, BallLook, seabed Material, wall Material, Water, DiveLight) of one session."""
    alb = np.array(FLOATS[int(rng.choice(len(FLOATS), p=[f[1] for f in FLOATS]))][0]) * rng.uniform(0.85, 1.05)
    ball = Material(tuple(float(a) for a in np.clip(alb, 0, 1)), 0.9, "foam", 0.02, float(rng.uniform(0.0, 0.08)),
                    int(rng.integers(1 << 30)))
    look = BallLook((0.0, 0.0, 0.0), radius_m, ks=float(rng.uniform(0.0, 0.6)), shininess=float(rng.uniform(20, 100)))
    rock = rng.random() < 0.4
    bed_alb = np.array((0.36, 0.34, 0.30) if rock else (0.58, 0.53, 0.40)) * rng.uniform(0.7, 1.2)
    seabed = Material(tuple(float(a) for a in bed_alb), 0.5, "gravel" if rock else "sand",
                      float(rng.uniform(0.08, 0.3)), float(rng.uniform(0.3, 0.8)), int(rng.integers(1 << 30)))
    wall = Material((0.30, 0.31, 0.30), 0.8, "noise", 0.2, 0.4, int(rng.integers(1 << 30)))
    water, spot = _water(rng)
    light = DiveLight(float(rng.uniform(0.3, 1.0)) if rng.random() < 0.5 else 0.0, float(rng.uniform(0.15, 0.5)),
                      float(rng.uniform(0.3, 1.5)) if spot else 0.0, water.spot_power,
                      float(rng.uniform(20, 300)) if rng.random() < 0.6 else 0.0)
    return ball, look, seabed, wall, water, light


def _water(rng) -> tuple[Water, bool]:
    """The water of one dive (as the underwater image kind draws it, the ball within ln 4 / c_green)."""
    c_g = float(rng.uniform(0.06, np.log(4.0) / MAX_BALL_DIST_M))
    ocean = rng.random() < 0.5
    c_rgb = (c_g + float(rng.uniform(0.3, 0.7)), c_g,
             c_g * float(rng.uniform(0.5, 0.9) if ocean else rng.uniform(1.2, 2.0)))
    tint = (np.array([0.05, 0.30, 0.55]) if ocean else np.array([0.08, 0.45, 0.42])) * rng.uniform(0.5, 1.1)
    spot = rng.random() < 0.5
    side = rng.normal(0, 1, 3)
    water = Water(c_g, tuple(float(t) for t in tint), up_gain=float(rng.uniform(0.4, 1.0)),
                  side_dir=tuple(side / np.linalg.norm(side)), side_gain=0.0, light_rgb=(0.95, 1.0, 1.0),
                  ambient=float(rng.uniform(0.2, 0.45)), diffuse=float(rng.uniform(0.3, 0.8)), attenuation_rgb=c_rgb,
                  spot_veil=float(rng.uniform(0.05, 0.4)) if spot else 0.0, spot_power=float(rng.uniform(4, 25)))
    return water, spot


def capture_photo(rng, light: DiveLight, ball: BallLook, centre, radius_m: float, eye) -> tuple[Photo, float]:
    """(Photo, snow particles per 960x540 image) of one capture: sun from above, caustics, the dive light."""
    c = np.asarray(centre, float)
    tilt = rng.normal(0, 0.25, 2)
    photo = Photo(key_dir=(float(tilt[0]), float(tilt[1]), 1.0), softness=float(rng.uniform(0.05, 0.2)),
                  occluders=((tuple(float(x) for x in c), float(radius_m)),), ao=float(rng.uniform(0.7, 1.0)),
                  ball=replace(ball, centre_m=tuple(float(x) for x in c), radius_m=float(radius_m)))
    if light.caustic:
        photo = replace(photo, caustic=light.caustic, caustic_scale_m=light.caustic_scale_m,
                        caustic_seed=int(rng.integers(1 << 30)))
    if light.spot_gain:
        pos = np.asarray(eye, float) + [0, 0, 0.15]
        axis = c - pos + rng.normal(0, 0.1, 3) * np.linalg.norm(c - pos)
        photo = replace(photo, spot_gain=light.spot_gain, spot_pos=tuple(float(x) for x in pos),
                        spot_dir=tuple(float(x) for x in axis / np.linalg.norm(axis)), spot_power=light.spot_power)
    snow = light.snow * float(rng.uniform(0.5, 1.5)) if light.snow else 0.0
    return photo, snow


def water_for(water: Water, photo: Photo) -> Water:
    """The session's water with the dive light's glow along this capture's light axis."""
    if water.spot_veil > 0 and photo.spot_gain > 0:
        return replace(water, spot_dir=photo.spot_dir)
    return replace(water, spot_veil=0.0) if water.spot_veil > 0 else water


def add_snow(L: np.ndarray, rng, snow: float, scale: float) -> np.ndarray:
    """Marine snow on one image's radiance (``snow`` particles at 960x540, scaled by the image area)."""
    if snow <= 0:
        return L
    s = scale / 0.5
    return marine_snow(L, rng, int(snow * s * s), (0.4 * s, 2.5 * s), float(rng.uniform(0.3, 0.9)),
                       float(rng.uniform(1.0, 4.0)) * s)
