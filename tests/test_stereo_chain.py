"""Stereo transforms chained through a third camera (issue 11, fifteenth round): a session that ties
each camera only to cam1 (``T_cam2_cam1``, ``T_cam3_cam1``, as real set B and the preset
carried-3cam) lets the well registered cam3 vouch for cam2."""

from types import SimpleNamespace

import cv2
import numpy as np

from calib_core.geometry import invert_T
from calib_core.stereo.chain import chained_stereo, compose_with_cov, invert_with_cov, stereo_path
from stereo_sessions import camera as _cam, detections, transform as _T


def _perturbed(T, d):
    """The solver's perturbation: R' = exp(w) R, t' = t + dt."""
    out = T.copy()
    out[:3, :3] = cv2.Rodrigues(np.asarray(d[:3], float))[0] @ T[:3, :3]
    out[:3, 3] = T[:3, 3] + d[3:]
    return out


def _delta(T_hat, T):
    """The perturbation that takes T_hat to T."""
    w = cv2.Rodrigues(T[:3, :3] @ T_hat[:3, :3].T)[0].ravel()
    return np.concatenate([w, T[:3, 3] - T_hat[:3, 3]])


def test_chained_covariance_matches_a_monte_carlo_of_the_chain():
    rng = np.random.default_rng(0)
    T21 = _T([0.02, 0.3, -0.01], [-0.4, 0.02, 0.05])
    T31 = _T([-0.2, 0.05, 0.03], [-0.2, -0.35, 0.1])
    C21 = np.diag([1e-6, 2e-6, 1e-6, 4e-6, 1e-6, 9e-6])
    C31 = np.diag([3e-6, 1e-6, 2e-6, 1e-6, 4e-6, 1e-6])
    stereo = {"T_cam2_cam1": T21, "T_cam3_cam1": T31}
    covs = {"T_cam2_cam1": C21, "T_cam3_cam1": C31}
    T32, C32, path = chained_stereo(stereo, covs.get, "cam2", "cam3")
    assert path == ["cam2", "cam1", "cam3"]
    assert np.allclose(T32, T31 @ invert_T(T21))
    L21, L31 = np.linalg.cholesky(C21), np.linalg.cholesky(C31)
    deltas = [_delta(T32, _perturbed(T31, L31 @ rng.normal(size=6)) @ invert_T(_perturbed(T21, L21 @ rng.normal(size=6))))
              for _ in range(4000)]
    C_mc = np.cov(np.array(deltas).T)
    sig = np.sqrt(np.diag(C32))
    assert np.all(np.abs(C_mc - C32) <= 0.08 * np.outer(sig, sig))  # correlations included
    # the lever arm: rotation alone moves the chained translation (|t| x sigma_rot)
    C_rot = np.diag([1e-6] * 3 + [0.0] * 3)
    _, C = chained_stereo(stereo, lambda k: C_rot, "cam2", "cam3")[:2]
    assert np.sqrt(C[3:, 3:].trace()) > 1e-3 * 0.2


def test_inverse_and_compose_are_consistent():
    T = _T([0.1, -0.2, 0.3], [0.5, -0.1, 0.2])
    C = np.diag([1e-6, 2e-6, 3e-6, 1e-5, 2e-5, 3e-5])
    Ti, Ci = invert_with_cov(T, C)
    Tii, Cii = invert_with_cov(Ti, Ci)
    assert np.allclose(Tii, T) and np.allclose(Cii, C)
    T_id, C_id = compose_with_cov(T, C, np.eye(4), np.zeros((6, 6)))
    assert np.allclose(T_id, T) and np.allclose(C_id, C)


def test_paths():
    stereo = {"T_cam2_cam1": np.eye(4), "T_cam3_cam1": np.eye(4), "T_cam4_cam3": np.eye(4)}
    assert stereo_path(stereo, "cam2", "cam4") == ["cam2", "cam1", "cam3", "cam4"]
    assert stereo_path(stereo, "cam1", "cam2") == ["cam1", "cam2"]
    assert stereo_path(stereo, "cam2", "cam5") is None
    assert chained_stereo(stereo, lambda k: np.eye(6), "cam2", "cam2") is None


def _three_camera_session(seed=3, wrong=(("p3", 30.0), ("p5", 120.0))):
    """cam1 sees 3 spheres (too few to vouch), cam3 all 8, cam2 5 right and 2 wrong; the session
    ties cam2 and cam3 to cam1 only."""
    rng = np.random.default_rng(seed)
    cams = {c: _cam() for c in ("cam1", "cam2", "cam3")}
    T1 = _T([0.1, -0.2, 0.05], [0.2, -0.1, 0.3])
    T21, T31 = _T([0.0, 0.05, 0.0], [-0.25, 0.0, 0.0]), _T([0.03, 0.0, 0.0], [-0.12, 0.35, 0.0])
    dets = detections(cams, {"cam1": T1, "cam2": T21 @ T1, "cam3": T31 @ T1}, rng, 8, wrong)
    for cid in ("p0", "p1", "p2", "p4", "p6"):
        dets[cid]["cam1"] = {"status": "auto", "reason": "no round outline"}
    dets["p7"]["cam2"] = {"status": "auto", "reason": "no round outline"}
    session = SimpleNamespace(stereo={"T_cam2_cam1": T21, "T_cam3_cam1": T31}, raw={}, sphere_radius_m=0.3,
                              cameras={"cam1": None, "cam2": None, "cam3": None})
    return SimpleNamespace(session=session, camera=lambda c: cams[c]), dets


def test_a_camera_tied_only_through_a_third_is_vouched_for_by_it():
    from calib_core.pipeline import _stereo_predictions, _stereo_refusals

    data, dets = _three_camera_session()
    preds = _stereo_predictions(data, dets, set(dets))
    assert preds["cam2"]["p0"].source == "cam3" and preds["cam1"]["p0"].source == "cam3"
    out = _stereo_refusals(data, dets, set(dets))
    assert set(out) == {("p3", "cam2"), ("p5", "cam2")}
    for seed in range(3, 11):  # right detections pass
        data, dets = _three_camera_session(seed=seed, wrong=())
        assert _stereo_refusals(data, dets, set(dets)) == {}


def test_camera_names_with_underscores_are_chained():
    """The bag importer names cameras after their topics (``/stereo/left/image_raw`` ->
    ``stereo_left``), so a stated key may be ``T_stereo_right_stereo_left``: the chain must still
    find it, directly and through a third camera (before the fix it split keys on every '_' and
    skipped them, losing the stereo link a plain lookup used to find)."""
    T = _T([0.0, 0.05, 0.0], [-0.3, 0.0, 0.0])
    T3 = _T([0.1, 0.0, 0.0], [0.0, -0.2, 0.0])
    stereo = {"T_stereo_right_stereo_left": T, "T_cam_3_stereo_left": T3}
    cams = ["stereo_left", "stereo_right", "cam_3"]
    assert stereo_path(stereo, "stereo_left", "stereo_right") == ["stereo_left", "stereo_right"]
    assert stereo_path(stereo, "stereo_right", "cam_3", cams) == ["stereo_right", "stereo_left", "cam_3"]
    T_got, _, path = chained_stereo(stereo, lambda k: np.eye(6) * 1e-6, "stereo_right", "cam_3", cams)
    assert np.allclose(T_got, T3 @ invert_T(T))
    # a split that names no camera of the session is no camera: nothing ties cam_3 to "stereo"
    assert stereo_path(stereo, "cam_3", "stereo", cams) is None


def test_the_solves_stereo_link_reads_underscored_names():
    from calib_core.solve.stereo_cov import stereo_link

    T = _T([0.0, 0.05, 0.0], [-0.3, 0.0, 0.0])
    session = SimpleNamespace(stereo={"T_stereo_right_stereo_left": T}, raw={},
                              cameras={"stereo_left": {}, "stereo_right": {}}, manifest_path="session.yaml")
    link = stereo_link(session, "stereo_left", "stereo_right")
    assert link is not None and np.allclose(link[0], T) and link[2] and link[3] is None
