"""Stereo vouching (issue 11, thirteenth round): the better registered camera, carried by the
session's stereo transform, refuses the other camera's wrong plain detections (gym s48 before the
tenth round: cam2 had 3 right and 2 wrong plain detections, and both wrong ones went into the solve)."""

from types import SimpleNamespace

import numpy as np

from calib_core.stereo.vouch import VOUCH_CHI2, VOUCH_FLOOR_PX, stereo_predictions, vouch_chi2
from stereo_sessions import camera as _cam, detections, transform as _T

RADIUS_M = 0.3


def _session(n=8, seed=3, wrong=(("p3", 26.0), ("p5", 134.0)), lost=("p1", "p6", "p7")):
    """A two-camera session's detections: cam1 sees all n spheres, cam2 a few right, a few wrong."""
    rng = np.random.default_rng(seed)
    cams = {"cam1": _cam(), "cam2": _cam()}
    T1 = _T([0.1, -0.2, 0.05], [0.2, -0.1, 0.3])
    T21 = _T([0.0, 0.05, 0.0], [-0.25, 0.0, 0.0])
    dets = detections(cams, {"cam1": T1, "cam2": T21 @ T1}, rng, n, wrong)
    for cid in lost:
        dets[cid]["cam2"] = {"status": "auto", "reason": "no round outline"}
    session = SimpleNamespace(stereo={"T_cam2_cam1": T21}, cameras={"cam1": None, "cam2": None}, raw={},
                              sphere_radius_m=RADIUS_M)
    data = SimpleNamespace(session=session, camera=lambda c: cams[c])
    return data, dets


def test_the_better_registered_camera_refuses_the_other_cameras_wrong_detections():
    from calib_core.pipeline import _stereo_refusals

    data, dets = _session()
    out = _stereo_refusals(data, dets, set(dets))
    assert set(out) == {("p3", "cam2"), ("p5", "cam2")}
    for e in out.values():
        assert e.get("center") is None and "stereo transform" in e["reason"] and e["refused_center"]


def test_no_right_detection_refused_and_nothing_without_a_stereo_transform():
    from calib_core.pipeline import _stereo_refusals

    for seed in range(3, 13):  # the right ones pass: 10 sessions, 80 + 50 plain detections
        data, dets = _session(seed=seed, wrong=())
        assert _stereo_refusals(data, dets, set(dets)) == {}
    data, dets = _session()
    data.session.stereo = {}
    assert _stereo_refusals(data, dets, set(dets)) == {}


def test_the_prediction_carried_by_the_stereo_transform_and_its_test():
    cam = _cam()
    T1 = _T([0.1, -0.2, 0.05], [0.2, -0.1, 0.3])
    T21 = _T([0.0, 0.05, 0.0], [-0.25, 0.0, 0.0])
    X_sonar = {"a": np.array([0.5, 0.2, 3.0])}
    p = stereo_predictions(cam, T21, np.eye(6) * 1e-8, T1, 0.0, cam.fx, X_sonar, "cam1")["a"]
    X2 = (T21 @ T1)[:3, :3] @ X_sonar["a"] + (T21 @ T1)[:3, 3]
    assert np.allclose(p.uv_px, cam.project(X2[None])[0]) and abs(p.range_m - np.linalg.norm(X2)) < 1e-9
    assert p.sigma_px >= VOUCH_FLOOR_PX  # the floor
    assert vouch_chi2(p, p.uv_px + [p.sigma_px, 0]) < VOUCH_CHI2 < vouch_chi2(p, p.uv_px + [4 * p.sigma_px, 0])


def test_far_from_the_registrations_points_the_stated_sigma_grows_and_right_ones_pass():
    """cam1's registration rests on 6 plain detections clustered near the middle of the volume
    (ranges erring by the stated RANGE_REL_SIGMA, centres by 0.3 px); it predicts cam2's spheres all
    over the volume (carried by an exact stereo transform). Far from its points a rigid fit's error
    grows (leverage); the stated sigma must grow with it: no right detection beyond the test, the
    chi2 (2 dof) median near 2 ln 2 = 1.39 or below. Before (one detection's range error and a
    1.5 px floor wherever the prediction lay): 90 of 160 right detections refused."""
    from calib_core.disambiguate.image import RANGE_REL_SIGMA, resolve_candidates
    from calib_core.geometry import invert_T

    cam, chi2 = _cam(), []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        T1, T21 = _T(rng.normal(0, 0.1, 3), [0.2, -0.1, 0.3]), _T([0.0, 0.05, 0.0], [-0.25, 0.0, 0.0])
        X_sup = np.column_stack([rng.uniform(-0.4, 0.4, 6), rng.uniform(-0.15, 0.15, 6), rng.uniform(3.0, 3.6, 6)])
        X_tgt = np.column_stack([rng.uniform(-1.3, 1.3, 8), rng.uniform(-0.6, 0.6, 8), rng.uniform(2.2, 5.0, 8)])
        inv = invert_T(T1)
        S_sup, S_tgt = (inv[:3, :3] @ X_sup.T).T + inv[:3, 3], (inv[:3, :3] @ X_tgt.T).T + inv[:3, 3]
        uv1 = cam.project(X_sup) + rng.normal(0, 0.3, (6, 2))
        rng1 = np.linalg.norm(X_sup, axis=1) * (1 + rng.normal(0, RANGE_REL_SIGMA, 6))
        ids, tids = [f"s{i}" for i in range(6)], [f"t{i}" for i in range(8)]
        res = resolve_candidates(cam, dict(zip(ids, S_sup)), {c: np.array([[*uv1[i], rng1[i]]]) for i, c in enumerate(ids)})
        assert res.support == 6
        preds = stereo_predictions(cam, T21, np.eye(6) * 1e-12, res.T_cam_sonar, res.residual_px, cam.fx,
                                   dict(zip(tids, S_tgt)), "cam1", S_sup)
        X2 = (T21 @ T1)[:3, :3] @ S_tgt.T + (T21 @ T1)[:3, 3:4]
        uv2 = cam.project(X2.T) + rng.normal(0, 0.3, (8, 2))
        chi2 += [vouch_chi2(preds[c], uv2[i], [0.09, 0, 0, 0.09]) for i, c in enumerate(tids) if c in preds]
    assert len(chi2) > 100
    assert max(chi2) < VOUCH_CHI2
    assert 0.3 < np.median(chi2) < 2.2, np.median(chi2)


def test_the_stated_sigma_is_near_honest_when_the_detections_err_as_stated():
    """8 plain detections of cam1 spread over the volume, ranges erring by RANGE_REL_SIGMA and centres
    by 0.3 px, a 0.6 m baseline: the right cam2 detections' chi2 median near 2 ln 2 = 1.39 (1.10
    measured). Before: 0.61 (one detection's range error, a 1.5 px floor); reading a's whole image
    residual as scatter across the rays (its range errors counted twice): 0.83."""
    from calib_core.disambiguate.image import RANGE_REL_SIGMA, resolve_candidates
    from calib_core.geometry import invert_T

    cam, chi2 = _cam(), []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        T1, T21 = _T(rng.normal(0, 0.1, 3), [0.2, -0.1, 0.3]), _T([0.0, 0.05, 0.0], [-0.6, 0.0, 0.0])
        X_cam1 = np.column_stack([rng.uniform(-1, 1, 8), rng.uniform(-0.4, 0.4, 8), rng.uniform(2.5, 4.5, 8)])
        inv = invert_T(T1)
        X_sonar = (inv[:3, :3] @ X_cam1.T).T + inv[:3, 3]
        uv1 = cam.project(X_cam1) + rng.normal(0, 0.3, (8, 2))
        rng1 = np.linalg.norm(X_cam1, axis=1) * (1 + rng.normal(0, RANGE_REL_SIGMA, 8))
        ids = [f"p{i}" for i in range(8)]
        res = resolve_candidates(cam, dict(zip(ids, X_sonar)), {c: np.array([[*uv1[i], rng1[i]]]) for i, c in enumerate(ids)})
        preds = stereo_predictions(cam, T21, np.eye(6) * 1e-12, res.T_cam_sonar, res.residual_px, cam.fx,
                                   dict(zip(ids, X_sonar)), "cam1", X_sonar)
        X2 = (T21 @ T1)[:3, :3] @ X_sonar.T + (T21 @ T1)[:3, 3:4]
        uv2 = cam.project(X2.T) + rng.normal(0, 0.3, (8, 2))
        chi2 += [vouch_chi2(preds[c], uv2[i], [0.09, 0, 0, 0.09]) for i, c in enumerate(ids) if c in preds]
    assert len(chi2) > 100 and max(chi2) < VOUCH_CHI2
    assert 0.95 < np.median(chi2) < 2.2, np.median(chi2)
