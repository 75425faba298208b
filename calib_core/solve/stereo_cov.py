"""The covariance of a session's stereo transform: stated in session.yaml (for either direction of
the pair), or assumed; and the link a joint solve takes between two cameras (stated for the pair,
or chained through the others)."""

from __future__ import annotations

import math

import numpy as np

from calib_core.errors import SessionError
from calib_core.geometry import invert_T
from calib_core.stereo.chain import chained_stereo, invert_with_cov

# Assumed stereo uncertainty when none is given: a good checkerboard stereo calibration
# (about 0.05 deg per axis and 1 mm per axis, 1-sigma). An assumption, said in the output.
# (Also what the stereo vouching of detections assumes: this module is in the detector fingerprint.)
DEFAULT_STEREO_SIGMA_RAD = math.radians(0.05)
DEFAULT_STEREO_SIGMA_M = 0.001


def default_stereo_cov() -> np.ndarray:
    return np.diag([DEFAULT_STEREO_SIGMA_RAD**2] * 3 + [DEFAULT_STEREO_SIGMA_M**2] * 3)


def assumed_stereo_text() -> str:
    """What the assumed stereo uncertainty is, as the warnings say it (from the constants above)."""
    return (f"assumed {math.degrees(DEFAULT_STEREO_SIGMA_RAD):.2g} deg / {DEFAULT_STEREO_SIGMA_M * 1000:.2g} mm "
            "(1-sigma) per axis for the stereo transform")


def session_stereo_cov(session, ref: str, cam: str, T_cam_ref: np.ndarray) -> tuple[np.ndarray, bool]:
    """Covariance of the stereo transform ``T_cam_ref`` from session.yaml's optional
    ``stereo_covariance`` mapping (same keys as ``stereo``; one stated for ``T_<ref>_<cam>`` is
    carried over to the inverse), else the assumed default. Returns (cov, assumed)."""
    raw = (session.raw or {}).get("stereo_covariance") or {}
    key, inverse = f"T_{cam}_{ref}", f"T_{ref}_{cam}"
    if isinstance(raw, dict) and key not in raw and inverse in raw:
        return invert_with_cov(invert_T(T_cam_ref), _stated(session, raw, inverse))[1], False
    if isinstance(raw, dict) and key in raw:
        return _stated(session, raw, key), False
    return default_stereo_cov(), True


def key_stereo_cov(session, key: str) -> tuple[np.ndarray, bool]:
    """(covariance, assumed) of the transform session.yaml states under ``stereo.<key>``, as stated
    under the same key in ``stereo_covariance``, else the assumed default."""
    raw = (session.raw or {}).get("stereo_covariance") or {}
    if isinstance(raw, dict) and key in raw:
        return _stated(session, raw, key), False
    return default_stereo_cov(), True


def stereo_link(session, ref: str, cam: str):
    """(T_cam_ref, covariance, assumed, via) along the shortest chain of session.yaml's stereo
    transforms (:func:`calib_core.stereo.chain.chained_stereo`): stated for the pair (via None),
    else chained through the cameras ``via`` names ("cam3", or "cam3, cam4"); ``assumed`` when
    any link's covariance is the assumed default. None when no chain ties the two."""
    got = chained_stereo(session.stereo, lambda key: key_stereo_cov(session, key)[0], ref, cam, list(session.cameras))
    if got is None:
        return None
    T, cov, path = got
    keys = [f"T_{b}_{a}" if f"T_{b}_{a}" in session.stereo else f"T_{a}_{b}" for a, b in zip(path[:-1], path[1:])]
    assumed = any(key_stereo_cov(session, key)[1] for key in keys)
    return T, cov, assumed, ", ".join(path[1:-1]) or None


def _stated(session, raw: dict, key: str) -> np.ndarray:
    """stereo_covariance.<key> as a symmetric positive definite 6x6 (else one clear line)."""
    try:
        C = np.asarray(raw[key], float).reshape(6, 6)
    except (TypeError, ValueError, OverflowError):
        raise SessionError(session.manifest_path, f"stereo_covariance.{key} must be a 6x6 matrix") from None
    C = 0.5 * (C + C.T)
    if not np.isfinite(C).all() or np.any(np.linalg.eigvalsh(C) <= 0):
        raise SessionError(session.manifest_path, f"stereo_covariance.{key} must be positive definite")
    return C
