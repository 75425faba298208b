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
    if dmodel not in _DISTORTIONS:
        raise SessionError(path, f"{key}: Kalibr distortion_model {short_repr(dmodel)} is not supported "
                                 "(use radtan, equidistant or none)")
    fu, fv, pu, pv = _numbers(path, entry, key, "intrinsics", 4)
    w, h = (int(round(v)) for v in _numbers(path, entry, key, "resolution", 2))
    if not (fu > 0 and fv > 0):
        raise SessionError(path, f"{key}: focal lengths must be positive (fu={fu}, fv={fv})")
    if not (0 < w <= 100_000 and 0 < h <= 100_000):
        raise SessionError(path, f"{key}: resolution {w} x {h} is not plausible (1 to 100000 pixels a side)")
    n = _DISTORTIONS[dmodel]
    coeffs = _numbers(path, entry, key, "distortion_coeffs", n) if n else np.zeros(0)
    K = np.array([[fu, 0.0, pu], [0.0, fv, pv], [0.0, 0.0, 1.0]])
    name = str(entry.get("camera_name") or key)[:200]
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
    if camera is not None:
        for k, v in data.items():
            topic = str(v.get("rostopic") or "")
            if str(v.get("camera_name") or "") == camera or camera in topic.strip("/").split("/"):
                return k
    raise SessionError(path, f"Kalibr camchain holds {len(keys)} cameras ({listed}) and none has the camera_name "
                             f"or a rostopic part {short_repr(camera)}: say which with the camera's "
                             "'intrinsics_entry: cam0' (say) in session.yaml")


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
