"""One camera's registration vouches for (or against) another's plain detections through the
session's stereo transform.

The session flow registers each camera to the sonar on its own (:mod:`calib_core.disambiguate.image`):
a camera with few plain detections, two of them wrong, cannot tell which are wrong (gym s48 cam2:
3 right, 2 wrong, and both wrong centres went into the solve). When the session states a stereo
transform ``T_b_a``, the better registered camera ``a`` predicts where camera ``b`` sees each
sphere: ``T_b_sonar = T_b_a @ T_a_sonar``. A plain detection of ``b`` far from that prediction, in
units of the prediction's stated uncertainty and its own, is refused (a chi-square test with 2
degrees of freedom at the false-alarm rate VOUCH_FALSE_ALARM); where ``b`` has too few plain
detections to predict on its own, the prediction is a place to look.

The prediction's uncertainty per image axis (px), root sum of squares of:
- ``a``'s registration scatter on its plain detections (RMS distance / sqrt 2, in ``b``'s focal
  length), with a floor VOUCH_FLOOR_PX (a rough registration predicts less well away from its
  points than on them);
- the stereo rotation's sigma x f_b, and its translation's sigma x f_b / range (the stated
  ``stereo_covariance``, else the solver's assumed default);
- a range error of ``a``'s registration (RANGE_REL_SIGMA of the range) seen across the baseline:
  f_b x RANGE_REL_SIGMA x |baseline| / range;
- the detection's own centre covariance (largest eigenvalue).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib_core.camera import CameraModel
from calib_core.disambiguate.image import RANGE_REL_SIGMA

# the rate at which a right detection is refused (chi-square, 2 degrees of freedom): 1 in 1000
VOUCH_FALSE_ALARM = 1e-3
VOUCH_CHI2 = float(-2.0 * np.log(VOUCH_FALSE_ALARM))  # 13.8, i.e. 3.7 sigma
# the least per-axis uncertainty of a prediction carried from another camera (px)
VOUCH_FLOOR_PX = 1.5


@dataclass(frozen=True)
class StereoPrediction:
    """Where camera ``b`` must see capture's sphere according to camera ``a``.

    uv_px: (2,) the projection; range_m: camera ``b`` to the centre; sigma_px: per-axis 1-sigma of
    the projection (without the detection's own error); source: camera ``a``'s name; terms_px:
    {term: its per-axis 1-sigma (px)}, the root sum of squares of which is sigma_px."""

    uv_px: np.ndarray
    range_m: float
    sigma_px: float
    source: str
    terms_px: dict = field(default_factory=dict)


def stereo_predictions(cam_b: CameraModel, T_b_a: np.ndarray, cov_stereo6: np.ndarray, T_a_sonar: np.ndarray,
                       residual_px_a: float, fx_a: float, centers_sonar_m: dict, source: str) -> dict:
    """{capture: StereoPrediction} for every sonar centre that lands in front of camera ``b`` and
    inside its image."""
    T_b_sonar = T_b_a @ T_a_sonar
    cov = np.asarray(cov_stereo6, float)
    sig_rot = float(np.sqrt(np.max(np.linalg.eigvalsh(cov[:3, :3]))))
    sig_t = float(np.sqrt(np.max(np.linalg.eigvalsh(cov[3:, 3:]))))
    baseline = float(np.linalg.norm(T_b_a[:3, 3]))
    reg = max(VOUCH_FLOOR_PX, residual_px_a / np.sqrt(2.0) * cam_b.fx / fx_a)
    out = {}
    for cid, X in centers_sonar_m.items():
        X_b = T_b_sonar[:3, :3] @ np.asarray(X, float) + T_b_sonar[:3, 3]
        if X_b[2] <= 0:
            continue
        uv = cam_b.project(X_b[None])[0]
        if not (np.isfinite(uv).all() and cam_b.in_image(uv[None])[0]):
            continue
        r = float(np.linalg.norm(X_b))
        terms = {"registration": reg, "stereo rotation": cam_b.fx * sig_rot, "stereo translation": cam_b.fx * sig_t / r,
                 "range across the baseline": cam_b.fx * RANGE_REL_SIGMA * baseline / r}
        s = float(np.sqrt(sum(v ** 2 for v in terms.values())))
        out[cid] = StereoPrediction(uv, r, s, source, terms)
    return out


def vouch_chi2(pred: StereoPrediction, uv_px, cov_px2=None) -> float:
    """The squared distance between a detection and the prediction in units of both
    uncertainties (chi-square with 2 degrees of freedom when both are right)."""
    C = np.eye(2) * pred.sigma_px ** 2
    if cov_px2 is not None:
        C = C + np.asarray(cov_px2, float).reshape(2, 2)
    d = np.asarray(uv_px, float).reshape(2) - pred.uv_px
    return float(d @ np.linalg.solve(C, d))


def refused(pred: StereoPrediction, uv_px, cov_px2=None) -> bool:
    """Whether the detection fails the test (VOUCH_CHI2, false-alarm rate VOUCH_FALSE_ALARM)."""
    return vouch_chi2(pred, uv_px, cov_px2) > VOUCH_CHI2
