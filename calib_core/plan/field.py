"""The sonar's field of view: an azimuth x elevation box about a forward axis, and a range interval.

Axes: the field is described in a frame (forward, left, up) obtained from the sonar frame by a
signed axis permutation ``R_field_sonar``; for the synthetic sonar (x forward, y left, z up) it
is the identity. From clouds the forward axis is the sonar axis nearest the points' mean
direction (up is +z, or -y when z is forward, as in OpenCV-like frames), and the angular and
range limits are the 1st-99th percentiles of the points.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class SonarField:
    """Angles in degrees, ranges in metres; ``R_field_sonar`` maps sonar-frame vectors to (fwd, left, up)."""

    azimuth_deg: tuple[float, float] = (-45.0, 45.0)
    elevation_deg: tuple[float, float] = (-45.0, 45.0)
    range_m: tuple[float, float] = (0.7, 8.0)
    R_field_sonar: np.ndarray = field(default_factory=lambda: np.eye(3))
    source: str = "default (90 x 90 deg, 0.7-8 m)"

    def angles(self, X_sonar_m: np.ndarray):
        """(azimuth deg, elevation deg, range m) of sonar-frame points (N,3)."""
        F = np.asarray(X_sonar_m, float).reshape(-1, 3) @ self.R_field_sonar.T
        r = np.maximum(np.linalg.norm(F, axis=1), 1e-12)
        return np.degrees(np.arctan2(F[:, 1], F[:, 0])), np.degrees(np.arcsin(np.clip(F[:, 2] / r, -1, 1))), r

    def contains(self, X_sonar_m: np.ndarray, radius_m: float = 0.0, margin_deg: float = 2.0) -> np.ndarray:
        """(N,) the whole sphere of ``radius_m`` inside the field with an angular margin."""
        az, el, r = self.angles(X_sonar_m)
        half = np.degrees(np.arcsin(np.clip(radius_m / r, 0, 1))) + margin_deg
        return ((r - radius_m >= self.range_m[0]) & (r + radius_m <= self.range_m[1])
                & (az - half >= self.azimuth_deg[0]) & (az + half <= self.azimuth_deg[1])
                & (el - half >= self.elevation_deg[0]) & (el + half <= self.elevation_deg[1]))

    def to_sonar(self, az_deg, el_deg, r_m) -> np.ndarray:
        """Sonar-frame points (N,3) at the given azimuths, elevations (deg) and ranges (m)."""
        a, e = np.radians(az_deg), np.radians(el_deg)
        F = np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], axis=-1) * np.asarray(r_m)[..., None]
        return F.reshape(-1, 3) @ self.R_field_sonar


def _axis_frame(mean_dir: np.ndarray) -> np.ndarray:
    """Signed permutation with the sonar axis nearest ``mean_dir`` as forward (right-handed)."""
    k = int(np.argmax(np.abs(mean_dir)))
    s = 1.0 if mean_dir[k] >= 0 else -1.0
    fwd = np.zeros(3)
    fwd[k] = s
    up = np.array([0.0, -1.0, 0.0]) if k == 2 else np.array([0.0, 0.0, 1.0])  # z forward: OpenCV-like, y down
    left = np.cross(up, fwd)
    return np.stack([fwd, left, up])


def field_from_points(points_sonar_m: np.ndarray, lo_pct: float = 1.0, hi_pct: float = 99.0) -> SonarField:
    """The field spanned by cloud points (any number of clouds stacked), see the module doc."""
    P = np.asarray(points_sonar_m, float).reshape(-1, 3)
    P = P[np.linalg.norm(P, axis=1) > 1e-6]
    if len(P) < 10:
        return SonarField()
    u = P / np.linalg.norm(P, axis=1, keepdims=True)
    R = _axis_frame(u.mean(axis=0))
    f = SonarField(R_field_sonar=R)
    az, el, r = f.angles(P)
    pct = lambda v: (float(np.percentile(v, lo_pct)), float(np.percentile(v, hi_pct)))  # noqa: E731
    return SonarField(pct(az), pct(el), pct(r), R, f"clouds ({len(P)} points)")


def field_from_manifest(session) -> SonarField | None:
    """The optional ``sonar.field`` of session.yaml (the sonar model's scanned volume), or None::

        sonar:
          field: {azimuth_deg: [-45, 45], elevation_deg: [-45, 45], range_m: [0.7, 8.0]}

    Angles about the sonar's x axis (x forward, y left, z up). Raises SessionError on bad values."""
    from calib_core.errors import SessionError

    raw = ((session.raw or {}).get("sonar") or {}).get("field") if isinstance((session.raw or {}).get("sonar"), dict) else None
    if raw is None:
        return None
    keys = ("azimuth_deg", "elevation_deg", "range_m")
    try:
        lims = [tuple(float(v) for v in raw[k]) for k in keys]
    except (KeyError, TypeError, ValueError):
        raise SessionError(session.manifest_path, "sonar.field needs azimuth_deg, elevation_deg and range_m, "
                                                  "each [min, max]") from None
    bad = [k for k, lim in zip(keys, lims) if len(lim) != 2 or not all(np.isfinite(lim)) or not lim[0] < lim[1]]
    if bad or not (-180 <= lims[0][0] and lims[0][1] <= 180 and -90 <= lims[1][0] and lims[1][1] <= 90 and lims[2][0] >= 0):
        raise SessionError(session.manifest_path, f"sonar.field: {', '.join(bad) or 'angles'} must be [min, max] with "
                                                  f"min < max (azimuth within +-180, elevation within +-90 deg, range >= 0)")
    return SonarField(lims[0], lims[1], lims[2], np.eye(3), "session.yaml sonar.field")
