"""Which captures disagree with the others, per camera, from the detections alone.

Uses the solver's robust start (RANSAC over the correspondences, its gate and statistic) so
that the workbench and ``calibrate`` agree on who does not fit.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib_core.pipeline import correspondences
from calib_core.solve.model import per_camera_stats
from calib_core.solve.stated import camera_data_from

MIN_CAPTURES = 6  # below this RANSAC cannot tell an outlier from the rest (calib_core.solve.pnp)


@dataclass
class Consistency:
    """One camera's robust pose and who does not fit it.

    T_cam_sonar: the consensus pose; outliers: capture ids outside the consensus;
    residual_px: {capture: |image centre - projected sonar centre|} at that pose.
    clear: False when another set of captures agrees with another pose about as well;
    warnings: the solver's words about it (:func:`calib_core.solve.consensus.no_consensus_phrase`).
    """

    cam: str
    T_cam_sonar: np.ndarray
    outliers: list[str]
    residual_px: dict[str, float]
    clear: bool = True
    warnings: list[str] = field(default_factory=list)


def check_camera(session, detections: dict, cam: str) -> Consistency | None:
    """Robust consistency of camera ``cam`` (None with fewer than MIN_CAPTURES pairs)."""
    corr = correspondences(session, detections, cam)
    if len(corr) < MIN_CAPTURES:
        return None
    cd = camera_data_from(session.camera_model(cam), detections, cam, corr, with_ranges=False)
    return consistency_of(cd)


def consistency_of(cd) -> Consistency:
    """Who does not fit, from one camera's correspondences: the solver's own consensus and gate
    (:func:`calib_core.solve.pnp.ransac_pose`), so a Solve and the flags agree."""
    from calib_core.solve.pnp import ransac_pose

    start = ransac_pose(cd)
    r_px = per_camera_stats(cd, start.T_cam_sonar)[0]
    res = {cid: float(np.linalg.norm(r)) for cid, r in zip(cd.capture_ids, r_px)}
    out = [cid for cid, ok in zip(cd.capture_ids, start.inliers) if not ok]
    return Consistency(cd.name, start.T_cam_sonar, out, res, start.clear, list(start.warnings))
