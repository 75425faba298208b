"""Held-out range sensors (calib_core.synth.range.heldout) and what the detector needed for them."""

import numpy as np
import pytest

from calib_core.detect.sonar.detect import detect_sphere_in_cloud
from calib_core.detect.sonar.fit import robust_sigma
from calib_core.detect.sonar.outline import attached_sectors, sample_spacing_rad
from calib_core.synth.range.capture import HELDOUT, range_capture


@pytest.mark.parametrize("sensor", HELDOUT)
def test_a_heldout_sensor_is_deterministic_and_its_plain_ball_is_found(sensor):
    P1, c1, r1 = range_capture(5, sensor, "stick")
    P2, c2, r2 = range_capture(5, sensor, "stick")
    assert np.array_equal(P1, P2) and np.array_equal(c1, c2) and r1 == r2
    assert not np.array_equal(P1, range_capture(6, sensor, "stick")[0])
    P, c, r = range_capture(5, sensor, "stick", radius_m=0.25, near_far_m=(1.5, 2.0))
    det = detect_sphere_in_cloud(P, r, 0.0)
    assert det.found, det.reason
    assert np.linalg.norm(det.center_sonar_m - c) < 0.015


def test_lidar128_rings_have_their_own_noise_and_stereo_depth_comes_in_steps():
    from calib_core.synth.range.heldout import StereoConfig, simulate_stereo
    from calib_core.synth.scene import Rect, Scene

    wall = Scene((Rect((3.0, 0, 0), (-1, 0, 0), (4.0, 4.0), u=(0, 1, 0)),))
    P = simulate_stereo(wall, np.eye(4), StereoConfig(subpixel_px=0.005, hole_rate=0.0), np.random.default_rng(1)).points_m
    levels = np.unique(np.round(P[:, 0], 6))
    assert 2 <= len(levels) <= 10  # a flat wall 3 m off: a few disparity steps, ~5 cm apart
    assert np.diff(levels).min() > 0.03


def test_robust_sigma_does_not_collapse_on_quantised_ranges():
    rng = np.random.default_rng(0)
    g = rng.standard_normal(20_000) * 0.01
    assert robust_sigma(g) == pytest.approx(0.01, rel=0.05)
    q = np.round(g / 0.02) * 0.02  # two thirds of the values on one step: the MAD is 0
    assert 1.4826 * np.median(np.abs(q)) == 0.0
    assert robust_sigma(q) > 0.005


def test_stereo_ball_whose_planes_are_single_depth_steps_is_found():
    # the floor and wall of this capture come out as exact disparity steps: their "noise" was 0
    # and the ball was refused "not sphere-shaped (fit sigma 11 mm, sensor noise 0 mm)"
    P, c, r = range_capture(1000, "stereo", "chair")
    det = detect_sphere_in_cloud(P, r, 0.0)
    assert det.found, det.reason
    assert np.linalg.norm(det.center_sonar_m - c) < 0.02


def test_a_fattened_rim_is_not_an_attachment_but_a_seat_is():
    rng = np.random.default_rng(3)
    c, r = np.array([2.0, 0.0, 0.0]), 0.2
    alpha = np.arcsin(r / 2.0)
    step = np.deg2rad(0.5)
    g = np.arange(-0.25, 0.25, step)
    A, E = np.meshgrid(g, g)
    D = np.stack([np.cos(E) * np.cos(A), np.cos(E) * np.sin(A), np.sin(E)], -1).reshape(-1, 3)
    theta = np.arccos(D[:, 0])
    rim = (theta > alpha) & (theta < alpha + 1.5 * step)
    ok = (theta <= alpha + 1.5 * step) | (rng.random(len(D)) < 0.0)  # nothing behind: holes
    R = np.full(len(D), 1.85)
    R[rim] = 1.86  # fattened pixels at the ball's edge range
    assert sample_spacing_rad(D[ok]) == pytest.approx(step, rel=0.2)
    assert not attached_sectors(R[ok], D[ok], c, r, alpha, 0.0, 0.005).any()
    seat = (D[:, 2] < -np.sin(alpha) * 0.9) & (theta < alpha * 1.8)  # a surface below continues it
    ok2 = ok | seat
    assert attached_sectors(R[ok2], D[ok2], c, r, alpha, 0.0, 0.005).sum() >= 2


def test_a_held_ball_in_front_of_its_carrier_is_taken_over_the_body_it_hides(tmp_path):
    # carried seed 74, p07 (RGB-D): the ball at 1.21 m hides part of the carrier's torso 0.6 m
    # behind it; what is left of the torso round that hole fits a sphere of the ball's size with
    # more evidence than the ball (it was refused "two candidates")
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from benchmarks.bench_detection_range import _sweep_session
    from calib_core.io.clouds import load_cloud
    from calib_core.session import load_session
    from calib_core.synth.ground_truth import load_ground_truth

    root = _sweep_session(tmp_path, "carried", 74, 0.5)
    s, gt = load_session(root), load_ground_truth(root)
    cap = next(c for c in s.captures if c.id == "p07")
    det = detect_sphere_in_cloud(load_cloud(cap.cloud_path).points_m, s.sphere_radius_m, 0.0)
    assert det.found, det.reason
    assert np.linalg.norm(det.center_sonar_m - np.asarray(gt["captures"]["p07"]["center_sonar_m"])) < 0.005
    assert det.extras["resolved_by"].startswith("occlusion:")
    assert det.extras["other_candidates"]
