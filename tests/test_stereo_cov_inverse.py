"""A stereo covariance stated for the inverse key (T_cam1_cam2 for the joint solve's T_cam2_cam1)."""

from __future__ import annotations

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from calib_core.detections import load_detections
from calib_core.geometry import invert_T
from calib_core.session import load_session
from calib_core.solve.calibrate import calibrate_session
from calib_core.solve.rig import cov_of_inverse
from calib_core.solve.simulate import synthetic_rig
from tests.test_solve_calibrate import write_session


def test_cov_of_inverse_matches_monte_carlo():
    rng = np.random.default_rng(4)
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec([0.3, -0.5, 0.2]).as_matrix()
    T[:3, 3] = [0.7, -0.1, 0.25]
    A = rng.normal(size=(6, 6)) * np.r_[[1e-3] * 3, [2e-3] * 3][:, None]
    C = A @ A.T + np.diag([1e-7] * 6)
    Ti = invert_T(T)
    d = rng.multivariate_normal(np.zeros(6), C, 100_000)
    out = np.empty_like(d)
    for k, (dr, dt) in enumerate(zip(d[:, :3], d[:, 3:])):  # the solver's perturbation of T, then its inverse
        Tp = np.eye(4)
        Tp[:3, :3] = Rotation.from_rotvec(dr).as_matrix() @ T[:3, :3]
        Tp[:3, 3] = T[:3, 3] + dt
        Tpi = invert_T(Tp)
        out[k, :3] = Rotation.from_matrix(Tpi[:3, :3] @ Ti[:3, :3].T).as_rotvec()
        out[k, 3:] = Tpi[:3, 3] - Ti[:3, 3]
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
