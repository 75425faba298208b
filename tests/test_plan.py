"""Capture planning: information model, candidates (visibility), criterion, session planner, coverage."""

from __future__ import annotations

import numpy as np
import pytest

from calib_core.plan import (Limits, NoiseModel, SonarField, Target, candidates, field_from_points, fit_noise, parse_target,
                             plan_next)
from calib_core.plan.candidates import far_from, grid_points, outline_visible
from calib_core.plan.information import capture_terms, information, logdet_gain, safe_inverse, updated_cov
from calib_core.plan.select import CameraState
from calib_core.solve.model import RigState, camera_data
from calib_core.solve.refine import RigProblem, refine
from calib_core.solve.simulate import default_camera, synthetic_rig
from calib_core.synth.rig import sample_rig, sphere_in_image


def _rig_terms(seed=3, n=10):
    r = synthetic_rig(seed, n_captures=n, sigma_px=0.5, sigma_m=0.003)
    return r, capture_terms(r.cameras["cam1"], r.T_cam_sonar["cam1"], r.X_sonar_m, r.cov_uv_px2["cam1"], r.cov_X_m2)


def test_information_matches_the_solvers_covariance():
    r, (D, S) = _rig_terms()
    cd = camera_data("cam1", r.cameras["cam1"], r.capture_ids, r.uv_px["cam1"], r.cov_uv_px2["cam1"], r.X_sonar_m,
                     r.cov_X_m2)
    res = refine(RigProblem([cd]), RigState(r.T_cam_sonar["cam1"], {"cam1": np.eye(4)}))
    D2, S2 = capture_terms(r.cameras["cam1"], res.state.T_ref_sonar, r.X_sonar_m, r.cov_uv_px2["cam1"], r.cov_X_m2)
    C = safe_inverse(information(D2, S2))
    assert np.allclose(C, res.cov[:6, :6], rtol=1e-3, atol=1e-12 * np.abs(C).max())


def test_rank2_updates_equal_full_recomputation_and_information_increases():
    _, (D, S) = _rig_terms()
    F = information(D[:6], S[:6])
    C = np.linalg.inv(F)
    Cn = updated_cov(C, D[6:], S[6:])
    gains = logdet_gain(C, D[6:], S[6:])
    for k in range(4):
        Fk = F + information(D[6 + k:7 + k], S[6 + k:7 + k])
        assert np.allclose(Cn[k], np.linalg.inv(Fk), rtol=1e-6, atol=1e-9 * np.abs(C).max())
        assert gains[k] == pytest.approx(np.linalg.slogdet(Fk)[1] - np.linalg.slogdet(F)[1], rel=1e-6)
        assert gains[k] > 0
        assert np.linalg.eigvalsh(C - Cn[k]).min() > -1e-12 * np.abs(C).max()  # never worse on any axis
        assert np.all(np.diag(Cn[k]) <= np.diag(C) * (1 + 1e-9))


def test_outline_visibility_agrees_with_the_synthetic_renderer():
    rng = np.random.default_rng(0)
    cam = default_camera("cam1")
    P = np.column_stack([rng.uniform(-3, 3, 600), rng.uniform(-2, 2, 600), rng.uniform(-1, 5, 600)])
    mine = outline_visible(cam, P, 0.11, margin_px=10)
    ref_loose = np.array([sphere_in_image(cam, np.eye(4), p, 0.11, 0.0) for p in P])
    ref_tight = np.array([sphere_in_image(cam, np.eye(4), p, 0.11, 20.0) for p in P])
    assert mine.sum() > 50 and (~mine).sum() > 50
    assert not np.any(mine & ~ref_loose)  # accepted => really fully in the image
    assert not np.any(ref_tight & ~mine)  # comfortably inside => accepted
    behind = outline_visible(cam, np.array([[0, 0, -2.0], [0, 0, 2.0], [0, 0, 0.05]]), 0.11, 10)
    assert behind.tolist() == [False, True, False]


def test_outline_half_outside_is_rejected_though_the_centre_is_inside():
    cam = default_camera("cam1")
    x_edge = (cam.width_px - 1 - cam.cx - 20) / cam.fx * 2.0  # centre 20 px from the right edge at 2 m
    P = np.array([[x_edge, 0, 2.0]])
    assert cam.in_image(cam.project(P))[0]
    assert not outline_visible(cam, P, 0.11, 0.0)[0]


def test_field_contains_and_recovers_from_points():
    f = SonarField((-30, 30), (-10, 20), (1.0, 6.0))
    X = f.to_sonar(np.array([0, 29, -45, 0]), np.array([0, 0, 0, 19]), np.array([3, 3, 3, 3]))
    assert f.contains(X, 0.0, margin_deg=0.5).tolist() == [True, True, False, True]
    assert f.contains(X, 0.11, margin_deg=2.0).tolist() == [True, False, False, False]
    rng = np.random.default_rng(1)
    pts = f.to_sonar(rng.uniform(-30, 30, 5000), rng.uniform(-10, 20, 5000), rng.uniform(1, 6, 5000))
    g = field_from_points(pts, 0.0, 100.0)
    assert np.allclose(g.azimuth_deg, (-30, 30), atol=0.5) and np.allclose(g.elevation_deg, (-10, 20), atol=0.5)
    assert np.allclose(g.range_m, (1, 6), atol=0.01)
    # a sonar writing z forward (x right, y down): the forward axis is found from the points
    zfwd = pts[:, [1, 2, 0]] * [-1, -1, 1]
    h = field_from_points(zfwd, 0.0, 100.0)
    assert np.allclose(sorted(np.abs(h.azimuth_deg)), [30, 30], atol=0.5)
    assert h.contains(zfwd[:100], 0.0, 0.0).mean() > 0.95


def test_candidates_are_seen_by_both_sensors_in_range_and_away_from_captures():
    rng = np.random.default_rng(5)
    rig = sample_rig(rng, 2, 1920, 1080)
    cams = {n: (rig.cams[n][0], rig.T_cam_sonar(n)) for n in rig.cams}
    field, lim = SonarField(), Limits(working_range_m=(1.0, 4.0), min_separation_m=0.3)
    taken = np.array([[2.0, 0.0, -0.5], [3.0, 0.3, -0.6]])
    c = candidates(cams, field, 0.11, lim, taken)
    assert len(c.X_sonar_m) > 50
    r = np.linalg.norm(c.X_sonar_m, axis=1)
    assert r.min() >= 1.0 and r.max() <= 4.0 and field.contains(c.X_sonar_m, 0.11).all()
    assert far_from(c.X_sonar_m, taken, 0.3).all()
    assert c.visible.any(axis=1).all() and c.visible.all(axis=1).any()
    for X, vis in zip(c.X_sonar_m[::7], c.visible[::7]):
        for j, n in enumerate(rig.cams):
            T_cw = rig.T_cam_world(n)
            Xw = rig.T_world_sonar[:3, :3] @ X + rig.T_world_sonar[:3, 3]
            if vis[j]:
                assert sphere_in_image(rig.cams[n][0], T_cw, Xw, 0.11, 0.0)
    assert len(grid_points(field, Limits(working_range_m=(5.0, 4.0)))) == 0


def _coplanar_state():
    """One camera, 8 captures all 2 m in front of it (one plane), the pose known."""
    cam = default_camera("cam1")
    T = np.eye(4)
    T[:3, :3] = np.array([[0.0, -1, 0], [0, 0, -1], [1, 0, 0]])  # sonar x forward = camera z
    uv = np.array([[u, v] for u in (300, 960, 1620) for v in (250, 830)] + [[960, 540], [600, 540]], float)
    P = cam.rays(uv)
    P = 2.0 * P / P[:, 2:3]
    X = (P - T[:3, 3]) @ T[:3, :3]
    noise = NoiseModel(np.eye(2) * 0.25, 0.002, 0.003)
    D, S = capture_terms(cam, T, X, noise.cov_uv_px2, noise.sonar_cov(X))
    return cam, T, X, noise, CameraState("cam1", cam, T, np.linalg.inv(information(D, S)))


def test_a_capture_off_the_plane_is_preferred_when_captures_are_coplanar():
    cam, T, X, noise, st = _coplanar_state()
    field, lim = SonarField(), Limits(working_range_m=(1.0, 4.5), min_separation_m=0.25)
    c = candidates({"cam1": (cam, T)}, field, 0.11, lim, X)
    depth = (c.X_sonar_m @ T[:3, :3].T + T[:3, 3])[:, 2]
    assert (np.abs(depth - 2.0) < 0.15).sum() > 10  # in-plane candidates exist
    for criterion in ("d", "worst"):
        plan = plan_next([st], c, noise, 0.11, Target(), 3, criterion, 0.25)
        d0 = (T[:3, :3] @ plan.suggestions[0].X_sonar_m + T[:3, 3])[2]
        assert abs(d0 - 2.0) > 0.5, criterion
        ratios = [s.ratio_after for s in plan.suggestions]
        assert ratios[0] < plan.ratio_now and all(b <= a + 1e-12 for a, b in zip(ratios, ratios[1:]))
        pts = np.array([s.X_sonar_m for s in plan.suggestions])
        assert np.linalg.norm(pts[0] - pts[1]) >= 0.25 and np.linalg.norm(pts[1] - pts[2]) >= 0.25
    # the first pick is the best single candidate: largest log-det gain (d), smallest worst-axis ratio (worst)
    D, S = capture_terms(cam, T, c.X_sonar_m, noise.cov_uv_px2, noise.sonar_cov(c.X_sonar_m))
    best = plan_next([st], c, noise, 0.11, Target(), 1, "d").suggestions[0]
    assert best.gain == pytest.approx(logdet_gain(st.cov, D, S).max())
    best = plan_next([st], c, noise, 0.11, Target(0.05, 2.0), 1, "worst").suggestions[0]
    assert best.ratio_after == pytest.approx(Target(0.05, 2.0).ratio(updated_cov(st.cov, D, S)).min())


def test_plan_with_no_candidate_says_so_and_criterion_is_checked():
    cam, T, X, noise, st = _coplanar_state()
    empty = candidates({"cam1": (cam, T)}, SonarField(), 0.11, Limits(working_range_m=(20, 30)), X)
    plan = plan_next([st], empty, noise, 0.11)
    assert plan.suggestions == [] and "no position" in plan.notes[0]
    with pytest.raises(ValueError):
        plan_next([st], empty, noise, 0.11, criterion="best")


@pytest.mark.parametrize("text,rot,trans", [("0.1deg,5mm", 0.1, 5.0), ("5 mm / 0.2 deg", 0.2, 5.0),
                                            ("0.5cm,0.1deg", 0.1, 5.0), ("0.001rad,0.004m", 0.0573, 4.0)])
def test_parse_target(text, rot, trans):
    t = parse_target(text)
    assert t.rotation_deg == pytest.approx(rot, rel=1e-3) and t.translation_mm == pytest.approx(trans)


@pytest.mark.parametrize("bad", ["0.1deg", "abc", "0.1deg,-5mm", "5mm,5mm", ""])
def test_parse_target_rejects(bad):
    with pytest.raises(ValueError):
        parse_target(bad)


def test_target_met_per_axis():
    C = np.diag([np.radians(0.09) ** 2] * 3 + [0.004**2] * 3)
    assert Target(0.1, 5).met(C)
    C[5, 5] = 0.0051**2
    assert not Target(0.1, 5).met(C)
    assert Target(0.1, 5).ratio(C) == pytest.approx(5.1 / 5)


def test_pose_uncertainty_widens_the_image_margin():
    from calib_core.plan.candidates import pose_margin_px

    cam, T, X, noise, st = _coplanar_state()
    pts = SonarField().to_sonar(np.zeros(5), np.zeros(5), np.linspace(1.5, 3.5, 5))
    assert np.allclose(pose_margin_px(cam, T, pts, np.zeros((6, 6))), 0)
    small = pose_margin_px(cam, T, pts, st.cov)
    big = pose_margin_px(cam, T, pts, 100 * st.cov)
    assert np.all(small > 0) and np.allclose(big, 10 * small)
    # 1 mrad of yaw moves a point about fx * 1e-3 px: 3-sigma margin of about 3.6 px
    C = np.zeros((6, 6))
    C[1, 1] = 1e-6
    assert pose_margin_px(cam, T, pts[:1], C)[0] == pytest.approx(3 * cam.fx * 1e-3, rel=0.05)
    lim = Limits(working_range_m=(1.0, 4.5))
    n_known = len(candidates({"cam1": (cam, T)}, SonarField(), 0.11, lim).X_sonar_m)
    n_unsure = len(candidates({"cam1": (cam, T)}, SonarField(), 0.11, lim, pose_cov={"cam1": 1e4 * st.cov}).X_sonar_m)
    assert 0 < n_unsure < n_known


def test_noise_model_is_fitted_from_the_stated_covariances():
    from calib_core.plan.noise import default_noise

    truth = NoiseModel(np.diag([0.3, 0.5]) ** 2, 0.002, 0.004)
    rng = np.random.default_rng(2)
    X = SonarField().to_sonar(rng.uniform(-40, 40, 30), rng.uniform(-30, 30, 30), rng.uniform(1, 5, 30))
    got = fit_noise(np.repeat(truth.cov_uv_px2[None], 30, 0), X, truth.sonar_cov(X))
    assert np.allclose(got.cov_uv_px2, truth.cov_uv_px2)
    assert got.sigma_along_m == pytest.approx(0.002) and got.sigma_across_per_m == pytest.approx(0.004)
    Y = np.array([[3.0, 0, 0]])
    assert np.allclose(got.sonar_cov(Y)[0], np.diag([0.002**2, 0.012**2, 0.012**2]))
    empty, d = fit_noise(np.zeros((0, 2, 2)), np.zeros((0, 3)), np.zeros((0, 3, 3))), default_noise()
    assert np.array_equal(empty.cov_uv_px2, d.cov_uv_px2) and empty.sigma_along_m == d.sigma_along_m
