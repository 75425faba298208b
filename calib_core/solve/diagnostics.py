"""Per-capture residuals, leave-one-out residuals and outlier flags for one camera's solution.

Flags (each with a reason an operator can act on) come from one test only, the gate of
:mod:`calib_core.solve.gate` (deleted residual against the noise level of the other captures):
- ``ransac``: left out of the solve (the target probably moved between scan and image, or one
  detection is wrong);
- ``gate``: fails the same test but was kept because too few captures would remain.
The leave-one-out refits are reported as numbers (how far the pose moves without a capture).
"""

from __future__ import annotations

import math

import numpy as np

from calib_core.geometry import pose_error
from calib_core.solve.model import CameraData, RigState, per_camera_stats, prediction_jacobian
from calib_core.solve.gate import gate_rule

LOO_REFIT_MAX = 20  # above this many captures, leave-one-out uses the closed form (one refit each is slow)
from calib_core.solve.refine import RigProblem, refine


def leave_one_out(cd: CameraData, used: np.ndarray, T_cam_sonar: np.ndarray, robust=None, progress=None) -> dict:
    """For each used row: solve without it and predict it (refits up to LOO_REFIT_MAX used rows,
    the closed form of the linearised problem beyond).

    Returns {row: {"residual_px", "mahalanobis", "shift_deg", "shift_mm"}} (needs >= 5 used rows:
    a solve without the row needs 4).
    """
    out = {}
    idx = np.flatnonzero(used)
    if len(idx) < 5:
        return out
    if len(idx) > LOO_REFIT_MAX:
        return _loo_linear(cd, used, T_cam_sonar)
    for k, i in enumerate(idx):
        if progress:
            progress(k, len(idx), f"{cd.name} leave-one-out {cd.capture_ids[i]}")
        m = used.copy()
        m[i] = False
        prob = RigProblem([cd], [m])
        res = refine(prob, RigState(T_cam_sonar, {cd.name: np.eye(4)}), robust=robust, max_outer=2)
        T = res.state.T_ref_sonar
        r_px, r_xy, S, _, depth = per_camera_stats(cd, T)
        G = prediction_jacobian(cd, T, np.array([i]))[0]
        Sp = S[i] + G @ res.cov @ G.T
        m2 = float(r_xy[i] @ np.linalg.solve(Sp, r_xy[i])) if depth[i] > 0 else math.inf
        dr, dt = pose_error(T, T_cam_sonar)
        out[int(i)] = {"residual_px": float(np.linalg.norm(r_px[i])), "mahalanobis": math.sqrt(m2),
                       "shift_deg": math.degrees(dr), "shift_mm": 1000 * dt}
    if progress:
        progress(len(idx), len(idx), f"{cd.name} leave-one-out done")
    return out


def _loo_linear(cd: CameraData, used: np.ndarray, T_cam_sonar: np.ndarray) -> dict:
    """Leave-one-out in closed form for the linearised problem (exact for a linear model):
    deleting row i moves the parameters by ``C J_i^T (I - H_ii)^-1 e_i`` and its whitened
    prediction residual is ``(I - H_ii)^-1 e_i``."""
    from calib_core.solve.refine import jacobian, weights_for

    prob = RigProblem([cd], [used])
    state = RigState(T_cam_sonar, {cd.name: np.eye(4)})
    Ws, _ = weights_for(prob, state, None, 1.0)
    e = prob.whitened(state, Ws).reshape(-1, 2)
    J = jacobian(prob, state, Ws).reshape(-1, 2, 6)
    C = np.linalg.inv(np.einsum("nij,nik->jk", J, J))
    H = J @ C @ np.swapaxes(J, 1, 2)
    A = np.linalg.inv(np.eye(2)[None] - H)
    e_del = np.einsum("nij,nj->ni", A, e)
    d = np.einsum("jk,nik,ni->nj", C, J, e_del)
    r_px = per_camera_stats(cd, T_cam_sonar)[0]
    out = {}
    for k, i in enumerate(np.flatnonzero(used)):  # groups keep the used rows in order (one camera)
        grow = float(np.linalg.norm(e_del[k]) / max(np.linalg.norm(e[k]), 1e-300))
        out[int(i)] = {"residual_px": float(np.linalg.norm(r_px[i])) * grow,
                       "mahalanobis": float(math.sqrt(max(e[k] @ e_del[k], 0.0))),
                       "shift_deg": math.degrees(float(np.linalg.norm(d[k, :3]))), "shift_mm": 1000 * float(np.linalg.norm(d[k, 3:]))}
    return out


def capture_rows(cd: CameraData, used: np.ndarray, T_cam_sonar: np.ndarray, gate_result, loo: dict,
                 scale: float = 1.0, miss_m: np.ndarray | None = None) -> list[dict]:
    """One dict per correspondence: residuals (px, normalised, Mahalanobis), the gate's F test,
    leave-one-out, flags. ``gate_result`` is the :class:`calib_core.solve.gate.GateResult` of
    the final set (None when there were too few captures to test)."""
    r_px, r_xy, S, m2, depth = per_camera_stats(cd, T_cam_sonar, scale)
    rows = []
    for i, cid in enumerate(cd.capture_ids):
        m = math.sqrt(m2[i]) if math.isfinite(m2[i]) else math.inf
        F = crit = None
        if gate_result is not None:
            F, crit = float(gate_result.F[i]), float(gate_result.crit[i])
        rows.append({
            "capture": cid,
            "used": bool(used[i]),
            "uv_px": [float(v) for v in cd.uv_px[i]],
            "X_sonar_m": [float(v) for v in cd.X_sonar_m[i]],
            "residual_px": [float(v) for v in r_px[i]],
            "residual_norm_px": float(np.linalg.norm(r_px[i])),
            "residual_normalized": [float(v) for v in r_xy[i]],
            "mahalanobis": m,
            "gate_F": F,
            "gate_F_critical": crit,
            "depth_m": float(depth[i]),
            "loo": loo.get(i),
            "flags": _flags(bool(used[i]), depth[i], F, crit, None if miss_m is None else miss_m[i], gate_rule(len(cd))),
        })
    return rows


def _flags(used: bool, depth: float, F, crit, miss, rule: str) -> list[dict]:
    """The gate's verdict on one capture, with a reason an operator can act on."""
    if F is None or (used and not F > crit):
        return []
    if depth <= 0:
        why = "behind the camera"
    else:
        why = f"F = {F:.1f} > {crit:.1f}, {rule}"
        if miss is not None and math.isfinite(miss):
            why += f"; its sonar centre misses the image ray by {100 * miss:.1f} cm"
    if not used:
        return [{"kind": "ransac", "reason": f"does not fit the other captures ({why}); left out. "
                 f"Did the target move between the sonar scan and the image, or is a detection wrong?"}]
    return [{"kind": "gate", "reason": f"does not fit the other captures ({why}) but was kept: too few "
             f"captures would remain without it; check this capture's detections"}]
