"""Kalibr camchain YAML as an intrinsics file (``cam0: {camera_model, intrinsics,
distortion_model, distortion_coeffs, resolution, ...}``, as ``kalibr_calibrate_cameras`` writes).

Kalibr's ``pinhole`` camera with ``radtan`` ([k1, k2, r1, r2], OpenCV's plumb_bob without k3),
``equidistant`` ([k1, k2, k3, k4], OpenCV's fisheye) or ``none`` distortion maps exactly onto
:class:`~calib_core.camera.CameraModel`; other Kalibr models (omni, ds, eucm, fov) are refused
by name. A camchain with several cameras gives the entry named like the session's camera.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calib_core.camera import CameraModel
from calib_core.errors import SessionError, short_repr
from calib_core.markup import plain_line

_DISTORTIONS = {"radtan": 4, "equidistant": 4, "none": 0}


def is_camchain(data: dict) -> bool:
    """True when ``data`` looks like a Kalibr camchain (camN entries with intrinsics)."""
    return bool(data) and all(isinstance(v, dict) and "intrinsics" in v for v in data.values()) \
        and any(str(k).startswith("cam") for k in data)


def camera_from_camchain(path: Path, data: dict, camera: str | None = None, entry: str | None = None) -> CameraModel:
    """The CameraModel of one camchain entry: ``entry`` (its key: cam0, ...) when given, else
    the one whose ``camera_name`` or a rostopic path element is ``camera``, else the only one.
    A session camera's own name never selects a key: Kalibr counts from cam0 where sessions
    often count from cam1, and a silent off-by-one would calibrate the wrong camera."""
    key = _choose_entry(path, data, camera, entry)
    entry = data[key]
    model = entry.get("camera_model", "pinhole")
    if model != "pinhole":
        raise SessionError(path, f"{key}: Kalibr camera_model {short_repr(model)} is not supported (use pinhole "
                                 "with radtan or equidistant distortion)")
    dmodel = entry.get("distortion_model", "none")
    if not isinstance(dmodel, str) or dmodel not in _DISTORTIONS:  # a list or mapping is unhashable
        raise SessionError(path, f"{key}: Kalibr distortion_model {short_repr(dmodel)} is not supported "
                                 "(use radtan, equidistant or none)")
    fu, fv, pu, pv = _numbers(path, entry, key, "intrinsics", 4)
    wh = _numbers(path, entry, key, "resolution", 2)
    if not (fu > 0 and fv > 0):
        raise SessionError(path, f"{key}: focal lengths must be positive (fu={fu:.6g}, fv={fv:.6g})")
    if not np.all((wh >= 0.5) & (wh < 100_000.5)):  # before int(): 1e300 pixels is no message
        raise SessionError(path, f"{key}: resolution {wh[0]:.6g} x {wh[1]:.6g} is not plausible "
                                 "(1 to 100000 pixels a side)")
    w, h = (int(round(v)) for v in wh)
    n = _DISTORTIONS[dmodel]
    coeffs = _numbers(path, entry, key, "distortion_coeffs", n) if n else _no_distortion(path, entry, key)
    K = np.array([[fu, 0.0, pu], [0.0, fv, pv], [0.0, 0.0, 1.0]])
    name = plain_line(_text(entry.get("camera_name")) or str(key))[:200]
    if dmodel == "equidistant":
        return CameraModel(w, h, K, coeffs, name=name, fisheye=True)
    return CameraModel(w, h, K, np.r_[coeffs, 0.0] if n else np.zeros(5), name=name)


def _choose_entry(path: Path, data: dict, camera: str | None, entry: str | None) -> str:
    keys = [str(k) for k in data]
    listed = ", ".join(short_repr(k) for k in keys[:8]) + (" ..." if len(keys) > 8 else "")
    if entry is not None:
        if entry not in data:
            raise SessionError(path, f"Kalibr camchain has no entry {short_repr(entry)} (it holds {listed})")
        return entry
    if len(keys) == 1:
        return next(iter(data))
    said = "say which with the camera's 'intrinsics_entry: cam0' (say) in session.yaml"
    if camera is None:
        raise SessionError(path, f"Kalibr camchain holds {len(keys)} cameras ({listed}): {said}")
    hits = [k for k, v in data.items() if _names(v, camera)]
    if len(hits) > 1:  # two entries named alike: taking the first would be a guess
        raise SessionError(path, f"Kalibr camchain: {len(hits)} entries ({', '.join(short_repr(str(k)) for k in hits[:8])})"
                                 f" have the camera_name or a rostopic part {short_repr(camera)}: {said}")
    if hits:
        return hits[0]
    raise SessionError(path, f"Kalibr camchain holds {len(keys)} cameras ({listed}) and none has the camera_name "
                             f"or a rostopic part {short_repr(camera)}: {said}")


def _text(value) -> str:
    """A name read from the file as text ("" unless a string or a number: never str() of a tree)."""
    return str(value) if isinstance(value, (str, int, float)) and not isinstance(value, bool) else ""


def _names(v: dict, camera: str) -> bool:
    """Does camchain entry ``v`` name ``camera`` (its camera_name, or an element of its rostopic)?"""
    return _text(v.get("camera_name")) == camera or camera in _text(v.get("rostopic")).strip("/").split("/")


def _no_distortion(path: Path, entry: dict, key: str) -> np.ndarray:
    """``distortion_model: none``: coefficients, if any are written, must all be zero. Non-zero
    ones contradict the model name, and dropping them silently would mis-project every pixel."""
    given = entry.get("distortion_coeffs")
    if given is None or (isinstance(given, list) and not given):
        return np.zeros(0)
    if not isinstance(given, list):
        raise SessionError(path, f"{key}: 'distortion_coeffs' must be a list of numbers")
    arr = _numbers(path, entry, key, "distortion_coeffs", len(given))
    if np.any(arr != 0):
        raise SessionError(path, f"{key}: distortion_model 'none' but distortion_coeffs are not zero "
                                 f"({', '.join(f'{v:.6g}' for v in arr[:6])}): name the model (radtan or equidistant)")
    return np.zeros(0)


def _numbers(path: Path, entry: dict, key: str, field: str, n: int) -> np.ndarray:
    try:
        arr = np.asarray(entry[field], dtype=float).ravel()
    except KeyError:
        raise SessionError(path, f"{key}: missing '{field}'") from None
    except (TypeError, ValueError, OverflowError, RecursionError):
        raise SessionError(path, f"{key}: '{field}' must be a list of numbers") from None
    if arr.size != n:
        raise SessionError(path, f"{key}: '{field}' has {arr.size} values, expected {n}")
    if not np.isfinite(arr).all():
        raise SessionError(path, f"{key}: '{field}' holds NaN or infinite values")
    return arr
