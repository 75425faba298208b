"""The covariance of a session's stereo transform: stated in session.yaml, or assumed."""

from __future__ import annotations

import numpy as np

from calib_core.errors import SessionError
from calib_core.solve.rig import default_stereo_cov


def session_stereo_cov(session, key: str) -> tuple[np.ndarray, bool]:
    """Covariance of a stereo transform from session.yaml's optional ``stereo_covariance``
    mapping (same keys as ``stereo``), else the assumed default. Returns (cov, assumed)."""
    raw = (session.raw or {}).get("stereo_covariance") or {}
    if isinstance(raw, dict) and key in raw:
        try:
            C = np.asarray(raw[key], float).reshape(6, 6)
        except (TypeError, ValueError):
            raise SessionError(session.manifest_path, f"stereo_covariance.{key} must be a 6x6 matrix") from None
        C = 0.5 * (C + C.T)
        if not np.isfinite(C).all() or np.any(np.linalg.eigvalsh(C) <= 0):
            raise SessionError(session.manifest_path, f"stereo_covariance.{key} must be positive definite")
        return C, False
    return default_stereo_cov(), True
