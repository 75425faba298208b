"""Model errors common to every capture (calib_core.solve.systematic) reach the pose covariance."""

from __future__ import annotations

import dataclasses

import numpy as np

from calib_core.geometry import invert_T, rotvec_from_T
from calib_core.solve.model import RigState, camera_data
from calib_core.solve.refine import RigProblem, refine
from calib_core.solve.simulate import synthetic_rig
from calib_core.solve.systematic import systematic_term




def test_a_common_radial_offset_moves_the_pose_as_the_term_says():
    rig = synthetic_rig(3, n_captures=9, sigma_px=0.2, sigma_m=0.001)
    cd = camera_data("cam1", rig.cameras["cam1"], rig.capture_ids, rig.uv_px["cam1"], rig.cov_uv_px2["cam1"],
                     rig.X_sonar_m, rig.cov_X_m2)
    prob = RigProblem([cd])
    res = refine(prob, RigState(rig.T_cam_sonar["cam1"], {"cam1": np.eye(4)}))
    C = systematic_term(prob, res.state, sonar_sigma_m=0.002, image_sigma_px=0.0)
    assert np.all(np.linalg.eigvalsh(C) > -1e-15) and np.linalg.matrix_rank(C, tol=1e-12 * np.abs(C).max()) == 1
    # push every sonar centre 2 mm along its ray: the refit moves by one sigma of the term
    u = cd.X_sonar_m / np.linalg.norm(cd.X_sonar_m, axis=1, keepdims=True)
    cd2 = dataclasses.replace(cd, X_sonar_m=cd.X_sonar_m + 0.002 * u)
    r2 = refine(RigProblem([cd2]), res.state)
    T0, T1 = res.state.T_ref_sonar, r2.state.T_ref_sonar
    d = np.r_[rotvec_from_T(T1 @ invert_T(T0)), T1[:3, 3] - T0[:3, 3]]
    assert abs(d @ np.linalg.pinv(C) @ d - 1.0) < 0.05
    # the image term scales with its sigma squared
    Ci1 = systematic_term(prob, res.state, sonar_sigma_m=0.0, image_sigma_px=0.1)
    Ci2 = systematic_term(prob, res.state, sonar_sigma_m=0.0, image_sigma_px=0.2)
    assert np.allclose(Ci2, 4 * Ci1, rtol=1e-6, atol=1e-18)
