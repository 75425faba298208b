"""Small synthetic multi-camera detections for the stereo-vouching tests (not a test module)."""

from __future__ import annotations

import cv2
import numpy as np

from calib_core.camera import CameraModel
from calib_core.geometry import invert_T


def camera(w: int = 960, h: int = 600, f: float = 700.0) -> CameraModel:
    """A distortion-free camera (px)."""
    return CameraModel(w, h, np.array([[f, 0, w / 2], [0, f, h / 2], [0, 0, 1]]), np.zeros(5))


def transform(rvec, t) -> np.ndarray:
    """4x4 from a rotation vector (rad) and a translation (m)."""
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(np.asarray(rvec, float))[0]
    T[:3, 3] = t
    return T


def detections(cams: dict, T_cam_sonar: dict, rng, n: int = 8, wrong=()) -> dict:
    """``{p0..: {sonar, cam..}}`` auto entries: n spheres 2.5-4.5 m in front of cam1, every camera's
    centre with 0.3 px of noise and its range with 0.5 %; ``wrong`` = ((capture, px), ...) moves
    cam2's centre that far in a random direction."""
    T1 = T_cam_sonar["cam1"]
    X_cam1 = np.column_stack([rng.uniform(-1, 1, n), rng.uniform(-0.4, 0.4, n), rng.uniform(2.5, 4.5, n)])
    X_sonar = (invert_T(T1)[:3, :3] @ X_cam1.T).T + invert_T(T1)[:3, 3]
    dets = {}
    for i in range(n):
        d = {"sonar": {"status": "auto", "center": X_sonar[i].tolist()}}
        for c, Tc in T_cam_sonar.items():
            Xc = Tc[:3, :3] @ X_sonar[i] + Tc[:3, 3]
            uv = cams[c].project(Xc[None])[0] + rng.normal(0, 0.3, 2)
            d[c] = {"status": "auto", "center": uv.tolist(), "cov_px2": [0.09, 0, 0, 0.09],
                    "range_m": float(np.linalg.norm(Xc) * (1 + rng.normal(0, 0.005)))}
        dets[f"p{i}"] = d
    for cid, off in wrong:
        a = rng.uniform(0, 2 * np.pi)
        dets[cid]["cam2"]["center"] = (np.asarray(dets[cid]["cam2"]["center"]) + off * np.array([np.cos(a), np.sin(a)])).tolist()
    return dets
