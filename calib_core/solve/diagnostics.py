"""Per-capture residuals, leave-one-out residuals and outlier flags for one camera's solution.

Flags (each with a reason an operator can act on):
- ``ransac``: left out of the solve; its Mahalanobis distance exceeds the gate at the consensus
  pose (the target probably moved between scan and image, or one detection is wrong).
- ``mahalanobis``: used, but its residual is unusually large for its stated uncertainty (99 %).
- ``leave-one-out``: solving without it, the pose does not predict it (99.9 %, with the
  leave-one-out pose uncertainty included): the others disagree with this capture.
"""

from __future__ import annotations

import math

import numpy as np

from calib_core.geometry import pose_error
from calib_core.solve.model import CameraData, RigState, per_camera_stats, prediction_jacobian
from calib_core.solve.pnp import CHI2_2_99, CHI2_2_999
from calib_core.solve.refine import RigProblem, refine


def leave_one_out(cd: CameraData, used: np.ndarray, T_cam_sonar: np.ndarray, robust=None, progress=None) -> dict:
    """For each used row: solve without it and predict it.

    Returns {row: {"residual_px", "mahalanobis", "shift_deg", "shift_mm"}} (needs >= 5 used rows:
    a solve without the row needs 4).
    """
    out = {}
    idx = np.flatnonzero(used)
    if len(idx) < 5:
        return out
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


def capture_rows(cd: CameraData, used: np.ndarray, T_cam_sonar: np.ndarray, ransac_m2: np.ndarray,
                 gate: float, loo: dict, scale: float = 1.0, miss_m: np.ndarray | None = None) -> list[dict]:
    """One dict per correspondence: residuals (px, normalised, Mahalanobis), leave-one-out, flags."""
    r_px, r_xy, S, m2, depth = per_camera_stats(cd, T_cam_sonar, scale)
    loo_gate = max(gate, CHI2_2_999)
    rows = []
    for i, cid in enumerate(cd.capture_ids):
        flags = []
        m = math.sqrt(m2[i]) if math.isfinite(m2[i]) else math.inf
        if not used[i]:
            why = "behind the camera" if depth[i] <= 0 else f"Mahalanobis {math.sqrt(ransac_m2[i]):.1f} > gate {math.sqrt(gate):.1f}"
            if miss_m is not None and math.isfinite(miss_m[i]) and depth[i] > 0:
                why += f"; its sonar centre misses the image ray by {100 * miss_m[i]:.1f} cm"
            flags.append({"kind": "ransac", "reason": f"does not fit the other captures ({why}); left out. "
                          f"Did the target move between the sonar scan and the image, or is a detection wrong?"})
        elif m2[i] > CHI2_2_99 * gate / CHI2_2_999:
            flags.append({"kind": "mahalanobis", "reason": f"large residual for its uncertainty (Mahalanobis {m:.1f}); "
                          f"check this capture's detections"})
        lo = loo.get(i)
        if lo is not None and lo["mahalanobis"] ** 2 > loo_gate:
            flags.append({"kind": "leave-one-out", "reason": f"solving without it, the pose misses it by "
                          f"{lo['residual_px']:.1f} px (Mahalanobis {lo['mahalanobis']:.1f}); dropping it moves the "
                          f"pose by {lo['shift_deg']:.2f} deg / {lo['shift_mm']:.1f} mm"})
        rows.append({
            "capture": cid,
            "used": bool(used[i]),
            "uv_px": [float(v) for v in cd.uv_px[i]],
            "X_sonar_m": [float(v) for v in cd.X_sonar_m[i]],
            "residual_px": [float(v) for v in r_px[i]],
            "residual_norm_px": float(np.linalg.norm(r_px[i])),
            "residual_normalized": [float(v) for v in r_xy[i]],
            "mahalanobis": m,
            "depth_m": float(depth[i]),
            "loo": lo,
            "flags": flags,
        })
    return rows
