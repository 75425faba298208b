"""calibrate_session and ``sonarcal calibrate`` on a session folder built from synthetic correspondences."""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import pytest
import yaml

from calib_core.detections import load_detections
from calib_core.errors import SessionError
from calib_core.geometry import pose_error
from calib_core.io.intrinsics import save_intrinsics_ros
from calib_core.results import load_calibration
from calib_core.session import load_session
from calib_core.solve.calibrate import calibrate_session
from calib_core.solve.simulate import synthetic_rig


def write_session(root, rig, moved=None, rejected=None, scale_stereo=True, n_only=None):
    """A session whose detections.yaml holds accepted entries for every capture (no images needed)."""
    root.mkdir(parents=True, exist_ok=True)
    ids = rig.capture_ids[:n_only] if n_only else rig.capture_ids
    for c, cam in rig.cameras.items():
        save_intrinsics_ros(root / "intrinsics" / f"{c}.yaml", cam, c)
    man = {"format": "sonar-camera-session/1", "name": "synthetic", "sphere": {"diameter": 0.22},
           "cameras": {c: {"intrinsics": f"intrinsics/{c}.yaml"} for c in rig.cameras},
           "captures": [{"id": i, "cloud": f"clouds/{i}.ply", "images": {c: f"images/{c}/{i}.png" for c in rig.cameras}}
                        for i in ids],
           "measured": {"cam1-sonar": 0.8656, "cam2-sonar": 0.8625, "cam1-cam2": 0.7437}}
    if scale_stereo:
        man["stereo"] = {"T_cam2_cam1": rig.T_cam2_cam1.tolist()}
    (root / "session.yaml").write_text(yaml.safe_dump(man, sort_keys=False))
    caps = {}
    for k, cid in enumerate(ids):
        X = rig.X_sonar_m[k] + (np.array([0.1, 0.1, -0.1]) if cid == moved else 0)
        e = {"sonar": {"center": X.tolist(), "status": "accepted", "cov_m2": rig.cov_X_m2[k].ravel().tolist()}}
        for c in rig.cameras:
            e[c] = {"center": rig.uv_px[c][k].tolist(), "status": "accepted", "cov_px2": rig.cov_uv_px2[c][k].ravel().tolist()}
        if cid == rejected:
            e["cam1"] = {"status": "rejected"}
        caps[cid] = e
    (root / "detections.yaml").write_text(yaml.safe_dump({"format": "sonar-camera-detections/1", "captures": caps}))
    return root


@pytest.fixture(scope="module")
def rig():
    return synthetic_rig(31, n_captures=10, sigma_px=0.3, sigma_m=0.003, scale=1.006)


def test_calibrate_session_full_result(tmp_path, rig):
    root = write_session(tmp_path / "s", rig, moved="p03", rejected="p05")
    s = load_session(root)
    cal = calibrate_session(s, load_detections(s), {"detect": False})
    assert cal["format"] == "sonar-camera-calibration/1" and cal["session"] == "synthetic"
    c1 = cal["cameras"]["cam1"]
    assert "p05" not in c1["captures_used"] and "p03" not in c1["captures_used"] and len(c1["captures_used"]) == 8
    assert c1["skipped"]["p05"] == "image rejected"
    assert any(o["capture"] == "p03" and "ransac" in o["kinds"] for o in c1["outliers"])
    assert "p03" not in cal["cameras"]["cam2"]["captures_used"]
    for cam in ("cam1", "cam2"):
        c = cal["cameras"][cam]
        assert c["solution"] == "joint"
        assert np.asarray(c["covariance"]).shape == (6, 6)
        assert np.allclose(np.asarray(c["sigma_3"]["translation_mm"]), 3 * np.asarray(c["sigma_1"]["translation_mm"]))
        dr, dt = pose_error(np.asarray(c["T_cam_sonar"]), rig.T_cam_sonar[cam])
        assert math.degrees(dr) < 0.5 and dt < 0.03  # scale 1.006 left unmodelled: a few mm of bias
        assert len(c["residuals"]) == (9 if cam == "cam1" else 10)
    ti = cal["table_i"]["pairs"]
    assert ti["cam1-sonar"]["measured_m"] == 0.8656
    assert ti["cam1-cam2"]["estimated_m"] == pytest.approx(np.linalg.norm(rig.T_cam2_cam1[:3, 3]))
    assert ti["cam2-sonar"]["error_length_m"] < 0.05
    assert any("stereo_covariance" in w for w in cal["warnings"])
    json.dumps(cal, allow_nan=False)  # strictly valid JSON


def test_scale_option_estimates_range_scale(tmp_path):
    rig = synthetic_rig(32, n_captures=24, sigma_px=0.2, sigma_m=0.002, scale=1.01)
    root = write_session(tmp_path / "s", rig)
    s = load_session(root)
    cal = calibrate_session(s, load_detections(s), {"detect": False, "estimate_scale": True, "leave_one_out": False})
    sc = cal["range_scale"]
    assert sc["estimated"] and abs(sc["value"] - 1.01) < max(4 * sc["sigma"], 0.002)
    C7 = np.asarray(cal["cameras"]["cam1"]["covariance_with_scale"])
    assert C7.shape == (7, 7) and math.sqrt(C7[6, 6]) == pytest.approx(sc["sigma"], rel=1e-6)
    for cam in ("cam1", "cam2"):
        dr, dt = pose_error(np.asarray(cal["cameras"][cam]["T_cam_sonar"]), rig.T_cam_sonar[cam])
        assert dt < 0.012


def _args(argv):
    from sonarcal_cli.commands import calibrate as cmd_calibrate

    sub = argparse.ArgumentParser().add_subparsers()
    cmd_calibrate.add_parser(sub)
    return sub._name_parser_map["calibrate"].parse_args(argv)


def test_cli_writes_json_and_report(tmp_path, rig, capsys):
    root = write_session(tmp_path / "s", rig, moved="p02")
    a = _args([str(root), "--no-detect"])
    assert a.run(a) == 0
    cal = load_calibration(root / "results" / "calibration.json")
    assert set(cal["cameras"]) == {"cam1", "cam2"}
    out = capsys.readouterr().out
    assert "Table I" in out and "p02" in out and "Assoc. length" in out


def test_cli_bad_input_overwrites_nothing(tmp_path, rig):
    root = write_session(tmp_path / "s", rig, n_only=3)
    (root / "results").mkdir()
    old = '{"format": "sonar-camera-calibration/1", "cameras": {}}\n'
    (root / "results" / "calibration.json").write_text(old)
    a = _args([str(root), "--no-detect"])
    with pytest.raises(SessionError, match="at least 4"):
        a.run(a)
    assert (root / "results" / "calibration.json").read_text() == old
    with pytest.raises(SessionError):
        calibrate_session(load_session(root), {}, {"robust": "bogus", "detect": False})
