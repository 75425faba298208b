"""A rough registration on exactly three plain image detections, for looks at its predictions.

The RANSAC registration of :mod:`calib_core.disambiguate.image` needs 4 captures that agree: a
3D-3D registration on 3 points has no redundancy (its residuals only check the 3 pairwise
distances; a rotation about the line through two of the points, or a range error shared by the
three, leaves them small while moving every other prediction). With exactly 3 plain detections
and nothing else to check them, the session's other captures are left without a place to look.

Here the 3-point registration is fitted anyway and its predictions carry their sensitivity to the
three ranges (``Resolution.sigma_px``). The caller looks at the predicted places and counts an
outline found there as a check: a wrong registration puts its predictions where no outline of the
predicted size is, so looks that find the sphere at the predicted place and size confirm it, and
the caller keeps them only when enough of them do (see :func:`calib_core.pipeline._looks_on_three`).
"""

from __future__ import annotations

import numpy as np

from calib_core.camera import CameraModel
from calib_core.disambiguate.image import (Resolution, fill_agreement, predict_places, rigid_fit, single_inliers,
                                           three_point_sigma_px, candidate_tolerances, candidate_points_cam_m)


def register_on_three(cam: CameraModel, centers_sonar_m: dict, candidates: dict, plain: list,
                      predict_for=()) -> Resolution | None:
    """The registration on the 3 captures ``plain`` (one candidate each, (u_px, v_px, range_m)
    with a measured range), or None when they do not fit one rigid transform within the RANSAC
    tolerance (their pairwise distances disagree).

    Returns a :class:`Resolution` with ``support`` 3, ``residual_px``, ``range_rel_rms``, the
    predicted places of the captures in ``predict_for`` (those with a sonar centre, in front of
    the camera and inside the image) and, for each, ``sigma_px``: how far its projection moves
    when one plain detection's range is off by ``RANGE_REL_SIGMA`` (root sum of squares).
    """
    if len(plain) != 3 or any(len(np.asarray(candidates[c]).reshape(-1, 3)) != 1 for c in plain):
        return None
    X = {c: np.asarray(centers_sonar_m[c], float) for c in plain}
    P = {c: candidate_points_cam_m(cam, candidates[c]) for c in plain}
    tol = {c: candidate_tolerances(candidates[c], False) for c in plain}
    T = rigid_fit(np.array([X[c] for c in plain]), np.array([P[c][0] for c in plain]))
    if T is None or len(single_inliers(T, plain, X, P, tol)) != 3:
        return None
    out = Resolution(T_cam_sonar=T)
    fill_agreement(out, cam, plain, X, P, tol, candidates)
    predict_places(out, cam, T, centers_sonar_m, [c for c in predict_for if c not in plain])
    targets = {c: np.asarray(centers_sonar_m[c], float) for c in out.predicted_uvr}
    out.sigma_px = three_point_sigma_px(cam, T, plain, X, P, targets) if targets else {}
    return out
