"""Plan the next captures of a session: detections -> per-camera solves -> suggestions.

Each camera with at least 4 usable correspondences is solved as ``sonarcal calibrate`` solves it
independently (:func:`calib_core.solve.single.solve_camera`, no leave-one-out, range scale held
at 1); its reported covariance (already multiplied by max(1, variance factor)) is the "now"
figure. When ``sonarcal calibrate`` also estimates the range scale, or solves two cameras jointly
through a stereo transform, its reported pose sigma can differ from this one. A camera with
3 correspondences uses the pose in ``results/calibration.json`` when there is one. The sonar
field comes from the session's clouds (see :func:`field_from_session`); the working range
defaults to the captures' ranges widened by 25 % each way.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from calib_core.errors import SessionError
from calib_core.plan.candidates import Limits, candidates
from calib_core.plan.field import SonarField, field_from_manifest, field_from_points
from calib_core.plan.information import capture_terms, information, safe_inverse
from calib_core.plan.noise import fit_noise
from calib_core.plan.select import DEFAULT_CRITERION, CameraState, Plan, plan_next
from calib_core.plan.target import Target


@dataclass
class SessionPlan:
    """A plan for a session plus what it was built from."""

    plan: Plan
    field: SonarField
    limits: Limits
    cameras: list[str]
    taken_sonar_m: np.ndarray
    taken_uv_px: dict = field(default_factory=dict)
    skipped: dict = field(default_factory=dict)


def field_from_session(session, load_points=None, max_clouds: int = 4, max_points: int = 20000,
                       seed: int = 0) -> SonarField:
    """The sonar field: session.yaml's optional ``sonar.field`` (see
    :func:`calib_core.plan.field.field_from_manifest`), else the field spanned by up to ``max_clouds``
    of the session's clouds (evenly spread over the list).

    ``load_points(capture_id) -> (N,3)`` lets a shell use its cache; default: read the file."""
    from calib_core.io.clouds import load_cloud

    declared = field_from_manifest(session)
    if declared is not None:
        return declared
    caps = session.captures
    if not caps:
        return SonarField()
    pick = sorted({int(i) for i in np.linspace(0, len(caps) - 1, min(max_clouds, len(caps)))})
    rng = np.random.default_rng(seed)
    pts = []
    for i in pick:
        P = load_points(caps[i].id) if load_points else load_cloud(caps[i].cloud_path).points_m
        P = np.asarray(P, float).reshape(-1, 3)
        pts.append(P[rng.choice(len(P), max_points, replace=False)] if len(P) > max_points else P)
    return field_from_points(np.vstack(pts))


def _camera_state(session, detections, cam: str, calibration: dict | None):
    """(CameraState, correspondences) or (None, reason)."""
    from calib_core.pipeline import correspondences
    from calib_core.solve.single import solve_camera
    from calib_core.solve.stated import camera_data_from, solver_sonar_cov, stated_sonar_rows

    corr = correspondences(session, detections, cam)
    model = session.camera_model(cam)
    n = len(corr)
    if n >= 4:
        cd = camera_data_from(model, detections, cam, corr, with_ranges=False)  # weighed as a Solve weighs them
        try:
            sol = solve_camera(cd, estimate_scale=False, loo=False)  # the planner plans the pose, scale at 1
        except SessionError as e:
            return None, e.problem
        inflate = max(1.0, sol.variance_factor) if sol.dof > 0 else 1.0
        return CameraState(cam, model, sol.T_cam_sonar, sol.cov, inflate, int(sol.used.sum())), corr
    entry = ((calibration or {}).get("cameras") or {}).get(cam) or {}
    if n == 3 and entry.get("T_cam_sonar") is not None:
        T = np.asarray(entry["T_cam_sonar"], float).reshape(4, 4)
        cov_X = solver_sonar_cov(corr.cov_X_m2, stated_sonar_rows(detections, corr.capture_ids))
        D, S = capture_terms(model, T, corr.X_sonar_m, corr.cov_uv_px2, cov_X)
        return CameraState(cam, model, T, safe_inverse(information(D, S)), 1.0, n), corr
    return None, f"{n} usable captures (the planner needs 4, or 3 and a calibration)"


def default_limits(taken_sonar_m: np.ndarray, radius_m: float) -> Limits:
    r = np.linalg.norm(taken_sonar_m, axis=1)
    return Limits(working_range_m=(round(float(0.75 * r.min()), 2), round(float(1.25 * r.max()), 2)),
                  min_separation_m=round(max(0.2, 4 * radius_m), 2))


def plan_session(session, detections: dict, calibration: dict | None = None, target: Target = Target(),
                 limits: Limits | None = None, count: int = 3, criterion: str = DEFAULT_CRITERION,
                 field: SonarField | None = None, load_points=None, working_range_m=None) -> SessionPlan:
    """Suggestions for the next ``count`` captures (see the module doc); ``working_range_m``
    (min, max) overrides the default working range.

    Raises SessionError (naming detections.yaml) when no camera has enough usable captures."""
    from calib_core.detections import detections_path

    states, skipped, corrs = [], {}, {}
    for cam in session.cameras:
        st, info = _camera_state(session, detections, cam, calibration)
        if st is None:
            skipped[cam] = info
        else:
            states.append(st)
            corrs[cam] = info
    if not states:
        why = "; ".join(f"{c}: {r}" for c, r in skipped.items())
        raise SessionError(detections_path(session), f"cannot plan yet: {why}. Take and detect at least 4 captures "
                                                     f"seen by the sonar and a camera (sonarcal detect)")
    X = np.vstack([c.X_sonar_m for c in corrs.values()])
    taken = np.unique(X.round(6), axis=0)
    noise = fit_noise(np.vstack([c.cov_uv_px2 for c in corrs.values()]), X, np.vstack([c.cov_X_m2 for c in corrs.values()]))
    limits = limits or default_limits(taken, session.sphere_radius_m)
    if working_range_m is not None:
        limits = replace(limits, working_range_m=tuple(float(v) for v in working_range_m))
    field = field or field_from_session(session, load_points)
    cams = {s.name: (s.cam, s.T_cam_sonar) for s in states}
    cands = candidates(cams, field, session.sphere_radius_m, limits, taken, pose_cov={s.name: s.cov for s in states})
    plan = plan_next(states, cands, noise, session.sphere_radius_m, target, count, criterion, limits.min_separation_m)
    return SessionPlan(plan, field, limits, [s.name for s in states], taken,
                       {c: corrs[c].uv_px for c in corrs}, skipped)
