"""Solver: exact recovery, outliers, degenerate layouts, range scale, covariance vs Monte Carlo, Table I."""

from __future__ import annotations

import math

import numpy as np
import pytest

from calib_core.errors import SessionError
from calib_core.geometry import invert_T, pose_error, transform_points
from calib_core.solve.model import camera_data, log_so3
from calib_core.solve.refine import Link
from calib_core.solve.rig import default_stereo_cov, solve_rig, table_i
from calib_core.solve.simulate import synthetic_rig
from calib_core.solve.single import solve_camera


def cdata(rig, cam, uv=None, X=None, idx=None):
    idx = np.arange(len(rig.capture_ids)) if idx is None else np.asarray(idx)
    uv = rig.uv_px[cam] if uv is None else uv
    X = rig.X_sonar_m if X is None else X
    return camera_data(cam, rig.cameras[cam], [rig.capture_ids[i] for i in idx], uv[idx], rig.cov_uv_px2[cam][idx],
                       X[idx], rig.cov_X_m2[idx])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_exact_recovery_without_noise(seed):
    rig = synthetic_rig(seed, n_captures=7, sigma_px=1e-7, sigma_m=1e-8, random_intrinsics=True)
    for cam in ("cam1", "cam2"):
        sol = solve_camera(cdata(rig, cam), loo=False)
        dr, dt = pose_error(sol.T_cam_sonar, rig.T_cam_sonar[cam])
        assert dr < 1e-6 and dt < 1e-6
        assert sol.used.all() and sol.rms_px < 1e-4 and not sol.outliers


@pytest.mark.parametrize("seed", [3, 4, 5, 6])
def test_moved_target_is_caught_and_named(seed):
    rig = synthetic_rig(seed, n_captures=9)
    bad = seed % 9
    X = rig.X_sonar_m.copy()
    X[bad] += np.array([0.12, -0.08, 0.05])  # the target moved ~15 cm between scan and image
    sol = solve_camera(cdata(rig, "cam1", X=X))
    assert rig.capture_ids[bad] not in sol.captures_used
    assert len(sol.captures_used) == 8
    out = {o["capture"]: o for o in sol.outliers}
    assert "ransac" in out[rig.capture_ids[bad]]["kinds"]
    assert "move" in out[rig.capture_ids[bad]]["reasons"][0]
    dr, dt = pose_error(sol.T_cam_sonar, rig.T_cam_sonar["cam1"])
    assert math.degrees(dr) < 1.0 and dt < 0.03


def test_fewer_than_four_is_a_clear_error():
    rig = synthetic_rig(0, n_captures=5)
    with pytest.raises(SessionError, match="at least 4"):
        solve_camera(cdata(rig, "cam1", idx=[0, 1, 2]))
    sol = solve_camera(cdata(rig, "cam1", idx=[0, 1, 2, 3, 4]))  # works, warns that outliers cannot be checked
    assert any("too few to check" in w for w in sol.warnings)


def test_degenerate_layouts_warn_with_advice():
    rig = synthetic_rig(7, n_captures=9, sigma_px=0.3, sigma_m=0.003)
    T = rig.T_cam_sonar["cam1"]
    cam = rig.cameras["cam1"]
    # collinear: positions along one line, at similar depth
    P = np.column_stack([np.linspace(-0.8, 0.8, 8), np.full(8, 0.1), 2.0 + np.linspace(-0.05, 0.05, 8)])
    X = transform_points(invert_T(T), P)
    uv = cam.project(P) + np.random.default_rng(0).normal(0, 0.3, (8, 2))
    cd = camera_data("cam1", cam, [f"q{i}" for i in range(8)], uv, np.repeat(0.09 * np.eye(2)[None], 8, 0), X,
                     np.repeat(9e-6 * np.eye(3)[None], 8, 0))
    sol = solve_camera(cd, loo=False)
    text = " ".join(sol.warnings)
    assert "one line" in text and "nearer and farther" in text
    # a well-spread layout gives no layout warning
    good = solve_camera(cdata(rig, "cam1"), loo=False)
    assert not any("line" in w or "nearer" in w or "plane" in w for w in good.warnings)


def test_scale_not_observable_from_one_camera_but_recovered_jointly():
    rig = synthetic_rig(8, n_captures=20, scale=1.012, sigma_px=0.2, sigma_m=0.002)
    sols = {c: solve_camera(cdata(rig, c), estimate_scale=True, loo=False) for c in ("cam1", "cam2")}
    assert sols["cam1"].scale == 1.0 and any("not observable from one camera" in w for w in sols["cam1"].warnings)
    rs = solve_rig(sols, {"cam2": Link(rig.T_cam2_cam1, default_stereo_cov())}, "cam1", estimate_scale=True)
    assert rs.scale_sigma is not None and rs.scale_sigma < 0.005
    assert abs(rs.scale - 1.012) < 4 * rs.scale_sigma
    for c in ("cam1", "cam2"):
        dr, dt = pose_error(rs.T_cam_sonar[c], rig.T_cam_sonar[c])
        assert math.degrees(dr) < 0.3 and dt < 0.015


def test_joint_solve_without_scale_is_consistent():
    rig = synthetic_rig(9, n_captures=9)
    sols = {c: solve_camera(cdata(rig, c), loo=False) for c in ("cam1", "cam2")}
    rs = solve_rig(sols, {"cam2": Link(rig.T_cam2_cam1, None)}, "cam1")  # stereo held fixed
    chained = rs.T_cam_ref["cam2"] @ rs.T_cam_sonar["cam1"]
    assert np.allclose(chained, rs.T_cam_sonar["cam2"], atol=1e-12)
    assert np.allclose(rs.T_cam_ref["cam2"], rig.T_cam2_cam1)
    # the joint covariance is smaller than either single-camera one
    assert np.trace(rs.cov["cam1"][3:, 3:]) < np.trace(sols["cam1"].cov[3:, 3:])


def test_covariance_agrees_with_monte_carlo():
    """Predicted 1-sigma per axis vs the spread of 150 noisy solves of one fixed layout."""
    base = synthetic_rig(21, n_captures=9, sigma_px=0.5, sigma_m=0.005, cross_factor=2.0)
    cam = base.cameras["cam1"]
    T = base.T_cam_sonar["cam1"]
    clean_uv = cam.project(transform_points(T, base.X_true_sonar_m))
    rng = np.random.default_rng(0)
    errs, covs, nees = [], [], []
    for _ in range(150):
        uv = clean_uv + rng.normal(0, 0.5, clean_uv.shape)
        X = base.X_true_sonar_m + np.stack([rng.multivariate_normal(np.zeros(3), C) for C in base.cov_X_m2])
        sol = solve_camera(cdata(base, "cam1", uv=uv, X=X), loo=False, check_outliers=False)
        e = np.concatenate([log_so3(sol.T_cam_sonar[:3, :3] @ T[:3, :3].T), sol.T_cam_sonar[:3, 3] - T[:3, 3]])
        errs.append(e)
        covs.append(sol.cov)
        nees.append(e @ np.linalg.solve(sol.cov, e))
    errs = np.array(errs)
    ratio = errs.std(axis=0) / np.sqrt(np.mean([np.diag(C) for C in covs], axis=0))
    assert np.all(ratio > 0.75) and np.all(ratio < 1.3), ratio
    assert 4.5 < np.mean(nees) < 7.5  # chi-square with 6 dof has mean 6
    assert np.all(np.abs(errs.mean(axis=0)) < 3 * errs.std(axis=0) / math.sqrt(len(errs)) + 1e-4)


def test_table_i_numbers_two_cameras():
    rig = synthetic_rig(12, n_captures=12, sigma_px=1e-6, sigma_m=1e-7)
    sols = {c: solve_camera(cdata(rig, c), loo=False) for c in ("cam1", "cam2")}
    t1 = np.linalg.norm(rig.T_cam_sonar["cam1"][:3, 3])
    measured = {"cam1-sonar": 0.8656, "cam2-sonar": 0.8625, "cam1-cam2": 0.7437}
    tab = table_i({c: s.T_cam_sonar for c, s in sols.items()}, "cam1", "cam2", rig.T_cam2_cam1, measured)
    p = tab["pairs"]
    assert p["cam1-sonar"]["estimated_m"] == pytest.approx(t1, abs=1e-6)
    assert p["cam1-sonar"]["error_pct"] == pytest.approx(100 * (t1 - 0.8656) / 0.8656, abs=1e-4)
    assert p["cam1-cam2"]["estimated_m"] == pytest.approx(np.linalg.norm(rig.T_cam2_cam1[:3, 3]))
    for k in ("cam1-sonar", "cam2-sonar"):  # noise-free: the chained transforms agree
        assert p[k]["error_length_m"] < 1e-5 and p[k]["included_angle_rad"] < 1e-5 and abs(p[k]["assoc_error_pct"]) < 1e-3
    # a stereo transform that is 2 degrees off shows up as pointing error, as in the paper
    from calib_core.solve.model import exp_so3

    wrong = rig.T_cam2_cam1.copy()
    wrong[:3, :3] = exp_so3([0, math.radians(2.0), 0]) @ wrong[:3, :3]
    tab2 = table_i({c: s.T_cam_sonar for c, s in sols.items()}, "cam1", "cam2", wrong, measured)
    q = tab2["pairs"]["cam2-sonar"]
    t_hat = (wrong @ sols["cam1"].T_cam_sonar)[:3, 3]
    t = sols["cam2"].T_cam_sonar[:3, 3]
    assert q["error_length_m"] == pytest.approx(np.linalg.norm(t - t_hat), rel=1e-9)
    assert math.degrees(q["included_angle_rad"]) > 0.5


@pytest.mark.parametrize("loss", ["huber", "cauchy"])
def test_robust_loss_downweights_a_bad_capture_kept_by_ransac(loss):
    rig = synthetic_rig(41, n_captures=12, sigma_px=0.3, sigma_m=0.003)
    uv = rig.uv_px["cam1"].copy()
    uv[2] += [5.0, -4.0]  # moderately wrong: a few sigma, not a gross outlier
    plain = solve_camera(cdata(rig, "cam1", uv=uv), loo=False, check_outliers=False)
    robust = solve_camera(cdata(rig, "cam1", uv=uv), loo=False, check_outliers=False, robust=loss)
    e_plain = pose_error(plain.T_cam_sonar, rig.T_cam_sonar["cam1"])[1]
    e_rob = pose_error(robust.T_cam_sonar, rig.T_cam_sonar["cam1"])[1]
    assert e_rob < e_plain
