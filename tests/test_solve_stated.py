"""The solver's reading of a detector's stated sonar-centre covariance (calib_core.solve.stated)."""

from __future__ import annotations

import numpy as np
import pytest

from calib_core.detections import load_detections
from calib_core.pipeline import DEFAULT_SIGMA_SONAR_M, correspondences
from calib_core.session import load_session
from calib_core.solve.calibrate import calibrate_session
from calib_core.solve.model import camera_data
from calib_core.solve.simulate import synthetic_rig
from calib_core.solve.single import solve_camera
from calib_core.solve.stated import (SONAR_CENTRE_VARIANCE_FACTOR, camera_data_from, solver_sonar_cov,
                                     stated_sonar_rows)
from tests.test_solve_calibrate import write_session


@pytest.fixture(scope="module")
def rig():
    return synthetic_rig(47, n_captures=8, sigma_px=0.3, sigma_m=0.002)


def test_only_stated_covariances_are_scaled():
    dets = {"p1": {"sonar": {"cov_m2": (np.eye(3) * 1e-6).ravel().tolist()}},
            "p2": {"sonar": {"center": [1, 0, 0]}},                       # none stated: assumed
            "p3": {"sonar": {"cov_m2": [0.0] * 9}},                        # not positive definite
            "p4": {"sonar": {"cov_m2": [float("nan")] * 9}}}
    dets["p6"] = {"sonar": refit_sonar_click_entry()}  # an operator's pick no refit confirmed: assumed
    rows = stated_sonar_rows(dets, ["p1", "p2", "p3", "p4", "p5", "p6"])
    assert rows.tolist() == [True, False, False, False, False, False]
    C = np.stack([np.eye(3) * 1e-6, np.eye(3) * 4e-6])
    out = solver_sonar_cov(C, np.array([True, False]))
    assert np.allclose(out[0], C[0] * SONAR_CENTRE_VARIANCE_FACTOR) and np.allclose(out[1], C[1])
    assert np.allclose(C[0], np.eye(3) * 1e-6)  # the input is not changed


def refit_sonar_click_entry() -> dict:
    """The entry :func:`calib_core.pipeline.refit_sonar` writes when its refit fails (no cloud here)."""
    from calib_core.pipeline import PICK_SIGMA_SONAR_M

    s2 = PICK_SIGMA_SONAR_M**2
    return {"status": "corrected", "center": [1.0, 0.0, 2.0], "method": "operator-pick", "refit": False,
            "cov_m2": [s2, 0, 0, 0, s2, 0, 0, 0, s2]}


def _one_camera(tmp_path, rig, drop_cov=False):
    root = write_session(tmp_path / "s", rig)
    s = load_session(root)
    dets = load_detections(s)
    if drop_cov:
        for e in dets.values():
            e["sonar"].pop("cov_m2")
    return s, dets


def test_calibrate_weighs_sonar_centres_as_stated_times_factor(tmp_path, rig, monkeypatch):
    # a factor other than 1, so that the test can tell whether it is applied (the product's is
    # 1 since the detectors' covariances were made honest at their source)
    from calib_core.solve import stated

    monkeypatch.setattr(stated, "SONAR_CENTRE_VARIANCE_FACTOR", 2.0)
    s, dets = _one_camera(tmp_path, rig)
    cal = calibrate_session(s, dets, {"detect": False, "leave_one_out": False})
    corr = correspondences(s, dets, "cam1")
    model = s.camera_model("cam1")
    want = solve_camera(camera_data_from(model, dets, "cam1", corr), loo=False)
    raw = solve_camera(camera_data("cam1", model, corr.capture_ids, corr.uv_px, corr.cov_uv_px2, corr.X_sonar_m,
                                   corr.cov_X_m2), loo=False)
    got = np.asarray(cal["cameras"]["cam1"]["independent"]["covariance"], float)[:6, :6]
    assert np.allclose(got, want.cov, rtol=1e-6, atol=1e-15)
    # the test can tell: the stated covariances as they are give another pose covariance
    assert not np.allclose(got, raw.cov, rtol=1e-3, atol=0)


def test_assumed_sonar_covariance_is_not_scaled(tmp_path, rig):
    s, dets = _one_camera(tmp_path, rig, drop_cov=True)
    cd = camera_data_from(s.camera_model("cam1"), dets, "cam1", correspondences(s, dets, "cam1"))
    assert np.allclose(cd.cov_X_m2, np.eye(3) * DEFAULT_SIGMA_SONAR_M**2)
