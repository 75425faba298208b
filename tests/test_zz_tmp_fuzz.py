"""Property-based tests: arbitrary input to the parsers raises SessionError or nothing.

Text clouds, session.yaml, detections.yaml, intrinsics YAML and calibration.json get both
random bytes/text and valid documents with random parts replaced by random values.
"""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib_core.detections import load_detections
from calib_core.errors import SessionError
from calib_core.io.clouds import load_cloud
from calib_core.io.intrinsics import load_intrinsics
from calib_core.results import load_calibration
from calib_core.session import load_session, validate_session

SETTINGS = settings(max_examples=1500, deadline=None, suppress_health_check=list(HealthCheck), derandomize=False)

# scalar values that break naive code: huge ints, NaN/inf, bools, empty and odd strings
SCALARS = st.one_of(
    st.none(), st.booleans(), st.integers(), st.integers(min_value=10**300, max_value=10**400),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=20),
    st.sampled_from(["../x", "/etc/passwd", "", ".", "clouds", "\x00", "p01", "cam1", "sonar", "accepted", "auto", "~"]),
)
VALUES = st.recursive(SCALARS, lambda inner: st.one_of(st.lists(inner, max_size=5),
                                                       st.dictionaries(st.one_of(st.text(max_size=8), st.integers()), inner,
                                                                       max_size=4)), max_leaves=12)


def _paths(node, prefix=()):
    """Every (path) into a nested dict/list document."""
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, prefix + (i,))


def mutate(data, base):
    """Replace (or delete) 1-3 random parts of ``base``."""
    doc = copy.deepcopy(base)
    for _ in range(data.draw(st.integers(1, 3))):
        paths = [p for p in _paths(doc) if p]
        if not paths:
            return data.draw(VALUES)
        path = data.draw(st.sampled_from(paths))
        parent = doc
        for k in path[:-1]:
            parent = parent[k]
        if isinstance(parent, dict) and data.draw(st.booleans()):
            del parent[path[-1]]
        else:
            parent[path[-1]] = data.draw(VALUES)
    return doc


def dump(doc) -> str:
    try:
        return yaml.safe_dump(doc, sort_keys=False)
    except (yaml.YAMLError, ValueError, OverflowError):
        return "{}"


@pytest.fixture(scope="module")
def base_session(tmp_path_factory):
    from conftest import build_session

    root = build_session(tmp_path_factory.mktemp("prop"), n_captures=2, cameras=("cam1", "cam2"), n_points=60)
    return root, yaml.safe_load((root / "session.yaml").read_text()), (root / "session.yaml").read_text()


# ---- text point clouds -----------------------------------------------------------
TOKENS = st.sampled_from(["1", "-2.5", "3e2", "nan", "inf", "-inf", "1e999", "x", "y", "z", "intensity", "#", "#c",
                          ",", ";", " ", "\t", "\n", "\r\n", "0x1F", "1,5", "--", "\ufeff", "é", "1_0"])


@SETTINGS
@given(text=st.lists(TOKENS, max_size=60).map("".join), suffix=st.sampled_from([".xyz", ".csv", ".txt"]))
def test_text_cloud_parser(tmp_path_factory, text, suffix):
    p = tmp_path_factory.getbasetemp() / f"prop_cloud{suffix}"
    p.write_text(text, encoding="utf-8")
    _only_session_error(lambda: _check_cloud(load_cloud(p)))


@SETTINGS
@given(raw=st.binary(max_size=400), suffix=st.sampled_from([".xyz", ".ply", ".pcd", ".npy", ".las"]))
def test_any_bytes_as_cloud(tmp_path_factory, raw, suffix):
    p = tmp_path_factory.getbasetemp() / f"prop_bytes{suffix}"
    p.write_bytes(raw)
    _only_session_error(lambda: _check_cloud(load_cloud(p)))


@SETTINGS
@given(prefix=st.sampled_from([b"ply\nformat ascii 1.0\n", b"ply\nformat binary_little_endian 1.0\n",
                               b"# .PCD v0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"]),
       body=st.lists(st.sampled_from([b"element vertex 3\n", b"element vertex -1\n", b"property float x\n",
                                      b"property float y\n", b"property float z\n", b"property list uchar int i\n",
                                      b"end_header\n", b"WIDTH 3\n", b"POINTS 3\n", b"DATA ascii\n", b"DATA binary\n",
                                      b"1 2 3\n", b"nan 0 1\n", b"\x00\x00\x80?" * 3, b"element face 1\n"]), max_size=12))
def test_ply_pcd_headers(tmp_path_factory, prefix, body):
    p = tmp_path_factory.getbasetemp() / ("prop_h.ply" if prefix.startswith(b"ply") else "prop_h.pcd")
    p.write_bytes(prefix + b"".join(body))
    _only_session_error(lambda: _check_cloud(load_cloud(p)))


def _check_cloud(c):
    assert c.points_m.ndim == 2 and c.points_m.shape[1] == 3 and len(c.points_m) > 0
    assert np.isfinite(c.points_m).all()


def _only_session_error(fn):
    try:
        fn()
    except SessionError as e:
        assert e.path is not None and e.problem


# ---- session.yaml -----------------------------------------------------------------
@SETTINGS
@given(data=st.data())
def test_session_yaml_mutations(base_session, data):
    root, base, original = base_session
    try:
        (root / "session.yaml").write_text(dump(mutate(data, base)))
        _only_session_error(lambda: load_session(root))
        check = validate_session(root)
        assert all(isinstance(e, SessionError) for e in check.problems)
    finally:
        (root / "session.yaml").write_text(original)


@SETTINGS
@given(text=st.text(max_size=300))
def test_session_yaml_any_text(base_session, text):
    root, _, original = base_session
    try:
        (root / "session.yaml").write_text(text, encoding="utf-8")
        _only_session_error(lambda: load_session(root))
    finally:
        (root / "session.yaml").write_text(original)


# ---- detections.yaml --------------------------------------------------------------
DET_BASE = {"format": "sonar-camera-detections/1",
            "captures": {"p01": {"sonar": {"center": [0.1, 0.2, 2.0], "status": "accepted"},
                                 "cam1": {"center": [10.0, 20.0], "status": "corrected", "score": 0.9}},
                         "p02": {"cam2": {"status": "rejected"}}}}


@SETTINGS
@given(data=st.data())
def test_detections_mutations(base_session, data):
    root, _, _ = base_session
    session = load_session(root)
    path = root / "detections.yaml"
    try:
        path.write_text(dump(mutate(data, DET_BASE)) if data.draw(st.booleans()) else data.draw(st.text(max_size=200)))
        dets = None
        try:
            dets = load_detections(session)
        except SessionError as e:
            assert e.path == path
        if dets is not None:  # what loads is well-formed
            for sensors in dets.values():
                for sensor, e in sensors.items():
                    assert e["status"] in ("auto", "accepted", "corrected", "rejected")
                    if "center" in e:
                        assert len(e["center"]) == (3 if sensor == "sonar" else 2)
                        assert all(np.isfinite(e["center"]))
    finally:
        path.unlink(missing_ok=True)


# ---- intrinsics -------------------------------------------------------------------
INTR_BASE = {"image_width": 64, "image_height": 48, "camera_name": "cam1",
             "camera_matrix": {"rows": 3, "cols": 3, "data": [50.0, 0, 31.5, 0, 50.0, 23.5, 0, 0, 1]},
             "distortion_model": "plumb_bob",
             "distortion_coefficients": {"rows": 1, "cols": 5, "data": [-0.05, 0.01, 0.0, 0.0, 0.0]}}


@SETTINGS
@given(data=st.data())
def test_intrinsics_mutations(tmp_path_factory, data):
    p = tmp_path_factory.getbasetemp() / "prop_intr.yaml"
    choice = data.draw(st.integers(0, 2))
    if choice == 0:
        p.write_text(dump(mutate(data, INTR_BASE)))
    elif choice == 1:
        p.write_text(data.draw(st.text(max_size=200)), encoding="utf-8")
    else:
        p.write_bytes(b"%YAML:1.0\n" + data.draw(st.binary(max_size=200)))
    try:
        cam = load_intrinsics(p)
    except SessionError as e:
        assert e.path == p
        return
    assert cam.width_px > 0 and cam.height_px > 0 and np.isfinite(cam.K).all() and cam.fx > 0


# ---- calibration.json -------------------------------------------------------------
CAL_BASE = {"format": "sonar-camera-calibration/1", "session": "s",
            "cameras": {"cam1": {"T_cam_sonar": np.eye(4).tolist(), "rms_reprojection_px": 1.0}}}


@SETTINGS
@given(data=st.data())
def test_calibration_mutations(tmp_path_factory, data):
    p = tmp_path_factory.getbasetemp() / "prop_cal.json"
    doc = mutate(data, CAL_BASE)
    try:
        text = json.dumps(doc)
    except (TypeError, ValueError):
        text = "{}"
    p.write_text(text)
    _only_session_error(lambda: load_calibration(p))
