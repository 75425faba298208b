"""``detections.yaml`` (format sonar-camera-detections/1): read, validate, merge, write.

In memory, detections are a plain dict ``{capture_id: {sensor: entry}}`` where
``sensor`` is ``"sonar"`` or a camera name and ``entry`` is a dict with at least
``status`` (auto / accepted / corrected / rejected) and, unless rejected or not
found, ``center`` ([x, y, z] metres in the sonar frame, or [u, v] raw pixels).
Extra keys are kept as they are.
"""

from __future__ import annotations

import copy
import datetime as _dt
import math
import re
from pathlib import Path

from calib_core.errors import SessionError, short_repr
from calib_core.io.atomic import atomic_write_yaml
from calib_core.io.confine import confine_write
from calib_core.io.yaml_safe import read_yaml_mapping

DETECTIONS_FORMAT = "sonar-camera-detections/1"
DETECTIONS_FILE = "detections.yaml"
_YAML11_EXPONENT = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+$")
STATUSES = ("auto", "accepted", "corrected", "rejected")
OPERATOR_STATUSES = ("accepted", "corrected", "rejected")


def detections_path(session) -> Path:
    """The session's detections.yaml; refused (SessionError) when it is a symlink out of the session."""
    return confine_write(session.root, Path(session.root) / DETECTIONS_FILE)


def load_detections(session) -> dict:
    """Read and validate the session's detections.yaml ({} when it does not exist)."""
    path = detections_path(session)
    if not path.exists():
        return {}
    data = read_yaml_mapping(path, "detections file")
    fmt = data.get("format", DETECTIONS_FORMAT)
    if fmt != DETECTIONS_FORMAT:
        raise SessionError(path, f"format {short_repr(fmt)} is not {DETECTIONS_FORMAT}")
    caps = data.get("captures") or {}
    if not isinstance(caps, dict):
        raise SessionError(path, "'captures' must map capture ids to sensors")
    known = {c.id for c in session.captures}
    sensors = {"sonar", *session.cameras}
    out: dict = {}
    for cid, entries in caps.items():
        cid = str(cid)
        if cid not in known:
            raise SessionError(path, f"capture {short_repr(cid)} is not in session.yaml")
        if not isinstance(entries, dict):
            raise SessionError(path, f"captures.{cid} must map sensor names to entries")
        out[cid] = {}
        for sensor, e in entries.items():
            sensor = str(sensor)
            if sensor not in sensors:
                raise SessionError(path, f"captures.{cid}: unknown sensor {short_repr(sensor)} (expected one of {', '.join(sorted(sensors))})")
            out[cid][sensor] = _check_entry(path, f"captures.{cid}.{sensor}", e, 3 if sensor == "sonar" else 2)
    return out


def _check_entry(path: Path, what: str, e, dim: int) -> dict:
    if not isinstance(e, dict):
        raise SessionError(path, f"{what} must be a mapping with 'status' (and 'center')")
    status = e.get("status", "auto")
    if status not in STATUSES:
        raise SessionError(path, f"{what}.status {short_repr(status)} is not one of {', '.join(STATUSES)}")
    e = dict(e)
    e["status"] = status
    c = e.get("center")
    if c is not None:
        if not _numbers(c, dim):
            raise SessionError(path, f"{what}.center must be {dim} finite numbers (metres or pixels, at most "
                                     f"{MAX_ABS_VALUE:.0e}), got {short_repr(c)}")
        e["center"] = [float(v) for v in c]
    elif status in ("accepted", "corrected"):
        raise SessionError(path, f"{what} is '{status}' but has no center")
    _check_geometry(path, what, e)
    _check_cov(path, what, e, dim)
    return e


def _check_cov(path: Path, what: str, e: dict, dim: int) -> None:
    """The entry's covariance (``cov_m2`` 3x3 for the sonar, ``cov_px2`` 2x2 for an image), flat or
    as rows: numbers (NaN and infinities allowed, as a tool may have written them: the solver then
    assumes its default), else one clear line."""
    key = "cov_m2" if dim == 3 else "cov_px2"
    v = e.get(key)
    if v is None:
        return
    rows = v if isinstance(v, list) and len(v) == dim and all(isinstance(r, list) for r in v) else [v]
    flat = [x for r in rows if isinstance(r, list) for x in r]
    if len(flat) != dim * dim or not all(_finite_number(x) or isinstance(x, float) for x in flat):
        raise SessionError(path, f"{what}.{key} must be a {dim}x{dim} matrix of numbers (flat or as rows), "
                                 f"got {short_repr(v)}")


# extra keys that the tools read back as geometry (the sonar-guided second look, the choice among
# round objects): a hand edit that breaks one is named here, not met later as a traceback
_RANGE_KEYS = ("range_m", "partial_range_m")
_ROW_KEYS = ("two_candidates", "other_candidates")  # rows (u, v, range_m) or (x, y, z)


# a coordinate in metres or pixels beyond this is no measurement: 1e308 is "finite" yet overflowed
# the report's projections and the solver's norms (an internal error instead of one line)
MAX_ABS_VALUE = 1e6


def _numbers(v, n: int) -> bool:
    return isinstance(v, list) and len(v) == n and all(_finite_number(x) and abs(float(x)) <= MAX_ABS_VALUE for x in v)


def _check_geometry(path: Path, what: str, e: dict) -> None:
    """Validate (and make floats of) the geometry extras (and the score) of one entry, in place."""
    v = e.get("score")
    if v is not None:  # every shell formats it as a number
        if not (_finite_number(v) or (isinstance(v, float) and math.isnan(v))):
            raise SessionError(path, f"{what}.score must be a number, got {short_repr(v)}")
        e["score"] = float(v)
    for key in _RANGE_KEYS:
        if e.get(key) is not None:
            if not (_finite_number(e[key]) and 0 < float(e[key]) <= MAX_ABS_VALUE):
                raise SessionError(path, f"{what}.{key} must be a positive number (m), got {short_repr(e[key])}")
            e[key] = float(e[key])
    v = e.get("partial_center_uv_px")
    if v is not None:
        if not _numbers(v, 2):
            raise SessionError(path, f"{what}.partial_center_uv_px must be 2 finite numbers, got {short_repr(v)}")
        e["partial_center_uv_px"] = [float(x) for x in v]
    for key in _ROW_KEYS:
        v = e.get(key)
        if v is not None:
            if not (isinstance(v, list) and all(_numbers(row, 3) for row in v)):
                raise SessionError(path, f"{what}.{key} must be a list of rows of 3 finite numbers, got {short_repr(v)}")
            e[key] = [[float(x) for x in row] for row in v]


def _finite_number(v) -> bool:
    if isinstance(v, str) and _YAML11_EXPONENT.match(v.strip()):
        v = float(v)  # a hand-written 1e-3 is a string to YAML 1.1
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return False
    try:
        return math.isfinite(v)
    except OverflowError:  # an int too large for a float
        return False


def save_detections(session, detections: dict) -> None:
    """Write detections.yaml atomically (captures in manifest order)."""
    order = [c.id for c in session.captures]
    caps = {cid: detections[cid] for cid in order if cid in detections and detections[cid]}
    path = confine_write(session.root, detections_path(session))
    atomic_write_yaml(path, {"format": DETECTIONS_FORMAT, "captures": _plain(caps)})


def _plain(x):
    """Convert numpy scalars/arrays to plain Python for YAML."""
    try:
        import numpy as np

        if isinstance(x, np.ndarray):
            return [_plain(v) for v in x.tolist()]
        if isinstance(x, np.generic):
            return x.item()
    except ImportError:  # pragma: no cover
        pass
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    return x


def is_operator_entry(entry: dict | None) -> bool:
    return bool(entry) and entry.get("status") in OPERATOR_STATUSES


def merge_auto(existing: dict, auto: dict) -> dict:
    """Merge fresh automatic detections into existing ones.

    Entries an operator set (accepted / corrected / rejected) are never overwritten;
    missing or ``auto`` entries are replaced by the new automatic result.
    """
    out = copy.deepcopy(existing)
    for cid, sensors in auto.items():
        for sensor, entry in sensors.items():
            if is_operator_entry(out.get(cid, {}).get(sensor)):
                continue
            out.setdefault(cid, {})[sensor] = dict(entry, status="auto")
    return out


def now_iso() -> str:
    """UTC timestamp for change records."""
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
