"""detections.yaml: read, validate, write, merge (operator entries are never overwritten)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from calib_core.detections import (DETECTIONS_FORMAT, detections_path, is_operator_entry, load_detections,
                                   merge_auto, now_iso, save_detections)
from calib_core.errors import SessionError
from calib_core.session import load_session


@pytest.fixture
def session(make_session, tmp_path):
    return load_session(make_session(tmp_path, n_captures=3, cameras=("cam1", "cam2")))


def test_missing_file_is_empty(session):
    assert load_detections(session) == {}


def test_spec_example_reads(session):
    detections_path(session).write_text(
        "format: sonar-camera-detections/1\n"
        "captures:\n"
        "  p01:\n"
        "    sonar: {center: [0.1, -0.2, 2.5], status: accepted}\n"
        "    cam1:  {center: [812.4, 433], status: corrected, who: ana, radius_px: 40}\n"
        "    cam2:  {status: rejected}\n"
        "  p02:\n"
        "    cam1: {status: auto, reason: no sphere}\n")
    d = load_detections(session)
    assert d["p01"]["sonar"] == {"center": [0.1, -0.2, 2.5], "status": "accepted"}
    assert d["p01"]["cam1"]["center"] == [812.4, 433.0] and d["p01"]["cam1"]["who"] == "ana"
    assert d["p01"]["cam2"] == {"status": "rejected"}
    assert d["p02"]["cam1"]["status"] == "auto"


def test_round_trip_with_numpy_values_in_manifest_order(session):
    dets = {
        "p03": {"sonar": {"center": np.array([1.0, 2.0, 3.0]), "status": "auto", "n_inliers": np.int64(42)}},
        "p01": {"cam1": {"center": [np.float32(10.5), 20.25], "status": "accepted", "history": [{"at": now_iso()}]}},
        "p02": {},
    }
    save_detections(session, dets)
    text = detections_path(session).read_text()
    raw = yaml.safe_load(text)
    assert raw["format"] == DETECTIONS_FORMAT and list(raw["captures"]) == ["p01", "p03"]
    back = load_detections(session)
    assert back["p03"]["sonar"]["center"] == [1.0, 2.0, 3.0] and back["p03"]["sonar"]["n_inliers"] == 42
    assert back["p01"]["cam1"]["center"] == [10.5, 20.25]
    save_detections(session, back)
    assert detections_path(session).read_text() == text, "writing what was read changes nothing"


@pytest.mark.parametrize("captures,match", [
    ({"p99": {"sonar": {"status": "auto"}}}, "capture 'p99' is not in session.yaml"),
    ({"p01": {"lidar": {"status": "auto"}}}, "unknown sensor 'lidar'"),
    ({"p01": ["sonar"]}, "must map sensor names"),
    ({"p01": {"sonar": "accepted"}}, "must be a mapping"),
    ({"p01": {"sonar": {"status": "great", "center": [0, 0, 1]}}}, "status 'great' is not one of"),
    ({"p01": {"sonar": {"status": "accepted", "center": [0, 0]}}}, "center must be 3 finite numbers"),
    ({"p01": {"cam1": {"status": "accepted", "center": [0, 0, 1]}}}, "center must be 2 finite numbers"),
    ({"p01": {"cam1": {"status": "accepted", "center": [".nan", 1]}}}, "center must be 2 finite"),
    ({"p01": {"cam1": {"status": "accepted", "center": [float("inf"), 1]}}}, "center must be 2 finite"),
    ({"p01": {"cam1": {"status": "accepted", "center": [True, 1]}}}, "center must be 2 finite"),
    ({"p01": {"cam1": {"status": "accepted", "center": [10**400, 1]}}}, "center must be 2 finite"),
    ({"p01": {"cam1": {"status": "corrected"}}}, "'corrected' but has no center"),
    ({"p01": {"cam1": {"status": "accepted", "center": ["1e3", "x"]}}}, "center must be 2 finite"),
    ({"p01": {"cam1": {"status": ["auto"]}}}, "is not one of"),
    ([1, 2], "'captures' must map"),
    # geometry extras the sonar-guided looks read back: a broken hand edit is named, not a traceback
    ({"p01": {"cam1": {"status": "auto", "partial_center_uv_px": [1, 2, 3], "partial_range_m": 2}}},
     "partial_center_uv_px must be 2 finite"),
    ({"p01": {"cam1": {"status": "auto", "partial_center_uv_px": [1, 2], "partial_range_m": "far"}}},
     "partial_range_m must be a positive number"),
    ({"p01": {"cam1": {"status": "accepted", "center": [1, 2], "range_m": 0}}}, "range_m must be a positive"),
    ({"p01": {"cam1": {"status": "auto", "two_candidates": [[1, 2], [3, 4]]}}}, "two_candidates must be a list of rows"),
    ({"p01": {"sonar": {"status": "accepted", "center": [0, 0, 1], "other_candidates": [0.1, 0.2, 1.0]}}},
     "other_candidates must be a list of rows"),
    ({"p01": {"sonar": {"status": "auto", "center": [0, 0, 1], "other_candidates": [[0, 0, ".nan"]]}}},
     "other_candidates must be a list of rows"),
    ({"p01": {"cam1": {"status": "auto", "center": [1, 2], "score": "high"}}}, "score must be a number"),
    # a hand-edited covariance reached the solver's reshape as a ValueError / TypeError
    ({"p01": {"sonar": {"status": "accepted", "center": [0, 0, 1], "cov_m2": "abc"}}}, "cov_m2 must be a 3x3 matrix"),
    ({"p01": {"sonar": {"status": "accepted", "center": [0, 0, 1], "cov_m2": [1, 2, 3]}}}, "cov_m2 must be a 3x3"),
    ({"p01": {"sonar": {"status": "accepted", "center": [0, 0, 1], "cov_m2": [[1, 0, 0], [0, 1]]}}}, "cov_m2 must be"),
    ({"p01": {"sonar": {"status": "accepted", "center": [0, 0, 1], "cov_m2": {"a": 1}}}}, "cov_m2 must be"),
    ({"p01": {"cam1": {"status": "accepted", "center": [1, 2], "cov_px2": [1, 0, 0, "x"]}}}, "cov_px2 must be a 2x2"),
    ({"p01": {"cam1": {"status": "accepted", "center": [1, 2], "cov_px2": [1, 0, 0, True]}}}, "cov_px2 must be"),
])
def test_invalid_entries(session, captures, match):
    detections_path(session).write_text(yaml.safe_dump({"format": DETECTIONS_FORMAT, "captures": captures}))
    with pytest.raises(SessionError, match=match) as ei:
        load_detections(session)
    assert ei.value.path == detections_path(session)


@pytest.mark.parametrize("text,match", [
    ("format: sonar-camera-detections/9\n", "is not sonar-camera-detections/1"),
    ("captures: {p01: {sonar: {status: auto}\n", "invalid YAML"),
    ("just text\n", "expected a YAML mapping"),
])
def test_invalid_files(session, text, match):
    detections_path(session).write_text(text)
    with pytest.raises(SessionError, match=match):
        load_detections(session)


def test_covariances_as_the_tools_and_people_write_them(session):
    caps = {"p01": {"sonar": {"status": "accepted", "center": [0, 0, 1], "cov_m2": [[4e-6, 0, 0], [0, 4e-6, 0],
                                                                                   [0, 0, "1e-5"]]},
                    "cam1": {"status": "auto", "center": [1, 2], "cov_px2": [0.25, 0, 0, float("nan")]},
                    "cam2": {"status": "auto", "center": [1, 2], "cov_px2": [float("inf"), 0, 0, 1]}}}
    detections_path(session).write_text(yaml.safe_dump({"format": DETECTIONS_FORMAT, "captures": caps}))
    d = load_detections(session)["p01"]
    assert d["sonar"]["cov_m2"][2][2] == "1e-5" and np.isnan(d["cam1"]["cov_px2"][3])


def test_merge_auto_never_overwrites_operator_entries():
    existing = {
        "p01": {"sonar": {"center": [0, 0, 1], "status": "accepted"},
                "cam1": {"center": [5, 5], "status": "corrected"},
                "cam2": {"status": "rejected"}},
        "p02": {"sonar": {"center": [9, 9, 9], "status": "auto"}},
    }
    auto = {
        "p01": {"sonar": {"center": [1, 1, 1], "status": "auto"}, "cam1": {"center": [6, 6]}, "cam2": {"center": [7, 7]}},
        "p02": {"sonar": {"center": [2, 2, 2], "status": "accepted"}},  # auto results are always 'auto'
        "p03": {"cam1": {"center": [3, 3], "score": 0.9}},
    }
    before = yaml.safe_dump(existing)
    merged = merge_auto(existing, auto)
    assert yaml.safe_dump(existing) == before, "input untouched"
    assert merged["p01"] == existing["p01"]
    assert merged["p02"]["sonar"] == {"center": [2, 2, 2], "status": "auto"}
    assert merged["p03"]["cam1"] == {"center": [3, 3], "score": 0.9, "status": "auto"}
    assert is_operator_entry(merged["p01"]["cam2"]) and not is_operator_entry(merged["p02"]["sonar"])
    assert not is_operator_entry(None) and not is_operator_entry({})


def test_now_iso_is_utc():
    assert now_iso().endswith("+00:00")


def test_hand_written_exponents_are_numbers(session):
    detections_path(session).write_text("captures:\n  p01:\n    cam1: {center: [1e3, 2E-1], status: corrected}\n")
    assert load_detections(session)["p01"]["cam1"]["center"] == [1000.0, 0.2]


def test_geometry_extras_written_by_the_tools_read_back(session):
    caps = {"p01": {"cam1": {"status": "auto", "reason": "outline 40 % hidden", "partial_center_uv_px": [10, 12.5],
                             "partial_range_m": "2e0", "two_candidates": [[1, 2, 3.5], [4, 5, 1.5]]},
                    "sonar": {"status": "auto", "center": [0, 0, 1], "other_candidates": [[0.5, 0, 2]]}}}
    detections_path(session).write_text(yaml.safe_dump({"format": DETECTIONS_FORMAT, "captures": caps}))
    d = load_detections(session)["p01"]
    assert d["cam1"]["partial_range_m"] == 2.0 and d["cam1"]["two_candidates"][1] == [4.0, 5.0, 1.5]
    assert d["sonar"]["other_candidates"] == [[0.5, 0.0, 2.0]]
