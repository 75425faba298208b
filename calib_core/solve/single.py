"""One camera to the sonar: RANSAC start, ML refinement, range scale check, diagnostics."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from calib_core.solve.diagnostics import capture_rows, leave_one_out
from calib_core.solve.model import CameraData, RigState, check_count, per_camera_stats
from calib_core.solve.pnp import layout_warnings, ransac_pose
from calib_core.solve.refine import RigProblem, refine
from calib_core.solve.range_scale import range_scale_choice
from calib_core.solve.scale import choose_scale, scale_mode
from calib_core.solve.systematic import systematic_term



@dataclass
class CameraSolution:
    """A camera's calibration to the sonar.

    Attributes:
        name: camera name; data: its correspondences.
        T_cam_sonar: 4x4 (maps true sonar-frame points, i.e. cloud points / scale, to the camera).
        cov: 6x6 covariance (rotation vector rad in the camera frame, then translation m), already
            multiplied by ``max(1, variance_factor)`` so over-optimistic detection covariances
            do not make the result look better than it is.
        cov_scale: 7x7 (pose, then scale) when the scale was estimated, else None.
        scale, scale_sigma: range scale and its 1-sigma (None when not estimated).
        scale_note: why the scale was or was not estimated.
        used: (N,) bool rows used in the final solve.
        rms_px: RMS reprojection error of the used rows (px); chi2, dof, variance_factor.
        rows: per-capture diagnostics (see :func:`calib_core.solve.diagnostics.capture_rows`).
        warnings: layout and data warnings.
    """

    name: str
    data: CameraData
    T_cam_sonar: np.ndarray
    cov: np.ndarray
    cov_scale: np.ndarray | None
    scale: float
    scale_sigma: float | None
    scale_note: str
    used: np.ndarray
    rms_px: float
    chi2: float
    dof: int
    variance_factor: float
    rows: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    scale_observable: bool = False
    scale_test: dict | None = None

    @property
    def captures_used(self) -> list[str]:
        return [c for c, u in zip(self.data.capture_ids, self.used) if u]

    @property
    def outliers(self) -> list[dict]:
        return [{"capture": r["capture"], "used": r["used"], "reasons": [f["reason"] for f in r["flags"]],
                 "kinds": [f["kind"] for f in r["flags"]]} for r in self.rows if r["flags"]]


def _scale_choice(cd: CameraData, used, prob, res, estimate_scale, robust, range_model):
    """Range scale of one camera: through its ranges (sphere's apparent size) when a used row
    has one (:func:`calib_core.solve.range_scale.range_scale_choice`), else (not observable) held
    at 1. Returns (ScaleChoice, extra covariance)."""
    mode = scale_mode(estimate_scale)
    if mode == "never" or not cd.has_ranges(used):
        return choose_scale(prob, res, RigProblem([cd], [used], estimate_scale=True), mode, robust), 0.0
    return range_scale_choice(cd, used, prob, res, mode, robust, range_model)


def _systematic(cd: CameraData, used: np.ndarray, state: RigState, robust) -> np.ndarray:
    """6x6 pose covariance of the offsets common to all captures (calib_core.solve.systematic),
    on the plain pose problem at the final pose and scale."""
    st = RigState(state.T_ref_sonar, {cd.name: np.eye(4)}, state.scale)
    return systematic_term(RigProblem([cd], [used]), st, robust)


def solve_camera(cd: CameraData, estimate_scale: bool | str | None = None, robust: str | None = None, loo: bool = True,
                 check_outliers: bool = True, seed: int = 0, progress=None,
                 diameter_rel_sigma: float = 0.0, range_model=None) -> CameraSolution:
    """Calibrate one camera to the sonar from its correspondences (see the package doc).

    Image ranges (on the used rows that have one) see the range scale: ``range_model`` (a
    :class:`calib_core.solve.outline.RangeModel`) says how, else ``diameter_rel_sigma`` is their
    fixed relative systematic.

    Raises SessionError when fewer than 4 correspondences are usable.
    """
    check_count(cd.name, len(cd))
    start = ransac_pose(cd, seed=seed, check_outliers=check_outliers)
    used = start.inliers.copy()
    check_count(cd.name, int(used.sum()), "captures that agree with each other")
    warnings = list(start.warnings)
    state0 = RigState(start.T_cam_sonar, {cd.name: np.eye(4)})
    prob = RigProblem([cd], [used])
    res = refine(prob, state0, robust=robust)
    cov_scale, scale_sigma = None, None
    ch, extra = _scale_choice(cd, used, prob, res, estimate_scale, robust,
                              diameter_rel_sigma if range_model is None else range_model)
    res, prob, scale_note = ch.res, ch.problem, ch.note
    if scale_mode(estimate_scale) == "always" and not ch.observable:
        warnings.append(f"{cd.name}: range scale {scale_note}; keeping it at 1")
    T = res.state.T_ref_sonar
    vf = res.variance_factor if res.dof > 0 else 1.0
    inflate = max(1.0, vf)
    cov_full = res.cov * inflate + extra
    cov_full[:6, :6] += _systematic(cd, used, res.state, robust)  # model errors common to all captures
    if ch.estimated:
        scale_sigma = math.sqrt(cov_full[-1, -1])
    cov6 = cov_full[:6, :6]
    if prob.estimate_scale:
        cov_scale = cov_full
    r_px, _, _, _, _ = per_camera_stats(cd, T, res.state.scale)
    rms = float(np.sqrt(np.mean(np.sum(r_px[used] ** 2, axis=1))))
    warnings += layout_warnings(cd, used, T)
    sig_r = np.degrees(np.sqrt(np.diag(cov6)[:3]))
    sig_t = 1000 * np.sqrt(np.diag(cov6)[3:])
    if 3 * sig_r.max() > 1.0 or 3 * sig_t.max() > 30.0:
        warnings.append(f"{cd.name}: the pose is uncertain (3-sigma up to {3 * sig_r.max():.2f} deg, "
                        f"{3 * sig_t.max():.0f} mm): add captures spread over the view and over distance")
    loo_res = leave_one_out(cd, used, T, robust=robust, progress=progress) if loo else {}
    rows = capture_rows(cd, used, T, start.gate_result, loo_res, res.state.scale, start.miss_m)
    return CameraSolution(cd.name, cd, T, cov6, cov_scale, res.state.scale, scale_sigma, scale_note, used, rms,
                          res.chi2, res.dof, vf, rows, warnings, ch.observable, ch.test)
