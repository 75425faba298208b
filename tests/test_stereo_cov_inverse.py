"""A stereo covariance stated for the inverse key (T_cam1_cam2 for the joint solve's T_cam2_cam1)."""

from __future__ import annotations

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from calib_core.detections import load_detections
from calib_core.geometry import invert_T
from calib_core.session import load_session
from calib_core.solve.calibrate import calibrate_session
from calib_core.solve.rig import cov_of_inverse, default_stereo_cov
from calib_core.solve.simulate import synthetic_rig
from tests.test_solve_calibrate import write_session


def _perturbed(T, d):
    """(R (n,3,3), t (n,3)) of T under the solver's perturbations d (n,6): R' = exp(dr) R, t' = t + dt."""
    return Rotation.from_rotvec(d[:, :3]).as_matrix() @ T[:3, :3], T[:3, 3] + d[:, 3:]


def test_cov_of_inverse_matches_monte_carlo():
    rng = np.random.default_rng(4)
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec([0.3, -0.5, 0.2]).as_matrix()
    T[:3, 3] = [0.7, -0.1, 0.25]
    A = rng.normal(size=(6, 6)) * np.r_[[1e-3] * 3, [2e-3] * 3][:, None]
    C = A @ A.T + np.diag([1e-7] * 6)
    Ti = invert_T(T)
    d = rng.multivariate_normal(np.zeros(6), C, 100_000)
    R, t = _perturbed(T, d)  # the solver's perturbation of T, then its inverse
    Ri = np.transpose(R, (0, 2, 1))
    ti = -np.einsum("nij,nj->ni", Ri, t)
    out = np.hstack([Rotation.from_matrix(Ri @ Ti[:3, :3].T).as_rotvec(), ti - Ti[:3, 3]])
    emp = np.cov(out.T)
    got = cov_of_inverse(T, C)
    sig = np.sqrt(np.diag(got))
    assert np.abs((emp - got) / np.outer(sig, sig)).max() < 0.03  # correlations agree to 0.03
    assert not np.allclose(got, C, rtol=0.1)  # the test can tell: the covariance as stated is not it


def test_covariance_stated_for_the_inverse_key_is_used(tmp_path):
    rig = synthetic_rig(31, n_captures=8, sigma_px=0.3, sigma_m=0.003)
    root = write_session(tmp_path / "s", rig)
    man = yaml.safe_load((root / "session.yaml").read_text())
    T12 = invert_T(rig.T_cam2_cam1)
    C12 = np.diag([np.radians(0.02) ** 2] * 3 + [0.0004**2] * 3)
    man["stereo"] = {"T_cam1_cam2": T12.tolist()}
    man["stereo_covariance"] = {"T_cam1_cam2": C12.tolist()}
    (root / "session.yaml").write_text(yaml.safe_dump(man, sort_keys=False))
    s = load_session(root)
    cal = calibrate_session(s, load_detections(s), {"detect": False, "leave_one_out": False})
    info = cal["joint"]["stereo"]["cam2"]
    assert info["covariance_assumed"] is False
    assert not any("no stereo_covariance" in w for w in cal["warnings"])
    assert np.allclose(np.asarray(info["covariance"], float), cov_of_inverse(T12, C12))




def test_cov_of_product_matches_monte_carlo():
    from calib_core.solve.rig import cov_of_product

    rng = np.random.default_rng(5)
    A, B = np.eye(4), np.eye(4)
    A[:3, :3], A[:3, 3] = Rotation.from_rotvec([0.1, 0.4, -0.2]).as_matrix(), [0.3, 0.05, -0.1]
    B[:3, :3], B[:3, 3] = Rotation.from_rotvec([-0.2, 0.1, 0.3]).as_matrix(), [-0.7, 0.2, 0.4]
    CA = np.diag([1e-6, 2e-6, 1e-6, 4e-6, 1e-6, 9e-6])
    CB = np.diag([3e-6, 1e-6, 2e-6, 1e-6, 5e-6, 2e-6])
    T0 = A @ B
    n = 100_000
    (Ra, ta), (Rb, tb) = _perturbed(A, rng.multivariate_normal(np.zeros(6), CA, n)), \
        _perturbed(B, rng.multivariate_normal(np.zeros(6), CB, n))
    out = np.hstack([Rotation.from_matrix(Ra @ Rb @ T0[:3, :3].T).as_rotvec(),
                     np.einsum("nij,nj->ni", Ra, tb) + ta - T0[:3, 3]])
    got = cov_of_product(A, B, CA, CB)
    sig = np.sqrt(np.diag(got))
    assert np.abs((np.cov(out.T) - got) / np.outer(sig, sig)).max() < 0.03
    assert not np.allclose(got, CA + CB, rtol=0.1)


def test_a_camera_tied_through_an_unsolved_one_joins_the_joint_solve(tmp_path):
    """Three cameras tied to cam1 by stereo transforms, cam1 without usable captures: cam2 and cam3
    were solved independently (no stereo key for the pair); here "hub" plays cam1's part."""
    from calib_core.io.intrinsics import save_intrinsics_ros
    from calib_core.solve.rig import cov_of_product
    from calib_core.stereo.chain import invert_with_cov

    rig = synthetic_rig(31, n_captures=8, sigma_px=0.3, sigma_m=0.003)
    root = write_session(tmp_path / "s", rig)
    save_intrinsics_ros(root / "intrinsics" / "hub.yaml", rig.cameras["cam1"], "hub")
    man = yaml.safe_load((root / "session.yaml").read_text())
    man["cameras"] = {"hub": {"intrinsics": "intrinsics/hub.yaml"}, **man["cameras"]}  # first, and never imaged
    H = np.eye(4)
    H[:3, :3], H[:3, 3] = Rotation.from_rotvec([0.0, 0.05, 0.01]).as_matrix(), [0.0, -0.3, 0.02]  # T_hub_cam1
    man["stereo"] = {"T_cam1_hub": invert_T(H).tolist(), "T_cam2_hub": (rig.T_cam2_cam1 @ invert_T(H)).tolist()}
    (root / "session.yaml").write_text(yaml.safe_dump(man, sort_keys=False))
    s = load_session(root)
    cal = calibrate_session(s, load_detections(s), {"detect": False, "leave_one_out": False})
    assert cal["joint"] is not None and cal["joint"]["reference"] == "cam1"
    info = cal["joint"]["stereo"]["cam2"]
    assert info["via"] == "hub"
    assert np.allclose(np.asarray(info["T_cam_ref"], float), rig.T_cam2_cam1, atol=1e-9)
    C = default_stereo_cov()  # none stated: assumed for both transforms as the file states them
    T_hub_cam1, C_hub_cam1 = invert_with_cov(invert_T(H), C)  # the file states T_cam1_hub
    want = cov_of_product(rig.T_cam2_cam1 @ invert_T(H), T_hub_cam1, C, C_hub_cam1)
    assert np.allclose(np.asarray(info["covariance"], float), want)
    assert cal["cameras"]["cam2"]["solution"] == "joint"


def _T(rotvec, t):
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = t
    return T


def test_stereo_link_chains_through_several_cameras():
    """A rig tied pairwise along a row (cam1-cam2, cam2-cam3 stated backwards, cam3-cam4): the link
    cam1 -> cam4 is the product along the chain, through "cam2, cam3"; assumed when any link is."""
    from types import SimpleNamespace

    from calib_core.solve.stereo_cov import stereo_link
    from calib_core.stereo.chain import compose_with_cov, invert_with_cov

    T21, T23, T43 = _T([0.01, 0.2, 0], [-0.3, 0, 0]), _T([0, -0.1, 0.02], [0.25, 0.01, 0]), _T([0.0, 0.1, 0], [-0.2, 0, 0.01])
    C = np.diag([np.radians(0.02) ** 2] * 3 + [0.0003**2] * 3)
    stereo = {"T_cam2_cam1": T21, "T_cam2_cam3": T23, "T_cam4_cam3": T43}
    raw = {"stereo_covariance": {k: C.tolist() for k in stereo}}
    s = SimpleNamespace(stereo=stereo, raw=raw, manifest_path="session.yaml", cameras=["cam1", "cam2", "cam3", "cam4"])
    T, cov, assumed, via = stereo_link(s, "cam1", "cam4")
    T32, C32 = invert_with_cov(T23, C)
    T31, C31 = compose_with_cov(T32, C32, T21, C)
    T41, C41 = compose_with_cov(T43, C, T31, C31)
    assert via == "cam2, cam3" and assumed is False
    assert np.allclose(T, T43 @ invert_T(T23) @ T21) and np.allclose(cov, C41)
    assert stereo_link(s, "cam1", "cam2")[3] is None  # a stated pair is direct
    del raw["stereo_covariance"]["T_cam2_cam3"]
    assert stereo_link(s, "cam1", "cam4")[2] is True
    assert stereo_link(SimpleNamespace(**{**vars(s), "stereo": {"T_cam2_cam1": T21}}), "cam1", "cam4") is None


def test_the_assumed_stereo_warning_says_the_assumed_numbers(monkeypatch):
    """The warning is built from the constants the solve and the vouching use (it was a fixed
    string beside them: a changed default would have been misreported)."""
    import math

    from calib_core.solve import stereo_cov

    assert stereo_cov.assumed_stereo_text().startswith("assumed 0.05 deg / 1 mm (1-sigma) per axis")
    monkeypatch.setattr(stereo_cov, "DEFAULT_STEREO_SIGMA_RAD", math.radians(0.1))
    monkeypatch.setattr(stereo_cov, "DEFAULT_STEREO_SIGMA_M", 0.002)
    assert stereo_cov.assumed_stereo_text().startswith("assumed 0.1 deg / 2 mm")
