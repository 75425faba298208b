"""results/calibration.json: write, read back, reject malformed files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from calib_core.errors import SessionError
from calib_core.results import CALIBRATION_FORMAT, calibration_path, load_calibration, save_calibration
from calib_core.session import load_session


def example():
    T = np.eye(4)
    T[:3, 3] = [0.1, -0.8, 0.05]
    return {"format": CALIBRATION_FORMAT, "session": "canal",
            "cameras": {"cam1": {"T_cam_sonar": T.tolist(), "rms_reprojection_px": 1.8,
                                 "captures_used": ["p01", "p02"], "covariance": (np.eye(6) * 1e-4).tolist()}},
            "range_scale": 1.0}


def test_round_trip_at_the_session_path(make_session, tmp_path):
    s = load_session(make_session(tmp_path, n_captures=2))
    path = calibration_path(s)
    assert path == s.root / "results" / "calibration.json"
    save_calibration(path, example())
    assert load_calibration(path) == example()
    assert json.loads(path.read_text()) == example()
    assert not [p for p in path.parent.iterdir() if p.name != "calibration.json"], "no temp files left"


def test_save_refuses_results_without_contract_keys(tmp_path):
    with pytest.raises(ValueError):
        save_calibration(tmp_path / "c.json", {"cameras": {}})
    assert not (tmp_path / "c.json").exists()


@pytest.mark.parametrize("content,match", [
    ("", "invalid JSON"), ("{", "invalid JSON"), ("[1, 2]", "not a sonar-camera-calibration/1"),
    ('{"format": "x", "cameras": {}}', "not a sonar-camera"), ('{"format": "sonar-camera-calibration/1"}', "cameras"),
    ('{"format": "sonar-camera-calibration/1", "cameras": {"cam1": {"T_cam_sonar": [[1, 0], [0, 1]]}}}', "finite 4x4"),
    ('{"format": "sonar-camera-calibration/1", "cameras": {"cam1": {"T_cam_sonar": [[1, 0, 0, "a"]]}}}', "finite 4x4"),
    ('{"format": "sonar-camera-calibration/1", "cameras": {"cam1": {"T_cam_sonar": [[1, [0]], 0, 0, 0]}}}', "finite 4x4"),
    ('{"format": "sonar-camera-calibration/1", "cameras": {"cam1": {"T_cam_sonar": [[NaN, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}}}', "finite 4x4"),
    ('{"format": "sonar-camera-calibration/1", "cameras": {"cam1": 5}}', "finite 4x4"),
    ("[" * 100000 + "]" * 100000, "invalid JSON"),
])
def test_malformed_calibration_files(tmp_path, content, match):
    p = tmp_path / "calibration.json"
    p.write_text(content)
    with pytest.raises(SessionError, match=match) as ei:
        load_calibration(p)
    assert ei.value.path == p


def test_missing_and_binary(tmp_path):
    with pytest.raises(SessionError, match="run 'sonarcal calibrate' first"):
        load_calibration(tmp_path / "nope.json")
    (tmp_path / "b.json").write_bytes(b"\xff\xfe\xfa" * 10)
    with pytest.raises(SessionError, match="invalid JSON"):
        load_calibration(tmp_path / "b.json")
