"""``results/calibration.json`` (format sonar-camera-calibration/1): read and write."""

from __future__ import annotations

import json
from pathlib import Path

from calib_core.errors import SessionError, short_repr
from calib_core.io.atomic import atomic_write_json
from calib_core.io.confine import confine_write

CALIBRATION_FORMAT = "sonar-camera-calibration/1"
MAX_CALIBRATION_BYTES = 50_000_000


def calibration_path(session) -> Path:
    """``results/calibration.json`` of the session; refused (SessionError) when a symlink
    on the way leads out of the session folder."""
    return confine_write(session.root, Path(session.root) / "results" / "calibration.json")


def save_calibration(path: str | Path, result: dict, root=None, explicit: bool = False) -> None:
    """Write a calibration result dict atomically (must carry the contract's keys).

    With ``root`` (the session folder) the path is confined to it first
    (:func:`calib_core.io.confine.confine_write`)."""
    if result.get("format") != CALIBRATION_FORMAT or "cameras" not in result:
        raise ValueError("calibration result lacks the contract keys 'format' and 'cameras'")
    if root is not None:
        confine_write(root, path, explicit=explicit)
    atomic_write_json(path, result)


def load_calibration(path: str | Path) -> dict:
    """Read a calibration.json, with clear errors for missing/corrupt files."""
    path = Path(path)
    if not path.is_file():
        raise SessionError(path, "calibration file not found (run 'sonarcal calibrate' first)")
    try:
        size = path.stat().st_size
        if size > MAX_CALIBRATION_BYTES:
            raise SessionError(path, f"calibration file is {size / 1e6:.0f} MB: far more than a calibration holds")
        data = json.loads(path.read_text(encoding="utf-8-sig"))
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise SessionError(path, f"invalid JSON ({e})") from None
    except RecursionError:
        raise SessionError(path, "invalid JSON (nested too deeply)") from None
    except OSError as e:
        raise SessionError(path, f"cannot read the calibration file: {e.strerror or e}") from None
    if not isinstance(data, dict) or data.get("format") != CALIBRATION_FORMAT or not isinstance(data.get("cameras"), dict):
        raise SessionError(path, f"not a {CALIBRATION_FORMAT} file (needs 'format' and a 'cameras' mapping)")
    import numpy as np

    from calib_core.geometry import is_rigid

    for cam, c in data["cameras"].items():
        try:
            T = np.asarray(c.get("T_cam_sonar"), dtype=float) if isinstance(c, dict) else None
        except (TypeError, ValueError, OverflowError, RecursionError):
            T = None
        if T is None or T.shape != (4, 4) or not np.isfinite(T).all():
            raise SessionError(path, f"cameras.{short_repr(cam)}.T_cam_sonar must be a finite 4x4 matrix")
        if not is_rigid(T):  # 1e308 entries are finite, and overflowed the report and plan
            raise SessionError(path, f"cameras.{short_repr(cam)}.T_cam_sonar is not a rigid transform (rotation "
                                     "not orthonormal or last row not 0 0 0 1)")
    return data
