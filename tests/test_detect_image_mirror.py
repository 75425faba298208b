"""Mirror pairs (calib_core.detect.image.mirror): a ball and its copy in a plane mirror are one
object (the nearer is the ball, the copy is named); two real balls side by side are not."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from calib_core.detect.image.detect import detect_sphere_in_image
from calib_core.detect.image.mirror import compare, noise_sigma_dn

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the analytic image maker next to this file
from test_detect_image_scenes import make_background, make_camera, render, sphere_pose_at  # noqa: E402

R_M = 0.11


def _lit_ball(shape, radius: float, centre, light, colour=(200, 120, 60)) -> tuple[np.ndarray, np.ndarray]:
    """A Lambertian ball lit from ``light`` (a direction in image x, y, towards the viewer z):
    (colour image contribution, mask), float."""
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]].astype(float)
    x, y = (xx - centre[0]) / radius, (yy - centre[1]) / radius
    inside = x * x + y * y < 1
    z = np.sqrt(np.clip(1 - x * x - y * y, 0, 1))
    L = np.asarray(light, float) / np.linalg.norm(light)
    shade = np.clip(x * L[0] + y * L[1] + z * L[2], 0, 1) * 0.8 + 0.2
    return np.asarray(colour, float)[None, None, :] * shade[..., None], inside


def _two_balls(light_b, colour_b=(200, 120, 60), gain_b=0.9, seed=0):
    """A ball at (80, 100) r 40 lit from the upper left and a second ball at (240, 100) r 36
    lit from ``light_b`` (a mirror copy across the vertical line between them is lit from the
    upper right); noise 3 grey levels."""
    rng = np.random.default_rng(seed)
    img = np.full((200, 320, 3), (40.0, 90.0, 100.0))
    for c, r, light, col, gain in (((80, 100), 40, (-0.6, -0.5, 0.6), (200, 120, 60), 1.0),
                                   ((240, 100), 36, light_b, colour_b, gain_b)):
        ball, m = _lit_ball(img.shape, r, c, light, col)
        img[m] = gain * ball[m]
    return np.clip(img + rng.normal(0, 3, img.shape), 0, 255).astype(np.uint8)


NEAR = {"centre_px": (80.0, 100.0), "radius_px": 40.0, "range_m": 1.0, "range_sigma_m": 0.005}
FAR = {"centre_px": (240.0, 100.0), "radius_px": 36.0, "range_m": 1.11, "range_sigma_m": 0.005}


def test_a_flipped_dimmer_smaller_copy_is_a_mirror_pair():
    img = _two_balls((0.6, -0.5, 0.6))  # lit from the upper right: the ball flipped left-right
    ev = compare(img, NEAR, FAR, noise_sigma_dn(img))
    assert ev.flip_corr > 0.9 and ev.is_pair(), ev


@pytest.mark.parametrize("light_b, colour_b, why", [
    ((-0.6, -0.5, 0.6), (200, 120, 60), "same light, not flipped: a second real ball"),
    ((0.6, -0.5, 0.6), (230, 230, 220), "another colour"),
])
def test_two_real_balls_are_not_a_mirror_pair(light_b, colour_b, why):
    img = _two_balls(light_b, colour_b)
    assert not compare(img, NEAR, FAR, noise_sigma_dn(img)).is_pair(), why


def test_twins_lit_from_above_are_not_a_mirror_pair():
    """Both lit from straight above: the disc looks the same flipped and unflipped, so the flip is
    no evidence of a mirror (two like boulders on a seabed); the pair stays two round objects."""
    rng = np.random.default_rng(3)
    base = np.full((200, 320, 3), (40.0, 90.0, 100.0))
    for c, r in (((80, 100), 40), ((240, 100), 36)):
        ball, m = _lit_ball(base.shape, r, c, (0.0, -0.7, 0.7))
        base[m] = ball[m]
    img = np.clip(base + rng.normal(0, 3, base.shape), 0, 255).astype(np.uint8)
    ev = compare(img, NEAR, FAR, noise_sigma_dn(img))
    assert ev.flip_corr > 0.8 and abs(ev.flip_corr - ev.direct_corr) < 0.05  # alike both ways
    assert not ev.is_pair()


def test_a_copy_brighter_or_nearer_than_the_ball_is_not_a_mirror_pair():
    img = _two_balls((0.6, -0.5, 0.6), gain_b=1.3)
    assert not compare(img, NEAR, FAR, noise_sigma_dn(img)).is_pair()  # brighter than the ball
    img = _two_balls((0.6, -0.5, 0.6))
    same_range = dict(FAR, range_m=1.004)  # within the ranges' uncertainty: which one is nearer?
    assert not compare(img, NEAR, same_range, noise_sigma_dn(img)).is_pair()


def test_noise_estimate_follows_added_noise():
    rng = np.random.default_rng(1)
    flat = np.full((200, 300, 3), 100.0)
    for sigma in (2.0, 8.0):
        img = np.clip(flat + rng.normal(0, sigma, flat.shape), 0, 255).astype(np.uint8)
        assert noise_sigma_dn(img) == pytest.approx(sigma, rel=0.25)


@pytest.mark.parametrize("colour_b, shading_b", [((225, 225, 215), True), ((210, 90, 40), False)],
                         ids=["white-ball", "flat-shaded-orange-ball"])
def test_two_different_real_balls_stay_two_round_objects(colour_b, shading_b):
    """Two solid balls at 1.2 and 1.5 m, the second of another colour or shaded otherwise (flat):
    not merged into a mirror pair; the detector still says "two round objects"."""
    cam = make_camera(960, 540, 600.0)
    rng = np.random.default_rng(21)
    bg = make_background(cam, rng)
    first, _ = render(cam, bg, sphere_pose_at(cam, (300, 250), 1.2), R_M, rng, colour=(210, 90, 40), mesh=False)
    img, _ = render(cam, first.astype(np.float32), sphere_pose_at(cam, (700, 300), 1.5), R_M, rng,
                    colour=colour_b, mesh=False, shading=shading_b)
    det = detect_sphere_in_image(img, cam, R_M)
    assert not det.found and det.reason.startswith("two round objects: ("), det.reason
    assert "mirror_copy" not in det.extras


def test_tank_glass_pane_copy_is_set_aside_and_named():
    """The tank kind, seed 1025 (a glass pane's total reflection: a full-brightness copy of a float
    lit by caustics from one side, its flip matching the ball's; was "two round objects"): the
    ball is found, the copy named."""
    from calib_core.synth.image_cases import render_case

    case = render_case("tank", 1025, 0.25)
    det = detect_sphere_in_image(case.image, case.cam, case.radius_m)
    assert det.found, det.reason
    assert np.hypot(*(det.center_uv_px - case.true_uv_px)) < 0.5
    assert det.extras["mirror_copy"].startswith("mirror copy at (")
    copy_uv = np.asarray(det.extras["mirror_copy_uv_px"])
    assert np.hypot(*(copy_uv - case.true_uv_px)) > 1.5 * case.radius_px  # the copy, beside the ball
