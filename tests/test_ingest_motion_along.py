"""The import's motion check sees a drift along the line of sight through the detector's own
distance (the exact cone fit's ``range_m`` and its sigma), counting only what that precision vouches for."""

from __future__ import annotations

import numpy as np
import pytest

from calib_core.detect.image.detect import background_model, detect_sphere_in_image, prepare_background
from calib_core.geometry import invert_T, transform_points
from calib_core.ingest.motion import TOLERANCE_M, TOLERANCE_PX, Track, capture_motion, motion_of
from calib_core.synth import world
from calib_core.synth.camera_render import RenderOptions, finish_image, render_radiance
from calib_core.synth.rig import sample_rig
from calib_core.synth.scene import Scene
from tests.conftest import tiny_camera


class _Det:
    def __init__(self, uv, r_m, sig_m):
        self.found, self.center_uv_px, self.radius_px, self.range_m = True, uv, 20.0, r_m
        self.extras = {"range_sigma_m": sig_m}


def _track(ranges, sigma):
    tr = Track()
    for j, r in enumerate(ranges):
        tr.add(j, _Det([32.0, 24.0], r, sigma))
    return tr


def test_change_of_distance_counts_beyond_its_sigmas():
    cam = tiny_camera()
    along = [2.00, 2.02, 2.04, 2.06, 2.08]  # 8 cm along the line of sight, the image centre still
    m = motion_of(_track(along, 0.003), 2, cam)
    assert m["motion_px"] == 0 and m["motion_along_m"] == pytest.approx(0.04 - 3 * np.hypot(0.003, 0.003), abs=1e-4)
    assert m["motion_m"] > TOLERANCE_M
    # the same change with a distance known to 2 cm is not vouched for
    assert motion_of(_track(along, 0.02), 2, cam)["motion_m"] == 0
    # a still target: distances within their noise
    still = 2.0 + np.array([0.004, -0.003, 0.0, 0.005, -0.004])
    assert motion_of(_track(still, 0.003), 2, cam)["motion_m"] == 0
    # no stated sigma (an older detection): the distance's change is not counted
    tr = _track(along, 0.003)
    tr.range_sigma_m = [None] * 5
    assert motion_of(tr, 2, cam)["motion_along_m"] == 0


def _frames_along_sight(distances_m, seed=3):
    """Rendered frames of a sphere on one camera ray at ``distances_m``, with fresh noise each."""
    rng = np.random.default_rng([seed, 42])
    rig = sample_rig(rng, 1, 576, 324, 0.3)
    cam, T_wc = rig.cams["cam1"]
    radius = 0.12
    style = world.sample_target_style(rng, radius)
    water = world.sample_water(rng, False)
    surface_z, static = world.surface_and_pontoons(rng, rig, "canal")
    opts = RenderOptions(aa=3, blur_sigma_px=0.5, noise_dn=1.5, shot_gain=0.1)
    L_bg, _ = render_radiance(Scene(tuple(static)), cam, T_wc, water, aa=2)
    bg = prepare_background(background_model([finish_image(L_bg, opts, rng) for _ in range(2)]))
    ray = transform_points(T_wc, np.array([[0.05, 0.03, 1.0]]))[0] - T_wc[:3, 3]
    ray /= np.linalg.norm(ray)
    frames = []
    for d in distances_m:
        c = T_wc[:3, 3] + d * ray
        L, _ = render_radiance(Scene(tuple(static + [world.target(style, c, radius, False)])), cam, T_wc, water, aa=3)
        frames.append(finish_image(L, opts, rng))
    C = transform_points(invert_T(T_wc), (T_wc[:3, 3] + ray)[None])[0]
    assert np.allclose(C[:2] / C[2], [0.05, 0.03])  # one camera ray: the centre projects to one pixel
    return cam, radius, bg, frames


def test_rendered_drift_along_the_line_of_sight_is_flagged_and_a_still_one_is_not():
    d = [1.56, 1.58, 1.60, 1.62, 1.64]  # 8 cm straight along the camera's ray: the image centre does not move
    cam, radius, bg, frames = _frames_along_sight(d + [1.60] * 5)
    tracks = {"moving": Track(), "still": Track()}
    for j, img in enumerate(frames):
        det = detect_sphere_in_image(img, cam, radius, background=bg)
        tracks["moving" if j < 5 else "still"].add(j, det)
    moving = capture_motion({"cam1": tracks["moving"]}, {"cam1": 2}, {"cam1": cam}, TOLERANCE_PX, TOLERANCE_M)
    m = moving["cameras"]["cam1"]
    assert m["motion_px"] < 1.0  # invisible to the image track ...
    assert moving["moved"] and 0.02 < m["motion_m"] <= 0.04  # ... seen along the ray, never overstated
    still = capture_motion({"cam1": tracks["still"]}, {"cam1": 2}, {"cam1": cam}, TOLERANCE_PX, TOLERANCE_M)
    assert not still["moved"] and still["cameras"]["cam1"]["motion_m"] < 0.005
