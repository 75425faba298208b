"""Result types shared by the image and sonar detectors, and their detections.yaml form."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def _r(x, nd=6):
    return [round(float(v), nd) for v in np.asarray(x, float).ravel()]


@dataclass
class ImageDetection:
    """The sphere found (or not) in one camera image.

    Attributes:
        found: False when nothing trustworthy was found (then ``reason`` says why).
        center_uv_px: (2,) raw (distorted) pixel of the perspective projection of the
            sphere centre (the spec's camera ``center``), not the ellipse centre.
        cov_uv_px2: (2,2) covariance of ``center_uv_px`` in px^2.
        score: P(the detection is right, within 3 px) (:mod:`calib_core.detect.image.score`), or
            None when no probability is known (the look at a predicted place: its ``outline_seen``
            extra says how much of the outline it saw; not written to detections.yaml then).
        reason: empty when found; else e.g. "no sphere", "cut by the image border", "two candidates".
        ellipse_px: ((cx, cy), (major, minor), angle_deg) of the silhouette in raw pixels, for drawing.
        radius_px: mean apparent radius in pixels.
        range_m: distance camera->sphere centre from the known diameter (a free check against the sonar).
        method: "ellipse-exact", "hough-circle", ...
        extras: other fields worth keeping (edge counts, timings).
    """

    found: bool
    center_uv_px: np.ndarray | None = None
    cov_uv_px2: np.ndarray | None = None
    score: float | None = 0.0
    reason: str = ""
    ellipse_px: tuple | None = None
    radius_px: float | None = None
    range_m: float | None = None
    method: str = ""
    extras: dict = field(default_factory=dict)

    def to_entry(self) -> dict:
        """detections.yaml entry (status auto)."""
        e: dict = {"status": "auto", "method": self.method}
        if self.score is not None:
            e["score"] = round(float(self.score), 4)
        if self.found:
            e["center"] = _r(self.center_uv_px, 3)
            if self.cov_uv_px2 is not None:
                e["cov_px2"] = _r(self.cov_uv_px2, 5)
            if self.ellipse_px is not None:
                (cx, cy), (a, b), ang = self.ellipse_px
                e["ellipse_px"] = _r([cx, cy, a, b, ang], 3)
            if self.radius_px is not None:
                e["radius_px"] = round(float(self.radius_px), 3)
            if self.range_m is not None:
                e["range_m"] = round(float(self.range_m), 4)
        else:
            e["reason"] = self.reason
        for k, v in self.extras.items():
            e[k] = v
        return e


@dataclass
class SonarDetection:
    """The sphere found (or not) in one sonar cloud.

    Attributes:
        found: False when nothing trustworthy was found (then ``reason`` says why).
        center_sonar_m: (3,) sphere centre in the sonar frame, metres (bias-corrected).
        cov_sonar_m2: (3,3) covariance of ``center_sonar_m`` in m^2.
        n_inliers: points on the sphere model.
        rms_m: residual RMS of the inliers (m).
        score: quality in [0, 1].
        reason: empty when found; else why not.
        apparent_diameter_m: diameter a free-radius fit sees (blooming makes it larger than the truth).
        diameter_m: diameter the sonar data supports after modelling the beam width (for the
            "is session.yaml's diameter right?" check), or None.
        method: "cone-model", "known-radius", ...
        inlier_mask: (N,) bool over the input cloud, or None (not written to YAML).
    """

    found: bool
    center_sonar_m: np.ndarray | None = None
    cov_sonar_m2: np.ndarray | None = None
    n_inliers: int = 0
    rms_m: float = float("nan")
    score: float = 0.0
    reason: str = ""
    apparent_diameter_m: float | None = None
    diameter_m: float | None = None
    method: str = ""
    inlier_mask: np.ndarray | None = None
    extras: dict = field(default_factory=dict)

    def to_entry(self) -> dict:
        """detections.yaml entry (status auto)."""
        e: dict = {"status": "auto", "method": self.method, "score": round(float(self.score), 4)}
        if self.found:
            e["center"] = _r(self.center_sonar_m, 6)
            if self.cov_sonar_m2 is not None:
                e["cov_m2"] = [float(f"{v:.6g}") for v in np.asarray(self.cov_sonar_m2, float).ravel()]
            e["inliers"] = int(self.n_inliers)
            e["rms_m"] = round(float(self.rms_m), 6)
            if self.apparent_diameter_m is not None:
                e["apparent_diameter_m"] = round(float(self.apparent_diameter_m), 4)
            if self.diameter_m is not None:
                e["diameter_m"] = round(float(self.diameter_m), 4)
        else:
            e["reason"] = self.reason
        for k, v in self.extras.items():
            e[k] = v
        return e
