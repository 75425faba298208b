"""calib_core.solve.lm against scipy's MINPACK (the solver it replaces in the refinement)."""

import numpy as np
import pytest
from scipy.optimize import least_squares

from calib_core.solve.lm import levenberg_marquardt


def _rosenbrock(x):
    return np.array([10 * (x[1] - x[0] ** 2), 1 - x[0]])


def _rosenbrock_jac(x):
    return np.array([[-20 * x[0], 10.0], [-1.0, 0.0]])


def test_rosenbrock_reaches_the_minimum_from_far():
    res = levenberg_marquardt(_rosenbrock, _rosenbrock_jac, np.array([-1.2, 1.0]), xtol=1e-14, ftol=1e-14, gtol=1e-14)
    assert np.allclose(res.x, [1.0, 1.0], atol=1e-10)
    assert res.status in ("zero", "gtol", "ftol", "xtol")


def _exp_fit(seed):
    """A noisy three-parameter exponential fit (nonzero residual at the minimum)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 4, 40)
    y = 2.5 * np.exp(-1.3 * t) + 0.4 + 0.02 * rng.standard_normal(t.size)

    def f(p):
        return p[0] * np.exp(-p[1] * t) + p[2] - y

    def j(p):
        e = np.exp(-p[1] * t)
        return np.column_stack([e, -p[0] * t * e, np.ones_like(t)])
    return f, j


@pytest.mark.parametrize("seed", range(5))
def test_agrees_with_minpack_on_a_nonzero_residual_problem(seed):
    f, j = _exp_fit(seed)
    x0 = np.array([1.0, 0.5, 0.0])
    ours = levenberg_marquardt(f, j, x0, xtol=1e-14, ftol=1e-14, gtol=1e-14)
    ref = least_squares(f, x0, jac=j, method="lm", xtol=1e-14, ftol=1e-14, gtol=1e-14)
    assert np.allclose(ours.x, ref.x, atol=1e-9, rtol=0)
    assert ours.fun @ ours.fun <= ref.fun @ ref.fun * (1 + 1e-10)


def test_an_unobservable_parameter_gives_a_finite_step():
    """A Jacobian column of zeros (a parameter the data cannot see) leaves it where it was."""
    f0, j0 = _exp_fit(0)

    def f(p):
        return f0(p[:3])

    def j(p):
        return np.column_stack([j0(p[:3]), np.zeros(40)])
    res = levenberg_marquardt(f, j, np.array([1.0, 0.5, 0.0, 0.7]), xtol=1e-14, ftol=1e-14, gtol=1e-14)
    assert np.all(np.isfinite(res.x)) and res.x[3] == 0.7
    ref = least_squares(f0, np.array([1.0, 0.5, 0.0]), jac=j0, method="lm", xtol=1e-14, ftol=1e-14, gtol=1e-14)
    assert np.allclose(res.x[:3], ref.x, atol=1e-9, rtol=0)


def test_max_nfev_bounds_the_work():
    calls = []

    def f(x):
        calls.append(1)
        return _rosenbrock(x)
    res = levenberg_marquardt(f, _rosenbrock_jac, np.array([-1.2, 1.0]), max_nfev=5)
    assert res.status == "max_nfev" and res.nfev == 5 and len(calls) == 5


def test_exact_zero_residual_stops_at_once():
    res = levenberg_marquardt(_rosenbrock, _rosenbrock_jac, np.array([1.0, 1.0]))
    assert res.status == "zero" and res.nfev == 1


def _minpack(fun, jac, x0, xtol, ftol, gtol, max_nfev):
    sol = least_squares(fun, x0, jac=jac, method="lm", xtol=xtol, ftol=ftol, gtol=gtol, max_nfev=max_nfev)
    return sol


@pytest.mark.parametrize("seed", [8, 11])
def test_the_joint_solve_with_scale_matches_the_minpack_one(seed, monkeypatch):
    """The whole rig solve (two cameras, stereo prior, range scale) gives the same poses, scale
    and covariances with this solver as with scipy's MINPACK."""
    from calib_core.solve import refine
    from calib_core.solve.model import camera_data
    from calib_core.solve.refine import Link
    from calib_core.solve.rig import default_stereo_cov, solve_rig
    from calib_core.solve.simulate import synthetic_rig
    from calib_core.solve.single import solve_camera

    rig = synthetic_rig(seed, n_captures=12, scale=1.015, sigma_px=0.3, sigma_m=0.003)
    idx = np.arange(len(rig.capture_ids))

    def run():
        cd = {c: camera_data(c, rig.cameras[c], list(rig.capture_ids), rig.uv_px[c][idx], rig.cov_uv_px2[c][idx],
                             rig.X_sonar_m[idx], rig.cov_X_m2[idx]) for c in ("cam1", "cam2")}
        sols = {c: solve_camera(cd[c], loo=False) for c in cd}
        return solve_rig(sols, {"cam2": Link(rig.T_cam2_cam1, default_stereo_cov())}, "cam1", estimate_scale=True)

    ours = run()
    monkeypatch.setattr(refine, "levenberg_marquardt", _minpack)
    ref = run()
    assert abs(ours.scale - ref.scale) < 1e-9
    for c in ("cam1", "cam2"):
        assert np.allclose(ours.T_cam_sonar[c], ref.T_cam_sonar[c], atol=1e-9, rtol=0)
        assert np.allclose(ours.cov[c], ref.cov[c], rtol=1e-6, atol=1e-15)
