"""One range scale from several cameras' diameter evidence, without a stereo transform."""

from __future__ import annotations

import math

import numpy as np
import pytest

from calib_core.geometry import pose_error, transform_points
from calib_core.solve.model import camera_data
from calib_core.solve.scale import SCALE_TEST_ALPHA
from calib_core.solve.shared_scale import shared_scale
from calib_core.solve.simulate import synthetic_rig
from calib_core.solve.single import solve_camera

REL = 0.001 / 0.22  # 1 mm on a 220 mm sphere


def _cams(rig, k_diam=1.0, seed=0, with_ranges=("cam1", "cam2")):
    rng = np.random.default_rng(seed)
    out = {}
    for c in ("cam1", "cam2"):
        r = (None, None)
        if c in with_ranges:
            true = np.linalg.norm(transform_points(rig.T_cam_sonar[c], rig.X_true_sonar_m), axis=1)
            sig = 0.003 * true
            r = (k_diam * true + rng.normal(0, 1, len(true)) * sig, sig)
        cd = camera_data(c, rig.cameras[c], rig.capture_ids, rig.uv_px[c], rig.cov_uv_px2[c], rig.X_sonar_m,
                         rig.cov_X_m2, *r)
        sol = solve_camera(cd, estimate_scale=False, loo=False)
        out[c] = (sol.data, sol.used, sol.T_cam_sonar)
    return out


def test_two_cameras_without_stereo_share_one_scale():
    rig = synthetic_rig(61, n_captures=12, scale=1.03, sigma_px=0.3, sigma_m=0.003, depth_m=(0.8, 3.0))
    cams = _cams(rig, k_diam=1.0 + 0.0007 / 0.22)
    sh = shared_scale(cams, "auto", REL)
    assert sh.estimated and sh.test["scaled_model_chosen"] and sh.test["p_value"] < SCALE_TEST_ALPHA
    assert sh.sigma >= REL * 0.99  # the diameter's tolerance is common to both cameras: a floor
    assert abs(sh.value - 1.03) < 3 * sh.sigma
    assert set(sh.per_camera) == {"cam1", "cam2"}
    lo, hi = sorted(v["value"] for v in sh.per_camera.values())
    assert lo - 1e-9 <= sh.value <= hi + 1e-9  # a weighted mean of the cameras' own estimates
    for c in ("cam1", "cam2"):
        T, cov = sh.poses[c]
        assert cov.shape == (6, 6) and np.all(np.linalg.eigvalsh(cov) > 0)
        _, dt_new = pose_error(T, rig.T_cam_sonar[c])
        _, dt_old = pose_error(cams[c][2], rig.T_cam_sonar[c])
        assert dt_new < dt_old
    tight = shared_scale(cams, "auto", 0.0)
    assert tight.sigma < sh.sigma


@pytest.mark.parametrize("seed", [62, 63])
def test_no_scale_error_follows_the_stated_test(seed):
    rig = synthetic_rig(seed, n_captures=12, scale=1.0, sigma_px=0.3, sigma_m=0.003, depth_m=(0.8, 3.0))
    sh = shared_scale(_cams(rig, seed=seed), "auto", REL)
    t = sh.test
    assert t["scaled_model_chosen"] == (t["p_value"] < SCALE_TEST_ALPHA)
    if not sh.estimated:
        assert sh.value == 1.0 and sh.poses == {} and "kept at 1" in sh.note
    forced = shared_scale(_cams(rig, seed=seed), "always", REL)
    assert forced.estimated and abs(forced.value - 1.0) < 3 * forced.sigma and "forced" in forced.note


def test_needs_two_cameras_with_ranges():
    rig = synthetic_rig(64, n_captures=10, scale=1.02, depth_m=(0.8, 3.0))
    assert shared_scale(_cams(rig, with_ranges=("cam1",)), "auto", REL) is None


def test_a_scale_known_worse_than_one_percent_is_reported_not_applied():
    """A 6 % scale error seen through image ranges with a 1.5 % systematic (e.g. a 1 px outline
    error on a 67 px sphere): significant, but too poorly known to apply by default; --scale
    ("always") still applies it."""
    from calib_core.solve.scale import MAX_SCALE_SIGMA, image_range_rel_sigma

    rig = synthetic_rig(61, n_captures=12, scale=1.06, sigma_px=0.3, sigma_m=0.003, depth_m=(0.8, 3.0))
    cams = _cams(rig)
    auto = shared_scale(cams, "auto", 0.015)
    assert auto.test["p_value"] < SCALE_TEST_ALPHA  # the deviation is significant ...
    assert not auto.estimated and auto.value == 1.0 and auto.sigma > MAX_SCALE_SIGMA  # ... but not applied
    assert "worse than the 1 %" in auto.note and "--scale" in auto.note
    assert shared_scale(cams, "auto", REL).estimated  # known to 1 %: applied
    forced = shared_scale(cams, "always", 0.015)
    assert forced.estimated and abs(forced.value - 1.06) < 3 * forced.sigma
    # the systematic the tool states: the diameter tolerance and the outline error over the radius
    cd = cams["cam1"][0]
    r_px = cd.cam.fx * 0.11 / float(np.median(cd.range_m))
    assert image_range_rel_sigma(0.22, 0.001, 0.0, cd) == pytest.approx(REL)
    assert image_range_rel_sigma(0.22, 0.001, 1.0, cd) == pytest.approx(math.hypot(REL, 1.0 / r_px))
    assert image_range_rel_sigma(0.22, 0.001, 1.0, None) == pytest.approx(REL)
