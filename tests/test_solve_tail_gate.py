"""The gate's heavy-tail reference from TAIL_FROM captures on (issue 12)."""

import numpy as np
import pytest

from calib_core.geometry import transform_points
from calib_core.solve.gate import drop_critical, f_critical, gate_rule
from calib_core.solve.model import camera_data
from calib_core.solve.simulate import synthetic_rig
from calib_core.solve.single import solve_camera
from calib_core.solve.tail_reference import T3_Q99, TAIL_FROM, t3_ratio_quantile, tail_critical


@pytest.mark.parametrize("dof", [10, 22])
def test_table_entries_are_rederived_by_monte_carlo(dof):
    fresh = t3_ratio_quantile(dof, draws=100_000)
    assert fresh == pytest.approx(T3_Q99[dof - 1], rel=0.06)


def test_reference_applies_from_tail_from_only():
    dof = np.array([10.0, 22.0, 200.0, 0.0])
    below = drop_critical(dof, TAIL_FROM - 1)
    np.testing.assert_array_equal(below, f_critical(dof, TAIL_FROM - 1))
    above = drop_critical(dof, 15)
    assert np.all(above[:3] >= tail_critical(dof)[:3])
    assert above[1] > 1.5 * f_critical(dof, 15)[1]  # Student-t 3 needs a much higher bar than F
    assert np.isinf(above[3])
    assert tail_critical(np.array([200.0]))[0] == T3_Q99[-1]  # beyond the table: its last entry
    assert "Student-t" not in gate_rule(9) and "Student-t" in gate_rule(15)


def _across(rig, i, dist_m, seed):
    """Sonar centres with capture i's moved ``dist_m`` across camera 1's ray."""
    T = rig.T_cam_sonar["cam1"]
    X = rig.X_sonar_m.copy()
    P = transform_points(T, X[i])[0]
    u = P / np.linalg.norm(P)
    d = np.random.default_rng(seed).normal(size=3)
    d -= (d @ u) * u
    X[i] = X[i] + T[:3, :3].T @ (dist_m * d / np.linalg.norm(d))
    return X


def _solve(rig, X):
    cd = camera_data("cam1", rig.cameras["cam1"], rig.capture_ids, rig.uv_px["cam1"], rig.cov_uv_px2["cam1"], X,
                     rig.cov_X_m2)
    return solve_camera(cd, loo=False)


def test_a_tail_error_is_kept_and_a_moved_target_dropped_at_15_captures():
    rig = synthetic_rig(1, n_captures=15, sigma_px=1.0, sigma_m=0.01)
    # 5.5 sonar sigmas across the ray: a tail error a Student-t sonar gives now and then
    sol = _solve(rig, _across(rig, 3, 0.055, 1))
    row = sol.rows[3]
    assert sol.used.all()
    # F's own critical value alone would have dropped it
    assert f_critical(np.array([22.0]), 15)[0] < row["gate_F"] < row["gate_F_critical"]
    moved = _solve(rig, _across(rig, 3, 0.15, 1))
    assert not moved.used[3] and moved.used.sum() == 14
    reason = moved.rows[3]["flags"][0]["reason"]
    assert "Student-t, 3 dof" in reason and "left out" in reason
