"""Range scale chosen on evidence (two cameras, one camera through the diameter), the outlier gate's
invariance to wrong stated sigmas, and the one consistency statistic."""

from __future__ import annotations

import math

import numpy as np
import pytest

from calib_core.geometry import pose_error, transform_points
from calib_core.solve.consistency import NAME, consistency, consistency_phrase
from calib_core.solve.model import camera_data
from calib_core.solve.refine import Link
from calib_core.solve.rig import default_stereo_cov, solve_rig
from calib_core.solve.scale import SCALE_TEST_ALPHA, size_route_caution, stereo_limit_note
from calib_core.solve.simulate import synthetic_rig
from calib_core.solve.single import solve_camera


def cdata(rig, cam="cam1", factor=1.0, X=None, ranges=None):
    X = rig.X_sonar_m if X is None else X
    rng = (None, None) if ranges is None else ranges
    return camera_data(cam, rig.cameras[cam], rig.capture_ids, rig.uv_px[cam], factor**2 * rig.cov_uv_px2[cam], X,
                       factor**2 * rig.cov_X_m2, *rng)


def joint(rig, mode):
    sols = {c: solve_camera(cdata(rig, c), estimate_scale=False, loo=False) for c in ("cam1", "cam2")}
    return solve_rig(sols, {"cam2": Link(rig.T_cam2_cam1, default_stereo_cov())}, "cam1", estimate_scale=mode)


def test_two_cameras_scale_error_is_estimated_without_a_flag():
    rig = synthetic_rig(12, n_captures=12, scale=1.02)
    rs = joint(rig, None)
    assert rs.scale_sigma is not None and rs.scale_test["scaled_model_chosen"]
    assert abs(rs.scale - 1.02) < 0.002
    dr, dt = pose_error(rs.T_cam_sonar["cam1"], rig.T_cam_sonar["cam1"])
    assert math.degrees(dr) < 0.2 and dt < 0.01
    held = joint(rig, False)
    assert held.scale == 1.0 and held.scale_sigma is None and "--no-scale" in held.scale_note


def test_the_scale_says_when_the_stereo_transform_limits_it():
    """With the default stereo uncertainty, the baseline's vergence dominates the scale's sigma
    (what the detections alone give is much smaller); with a near-exact stereo it does not."""
    rig = synthetic_rig(12, n_captures=12, scale=1.02)
    rs = joint(rig, True)
    assert rs.scale_sigma_detections < 0.7 * rs.scale_sigma
    assert "the stereo transform limits it" in stereo_limit_note(rs.scale_sigma, rs.scale_sigma_detections, True)
    sols = {c: solve_camera(cdata(rig, c), estimate_scale=False, loo=False) for c in ("cam1", "cam2")}
    sharp = solve_rig(sols, {"cam2": Link(rig.T_cam2_cam1, default_stereo_cov() * 1e-4)}, "cam1", estimate_scale=True)
    assert sharp.scale_sigma < rs.scale_sigma and sharp.scale_sigma_detections > 0.9 * sharp.scale_sigma
    assert stereo_limit_note(sharp.scale_sigma, sharp.scale_sigma_detections, False) == ""


@pytest.mark.parametrize("seed", [13, 14, 15])
def test_two_cameras_without_scale_error_follow_the_test(seed):
    rig = synthetic_rig(seed, n_captures=12, scale=1.0)
    rs = joint(rig, None)
    t = rs.scale_test
    assert t["level"] == SCALE_TEST_ALPHA and t["scaled_model_chosen"] == (t["p_value"] < SCALE_TEST_ALPHA)
    assert (rs.scale_sigma is None) == (not t["scaled_model_chosen"])
    if not t["scaled_model_chosen"]:
        assert rs.scale == 1.0 and "kept at 1" in rs.scale_note


def _ranges(rig, sigma_m, seed):
    T = rig.T_cam_sonar["cam1"]
    true = np.linalg.norm(transform_points(T, rig.X_true_sonar_m), axis=1)
    noise = np.random.default_rng(seed).normal(0, sigma_m, len(true))
    return true + noise, np.full(len(true), sigma_m)


def test_one_camera_scale_through_the_diameter_with_its_tolerance():
    rig = synthetic_rig(21, n_captures=15, scale=1.03, sigma_px=0.3, sigma_m=0.003, depth_m=(0.8, 3.0))
    no_rng = solve_camera(cdata(rig), loo=False)
    assert no_rng.scale == 1.0 and not no_rng.scale_observable
    rel = 0.001 / 0.22
    sol = solve_camera(cdata(rig, ranges=_ranges(rig, 0.003, 1)), loo=False, diameter_rel_sigma=rel)
    assert sol.scale_observable and sol.scale_sigma is not None
    assert sol.scale_sigma > rel * 0.99  # the diameter's tolerance is a floor under the scale's sigma
    assert abs(sol.scale - 1.03) < 3 * sol.scale_sigma
    tight = solve_camera(cdata(rig, ranges=_ranges(rig, 0.003, 1)), loo=False, diameter_rel_sigma=0.0)
    assert tight.scale_sigma < sol.scale_sigma
    held = solve_camera(cdata(rig, ranges=_ranges(rig, 0.003, 1)), loo=False, estimate_scale=False)
    assert held.scale == 1.0


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_gate_verdict_does_not_depend_on_the_stated_noise_level(seed):
    rig = synthetic_rig(seed, n_captures=10, sigma_px=1.0, sigma_m=0.01)
    X = rig.X_sonar_m.copy()
    X[seed] += np.array([0.0, 0.15, 0.05])  # moved ~16 cm
    used = [solve_camera(cdata(rig, factor=f, X=X), loo=False).used for f in (0.5, 1.0, 2.0)]
    assert not used[1][seed]
    assert all(np.array_equal(u, used[1]) for u in used)


def test_one_consistency_statistic():
    c = consistency(45.0, 20, "cam1 (independent solve)")
    assert c["name"] == NAME and c["ratio"] == pytest.approx(1.5)
    assert 0 < c["p_value"] < 0.01
    text = consistency_phrase(c)
    assert "residual ratio 1.50" in text and "inflated" not in text
    assert "inflated" in consistency_phrase(consistency(500.0, 20, "joint solve"))
    assert "not available" in consistency_phrase(consistency(0.0, 0, "cam1"))


def test_calibrate_reports_the_scale_and_speaks_with_one_voice(tmp_path, capsys):
    import json

    from test_solve_calibrate import write_session

    from sonarcal_cli.main import main

    rig = synthetic_rig(33, n_captures=12, scale=1.02)
    root = write_session(tmp_path / "s", rig)
    assert main(["calibrate", str(root), "--no-loo"]) == 0
    out = capsys.readouterr()
    cal = json.loads((root / "results" / "calibration.json").read_text())
    sc = cal["range_scale"]
    assert sc["estimated"] and abs(sc["value"] - 1.02) < 0.002 and sc["sigma"] > 0 and "stereo" in sc["source"]
    assert "range scale 1.0" in out.out and "residual ratio" in out.out
    text = out.out + out.err
    assert "what the detection uncertainties predict" not in text and "larger than the detections' stated" not in text
    assert main(["calibrate", str(root), "--no-loo", "--no-scale", "--out", str(tmp_path / "c.json")]) == 0
    held = json.loads((tmp_path / "c.json").read_text())["range_scale"]
    assert held["value"] == 1.0 and not held["estimated"] and "held at 1" in capsys.readouterr().out


def test_closed_form_leave_one_out_agrees_with_refits():
    from calib_core.solve import diagnostics as dg

    rig = synthetic_rig(5, n_captures=25)
    cd = cdata(rig)
    sol = solve_camera(cd, loo=False)
    lin = dg._loo_linear(cd, sol.used, sol.T_cam_sonar)
    ref = dg.leave_one_out(cd, sol.used, sol.T_cam_sonar) if len(sol.used) <= dg.LOO_REFIT_MAX else None
    if ref is None:
        old, dg.LOO_REFIT_MAX = dg.LOO_REFIT_MAX, 1000
        try:
            ref = dg.leave_one_out(cd, sol.used, sol.T_cam_sonar)
        finally:
            dg.LOO_REFIT_MAX = old
    for i, r in ref.items():
        for k in ("residual_px", "mahalanobis", "shift_deg", "shift_mm"):
            assert lin[i][k] == pytest.approx(r[k], rel=0.02, abs=1e-3)


def test_a_far_apparent_size_scale_is_applied_with_a_caution():
    """The apparent-size route reads a focal-length error as a scale error: a scale further from
    1 than a sound-speed error gives is still applied, but the note says to check the intrinsics."""
    assert "check the cameras' intrinsics" in size_route_caution(1.061, True)
    assert "6.1 % from 1" in size_route_caution(1.061, True)
    assert "check the cameras' intrinsics" in size_route_caution(0.95, True)
    assert size_route_caution(1.02, True) == "" and size_route_caution(1.061, False) == ""
