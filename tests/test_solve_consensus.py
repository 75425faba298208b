"""Several wrong image centres: the consensus keeps the right captures and flags the wrong ones,
in the solver and in the diagnosis before any Solve (one code path), and says so plainly when
two sets of captures agree with two poses about as well."""

from __future__ import annotations

import numpy as np
import pytest

from calib_core.diagnose.consistency import consistency_of
from calib_core.geometry import make_T, pose_error
from calib_core.solve.model import exp_so3
from calib_core.solve.consensus import find_consensus
from calib_core.solve.model import camera_data
from calib_core.solve.simulate import synthetic_rig, wrong_centres
from calib_core.solve.single import solve_camera


def _wrong_centres(seed: int, n: int, k: int, stated: float = 0.5):
    """A rig with ``k`` of ``n`` image centres moved 30-80 px in random directions (a decoy or a
    mislocated ball: tens of px off, where a sphere could be), realistic noise (0.3 px, 1 mm),
    stated image sigmas ``stated`` times the true ones."""
    rig = synthetic_rig(500 + seed, n_captures=n, sigma_px=0.3, sigma_m=0.001)
    uv, bad = wrong_centres(rig.uv_px["cam1"], k, np.random.default_rng(seed))
    cd = camera_data("cam1", rig.cameras["cam1"], rig.capture_ids, uv, rig.cov_uv_px2["cam1"] * stated**2,
                     rig.X_sonar_m, rig.cov_X_m2)
    good = np.ones(n, bool)
    good[bad] = False
    return rig, cd, good


@pytest.mark.parametrize("n,k", [(8, 3), (10, 4)])
def test_several_wrong_centres_are_flagged_and_the_right_ones_kept(n, k):
    kept = flagged = 0
    trials = 6
    for seed in range(trials):
        rig, cd, good = _wrong_centres(seed, n, k)
        sol = solve_camera(cd, loo=False)
        kept += int((sol.used & good).sum())
        flagged += int((~sol.used & ~good).sum())
        if np.array_equal(sol.used, good):
            rot, t = pose_error(sol.T_cam_sonar, rig.T_cam_sonar["cam1"])
            assert np.degrees(rot) < 0.5 and t < 0.03
        # the diagnosis before any Solve names the same captures
        cons = consistency_of(cd)
        assert set(cons.outliers) == {c for c, u in zip(cd.capture_ids, sol.used) if not u}
    assert kept == trials * (n - k)  # no right capture lost
    assert flagged >= 0.85 * trials * k  # wrong ones flagged (a few 30 px ones can hide in a 5-capture set)


def test_the_old_failure_is_gone_all_wrong_ones_flagged_on_a_clear_case():
    rig, cd, good = _wrong_centres(2, 8, 3)
    cons = find_consensus(cd)
    assert cons.clear and np.array_equal(cons.inliers, good)
    assert np.array_equal(solve_camera(cd, loo=False).used, good)


def test_no_clear_consensus_is_said_plainly():
    """Six captures agree with one pose and five with another: say so, do not pretend."""
    rig = synthetic_rig(7, n_captures=11, sigma_px=0.3, sigma_m=0.001)
    uv = rig.uv_px["cam1"].copy()
    T_other = make_T(exp_so3([0.0, np.radians(3.0), np.radians(2.0)]), [0.05, -0.05, 0.0]) @ rig.T_cam_sonar["cam1"]
    other = rig.cameras["cam1"].project(rig.X_sonar_m[6:] @ T_other[:3, :3].T + T_other[:3, 3])
    uv[6:] = other + np.random.default_rng(1).normal(0, 0.3, other.shape)
    cd = camera_data("cam1", rig.cameras["cam1"], rig.capture_ids, uv, rig.cov_uv_px2["cam1"], rig.X_sonar_m,
                     rig.cov_X_m2)
    sol = solve_camera(cd, loo=False)
    said = [w for w in sol.warnings if "no clear consensus" in w]
    assert len(said) == 1
    cons = consistency_of(cd)
    assert not cons.clear and cons.warnings == [w for w in sol.warnings if w in cons.warnings] and said[0] in cons.warnings


def test_clean_captures_all_kept():
    for seed in range(4):
        rig, cd, good = _wrong_centres(seed, 9, 0, stated=1.0)
        sol = solve_camera(cd, loo=False)
        assert sol.used.all() and not any("consensus" in w for w in sol.warnings)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_readmission_takes_back_good_captures_and_not_a_wrong_one(seed):
    """Left out of the set: one good capture and one 40 px wrong centre. The gate's re-admission takes
    the good one back and not the wrong one."""
    from calib_core.solve import pnp
    from calib_core.solve.consensus import fit_subset
    from calib_core.solve.gate import gate_test

    rig, cd, _ = _wrong_centres(seed, 10, 0, stated=1.0)
    uv = cd.uv_px.copy()
    uv[1] += [40.0, 0.0]
    cd = camera_data("cam1", rig.cameras["cam1"], rig.capture_ids, uv, cd.cov_uv_px2, cd.X_sonar_m, cd.cov_X_m2)
    inl = np.ones(10, bool)
    inl[[0, 1]] = False
    T, cov = fit_subset(cd, inl, rig.T_cam_sonar["cam1"])
    extra = pnp._readmit(cd, T, inl, gate_test(cd, T, cov, inl))
    assert extra[0] and not extra[1] and not extra[inl].any()


def test_a_wrong_tight_core_does_not_leave_out_good_captures():
    """Clean data (1 px / 10 mm, stated 1 px / 5 mm) where the tightest 4-capture core fits a pose
    that four good captures contradict: the solver must come back to the fit on all nine (it used
    to keep 5 of 9 and land 180 mm off)."""
    from calib_core.geometry import pose_error
    from calib_core.solve.model import camera_data
    from calib_core.solve.simulate import synthetic_rig
    from calib_core.solve.single import solve_camera

    seed, n = 10_157, 9
    rig = synthetic_rig(seed, n_captures=n, sigma_px=1e-9, sigma_m=1e-9)
    rng = np.random.default_rng(seed + 7_000_003)
    uv = rig.uv_px["cam1"] + 1.0 * rng.normal(size=(n, 2))
    X = rig.X_sonar_m + 0.010 * rng.normal(size=(n, 3))
    cd = camera_data("cam1", rig.cameras["cam1"], rig.capture_ids, uv, np.repeat(np.eye(2)[None], n, 0),
                     X, np.repeat(0.005**2 * np.eye(3)[None], n, 0))
    sol = solve_camera(cd, loo=False)
    assert sol.used.all()
    assert pose_error(sol.T_cam_sonar, rig.T_cam_sonar["cam1"])[1] < 0.05
