"""Model errors common to every capture, added to the pose covariance.

A detector's error that is the same on every capture does not show in the residuals (the pose
absorbs it) and does not average away: the stated covariance misses it, and the pose error is
larger than the covariance says. Two are modelled, each as one unknown offset shared by all
captures:

- the sonar centres pushed along their rays from the sonar (the beam-width model's residual
  bias, a range offset): ``SONAR_RADIAL_SIGMA_M``; measured on the synthetic presets
  (sonar, LiDAR, RGB-D) at about 1 mm RMS (BENCHMARKS.md, "Honest covariance");
- each camera's image centres shifted by the same pixel offset (shading, blur through the
  camera's gamma): ``IMAGE_OFFSET_SIGMA_PX`` in u and in v, independently per camera.

The parameter shift per unit offset ``g`` (one Gauss-Newton step at the optimum with each
offset applied: a refit, to first order) adds ``g g^T sigma^2`` to the parameter covariance.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from calib_core.solve.model import RigState
from calib_core.solve.refine import RigProblem, jacobian, weights_for

SONAR_RADIAL_SIGMA_M = 0.001
IMAGE_OFFSET_SIGMA_PX = 0.1
_EPS_M = 1e-3
_EPS_PX = 1.0


def _shift(problem: RigProblem, state: RigState, cams: list, lin) -> np.ndarray:
    """Parameter shift of the fit when its data become ``cams``: one Gauss-Newton step at the
    optimum with the weights held (exact to first order, as a refit would be)."""
    Ws, J, r0 = lin
    p2 = RigProblem(cams, problem.masks, problem.links, estimate_scale=problem.estimate_scale,
                    use_ranges=len(problem.range_rows) > 0)
    dr = p2.whitened(state, Ws) - r0
    return -np.linalg.lstsq(J, dr, rcond=None)[0]


def systematic_term(problem: RigProblem, state: RigState, robust: str | None = None,
                    sonar_sigma_m: float | None = None, image_sigma_px: float | None = None) -> np.ndarray:
    """(n x n) covariance, in the parameter perturbation of ``problem`` (a plain RigProblem) at its
    optimum ``state``, of the common offsets above (sigmas default to the module's constants)."""
    sonar_sigma_m = SONAR_RADIAL_SIGMA_M if sonar_sigma_m is None else sonar_sigma_m
    image_sigma_px = IMAGE_OFFSET_SIGMA_PX if image_sigma_px is None else image_sigma_px
    n = problem.n_params
    out = np.zeros((n, n))
    Ws, _ = weights_for(problem, state, robust, 2.5)
    lin = (Ws, jacobian(problem, state, Ws), problem.whitened(state, Ws))
    if sonar_sigma_m > 0:
        moved = []
        for cd in problem.cams:
            u = cd.X_sonar_m / np.linalg.norm(cd.X_sonar_m, axis=1, keepdims=True)
            moved.append(dataclasses.replace(cd, X_sonar_m=cd.X_sonar_m + _EPS_M * u))
        g = _shift(problem, state, moved, lin) / _EPS_M
        out += np.outer(g, g) * sonar_sigma_m**2
    if image_sigma_px > 0:
        for k, cd in enumerate(problem.cams):
            for axis in (0, 1):
                uv = cd.uv_px.copy()
                uv[:, axis] += _EPS_PX
                cams = list(problem.cams)
                cams[k] = dataclasses.replace(cd, uv_px=uv, xy=cd.cam.normalize(uv))
                g = _shift(problem, state, cams, lin) / _EPS_PX
                out += np.outer(g, g) * image_sigma_px**2
    return 0.5 * (out + out.T)
