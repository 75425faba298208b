"""A side-lit ball's image centre moves off the limb's centre by up to a few tenths of a px (the
located edges lie off the limb where its step is weak or crosses the background's level, slowly
around the outline); the stated covariance must cover that (calib_core.detect.image.limb), and
an evenly lit ball must keep its tight covariance."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from calib_core.detect.image.detect import detect_sphere_in_image
from calib_core.detect.image.limb import LOPSIDED_HARMONIC_FACTOR, harmonic_power_px2, lopsided_floor_px2

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_detect_image_scenes import make_camera, render, sphere_pose_at  # noqa: E402

CHI2_2_99 = 9.21


def _ball(seed: int, to_light, ambient: float, bg_dn: float, distance_m: float = 1.0):
    cam = make_camera(960, 540, 600.0)
    rng = np.random.default_rng(seed)
    bg = np.full((540, 960, 3), bg_dn, np.float32)
    img, truth = render(cam, bg, sphere_pose_at(cam, (470, 280), distance_m), 0.11, rng, colour=(200, 180, 160),
                        mesh=False, chain=False, blur_px=1.0, noise=2.0, light=(np.asarray(to_light, float), ambient))
    det = detect_sphere_in_image(img, cam, 0.11)
    assert det.found, det.reason
    return det, det.center_uv_px - truth


def test_the_floor_is_the_seen_harmonics_power_less_the_noise():
    th = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    # a deviation of 0.3 px in the second harmonic: its power, per component of orders 2 and 3
    assert np.isclose(harmonic_power_px2(0.3 * np.cos(2 * th), th), 0.3 ** 2 / 4)
    # the constant and the first harmonic are the fit's radius and centre: not counted
    assert harmonic_power_px2(0.5 + 0.4 * np.cos(th) - 0.2 * np.sin(th), th) < 1e-20
    assert np.isclose(lopsided_floor_px2(0.3 * np.cos(2 * th), th, 0.0, 1.0), LOPSIDED_HARMONIC_FACTOR ** 2 * 0.3 ** 2 / 4)
    # white noise of 0.2 px: what it puts in one component (2 sigma^2 / N) is taken out, on average
    rng = np.random.default_rng(3)
    floors = [lopsided_floor_px2(rng.normal(0, 0.2, 200), th, 0.2, 1.0) for _ in range(200)]
    powers = [harmonic_power_px2(rng.normal(0, 0.2, 200), th) for _ in range(200)]
    assert np.isclose(np.mean(powers), 2 * 0.2 ** 2 / 200, rtol=0.2)
    # (what is left is the positive part of a chi-square of 4 dof about its mean: ~1/3 of it, 0.01 px)
    assert np.mean(floors) < 0.4 * np.mean(powers)
    assert lopsided_floor_px2(np.zeros(5), th[:5], 0.1, 1.0) == 0.0  # too few points


@pytest.mark.parametrize("to_light, ambient, bg_dn", [
    # lit from the right and the front over a background as bright as the ball's shaded side:
    # the limb's step crosses zero around the outline, the edges there read off the limb
    ((0.5, 0.0, -np.sqrt(0.75)), 0.05, 60.0),
    # lit from the upper left, no ambient, mid-grey background
    ((0.5 * np.cos(np.radians(-30)), 0.5 * np.sin(np.radians(-30)), -np.sqrt(0.75)), 0.0, 40.0),
])
@pytest.mark.parametrize("seed", [0, 1])
def test_a_side_lit_balls_shift_is_covered(seed, to_light, ambient, bg_dn):
    """The centre is 0.2-0.3 px off (stated 0.04-0.06 px without the floor: squared Mahalanobis
    12-16); with the floor the error lies within the 99 % ellipse."""
    det, err = _ball(seed, to_light, ambient, bg_dn, distance_m=1.0 if bg_dn > 50 else 0.8)
    assert np.hypot(*err) > 0.15  # the shift is there (the detector does not remove it)
    assert np.hypot(*err) < 1.0
    m2 = float(err @ np.linalg.solve(det.cov_uv_px2, err))
    assert m2 < CHI2_2_99, (err, det.cov_uv_px2)
    assert det.extras["lopsided_limb_px"] > 0.1
    # and the floor is not many times the error (the capture keeps its weight)
    assert np.sqrt(np.trace(det.cov_uv_px2) / 2) < 3 * np.hypot(*err)


@pytest.mark.parametrize("seed", [0, 1])
def test_an_evenly_lit_ball_is_neither_moved_nor_widened(seed):
    # uniform light (ambient only) on a dark background: every edge the same step
    det, err = _ball(seed, (0.0, 0.0, -1.0), 1.0, 5.0)
    assert np.hypot(*err) < 0.02
    assert det.extras["lopsided_limb_px"] < 0.01
    assert np.sqrt(np.trace(det.cov_uv_px2) / 2) < 0.05


@pytest.mark.parametrize("seen", [0.5, 0.35])
def test_a_partly_hidden_outlines_noise_does_not_blow_the_floor_up(seen):
    """On an arc (half the outline hidden: the free search accepts 0.5 of it, the look 0.35) the
    harmonics 0-3 are nearly collinear and the lstsq amplifies the edges' noise many times beyond
    the full circle's 2 sigma^2 / N: white noise alone gave a floor of 0.35 px (half) and 3.7 px
    (0.35) RMS for edges of 0.2 px. Only a smooth deviation the noise cannot explain may count."""
    rng = np.random.default_rng(7)
    n = int(300 * seen)
    th = np.linspace(0, 2 * np.pi * seen, n, endpoint=False)
    floors = [lopsided_floor_px2(rng.normal(0, 0.2, n), th, 0.2, 1.0) for _ in range(200)]
    assert np.sqrt(np.mean(floors)) < 0.05
    # a true 0.5 px third harmonic on the half arc still stands out (a second one there is mostly taken
    # into the centre and the radius: the data cannot tell it)
    if seen == 0.5:
        assert np.mean([lopsided_floor_px2(0.5 * np.cos(3 * th) + rng.normal(0, 0.2, n), th, 0.2, 1.0)
                        for _ in range(20)]) > 0.1 ** 2
