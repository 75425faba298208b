"""A motion-smeared ball read as ramps (issue 11, twenty-second round; calib_core.detect.image.smear).

A ball moving during the exposure images as its disc convolved with a line: across the motion its
edge is a ramp of width ~ L |cos theta|, whose middle is the outline at mid-exposure; the still
scene's sharp edges show through it and took the peak readings anywhere on the ramp (motion s1017:
1.89 px off with edge RMS 0.30 on 61 % of the outline). The smear is measured from the edge widths'
anisotropy around the outline and each edge is read at the middle of the ramp of its width.
"""

import numpy as np
import pytest

from calib_core.detect.image import smear
from calib_core.detect.image.detect import detect_sphere_in_image
from calib_core.detect.image.predicted import detect_at_prediction
from tests.test_detect_image_flow import RADIUS_M, _bricks, _cam, _finish, _truth
from tests.test_look_blur import _smeared


def test_the_smear_is_measured_from_the_widths_anisotropy():
    rng = np.random.default_rng(3)
    theta = np.linspace(-np.pi, np.pi, 180, endpoint=False)
    L, phi = 12.0, np.radians(30.0)
    w = np.sqrt(2.0 ** 2 + (L * np.cos(theta - phi)) ** 2) + rng.normal(0, 0.7, theta.size)
    sm = smear.measure(theta, w, 1.1)
    assert sm.real
    assert sm.length_px == pytest.approx(L, abs=1.0)
    assert abs((sm.angle_rad - phi + np.pi / 2) % np.pi - np.pi / 2) < np.radians(5)
    # widths of one size all round, or varying at random: no smear
    assert not smear.measure(theta, 3.0 + rng.normal(0, 0.7, theta.size), 1.1).real
    assert not smear.measure(theta, rng.uniform(1.5, 15.0, theta.size), 1.1).real
    # widths that vary with the angle but are nowhere a sharp edge's (oriented texture): no smear
    wide = np.sqrt(9.0 ** 2 + (L * np.cos(theta - phi)) ** 2) + rng.normal(0, 0.7, theta.size)
    assert not smear.measure(theta, wide, 1.1).real


def test_a_ramp_is_read_at_its_middle_whatever_its_width():
    t = np.arange(-20.0, 20.01, smear.STEP_PX)
    rows = []
    for w, t0 in ((0.0, 1.3), (6.0, -2.2), (14.0, 0.7)):
        r = np.clip(0.5 - (t - t0) / max(w, 1e-6), 0, 1)
        rows.append(np.stack([40 + 120 * r, 60 + 50 * r, 200 - 90 * r], axis=1))
    prof = np.array(rows)
    widths, templates, _ = smear.bank(60.0)
    E = smear.energies(prof, templates)
    band = np.abs(t) <= 5.0
    wf = smear.free_widths(E, widths, band)
    assert wf == pytest.approx([0.0, 6.0, 15.0], abs=1.6)
    te, _ = smear.edges_at_widths(E, widths, np.array([0.0, 6.0, 14.0]), t, band)
    assert te == pytest.approx([1.3, -2.2, 0.7], abs=0.15)


def _smeared_case(seed, C, motion_px):
    rng = np.random.default_rng(seed)
    cam = _cam()
    uv, r = _truth(cam, C)
    img = _finish(_smeared(cam, _bricks(cam.height_px, cam.width_px, rng), C, motion_px * C[2] / cam.fx), rng)
    return cam, uv, r, img


def test_a_smeared_ball_on_bricks_is_read_as_a_smear():
    # (before: found 0.43 px off from the peaks, edge RMS 0.67 px, no smear measured)
    cam, uv, _, img = _smeared_case(6, (0.6, -0.3, 3.0), 12.0)
    det = detect_sphere_in_image(img, cam, RADIUS_M)
    assert det.found, det.reason
    assert det.extras["smear_px"] == pytest.approx(12.0, abs=2.0)
    assert abs((det.extras["smear_deg"] + 90) % 180 - 90) < 8  # the motion is along x
    assert np.hypot(*(det.center_uv_px - uv)) < 0.6


def test_a_sharp_ball_is_not_read_as_a_smear():
    cam, uv, _, img = _smeared_case(6, (0.6, -0.3, 3.0), 0.0)
    det = detect_sphere_in_image(img, cam, RADIUS_M)
    assert det.found, det.reason
    assert "smear_px" not in det.extras
    assert np.hypot(*(det.center_uv_px - uv)) < 0.3


def test_the_look_states_a_floor_that_grows_with_the_measured_smear():
    cam, uv, r, img = _smeared_case(5, (-0.5, 0.2, 3.5), 15.0)
    det = detect_at_prediction(img, cam, RADIUS_M, uv + np.array([2.5, -1.0]), 1.01 * r, shift_frac=0.07)
    assert det.found, det.reason
    assert det.extras["smear_px"] == pytest.approx(15.0, abs=3.0)
    err = det.center_uv_px - uv
    assert np.hypot(*err) < 1.0
    assert float(err @ np.linalg.solve(det.cov_uv_px2, err)) < 13.8
    # the floor is the smear's: a sigma per axis of at least the ramp's scatter across its width
    assert np.sqrt(np.linalg.eigvalsh(det.cov_uv_px2).min()) > 0.5
