"""Which captures disagree with the others, per camera, from the detections alone.

Uses the solver's robust start (RANSAC over the correspondences, its gate and statistic) so
that the workbench and ``calibrate`` agree on who does not fit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_core.pipeline import correspondences
from calib_core.solve.model import camera_data, per_camera_stats

MIN_CAPTURES = 6  # below this RANSAC cannot tell an outlier from the rest (calib_core.solve.pnp)


@dataclass
class Consistency:
    """One camera's robust pose and who does not fit it.

    T_cam_sonar: the consensus pose; outliers: capture ids outside the consensus;
    residual_px: {capture: |image centre - projected sonar centre|} at that pose.
    """

    cam: str
    T_cam_sonar: np.ndarray
    outliers: list[str]
    residual_px: dict[str, float]


def check_camera(session, detections: dict, cam: str) -> Consistency | None:
    """Robust consistency of camera ``cam`` (None with fewer than MIN_CAPTURES pairs)."""
    from calib_core.solve.pnp import ransac_pose

    corr = correspondences(session, detections, cam)
    if len(corr) < MIN_CAPTURES:
        return None
    cd = camera_data(cam, session.camera_model(cam), corr.capture_ids, corr.uv_px, corr.cov_uv_px2,
                     corr.X_sonar_m, corr.cov_X_m2)
    start = ransac_pose(cd)
    r_px = per_camera_stats(cd, start.T_cam_sonar)[0]
    res = {cid: float(np.linalg.norm(r)) for cid, r in zip(cd.capture_ids, r_px)}
    out = [cid for cid, ok in zip(cd.capture_ids, start.inliers) if not ok]
    return Consistency(cam, start.T_cam_sonar, out, res)
