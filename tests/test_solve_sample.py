"""``sonarcal calibrate`` end to end on the two-camera sample session (detection included): Table I."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from calib_core.geometry import pose_error
from calib_core.results import load_calibration

CANAL = Path(__file__).resolve().parents[1] / "sample_sessions" / "canal"


@pytest.mark.skipif(not (CANAL / "session.yaml").is_file(), reason="sample_sessions/canal not generated")
def test_calibrate_sample_canal_table_i(tmp_path, capsys):
    from calib_core.synth.ground_truth import load_ground_truth
    from sonarcal_cli.main import main

    root = tmp_path / "canal"
    shutil.copytree(CANAL, root, ignore=shutil.ignore_patterns("results", "detections.yaml"))
    assert main(["calibrate", str(root), "--no-loo"]) == 0
    out = capsys.readouterr().out
    assert "Table I" in out and "Incl. angle" in out
    cal = load_calibration(root / "results" / "calibration.json")
    gt = load_ground_truth(root)
    for cam in ("cam1", "cam2"):
        c = cal["cameras"][cam]
        # the sample has no moved target and no wrong detection: a capture left out is a false flag, the first
        # thing a new user would see (the sample made by an older simulator had one: cam2 p08)
        assert c["solution"] == "joint" and len(c["captures_used"]) == len(gt["captures"])
        dr, dt = pose_error(np.asarray(c["T_cam_sonar"]), np.asarray(gt["cameras"][cam]["T_cam_sonar"]))
        assert math.degrees(dr) < 0.3 and dt < 0.012
    pairs = cal["table_i"]["pairs"]
    for k in ("cam1-sonar", "cam2-sonar"):
        # the paper: 43-67 mm error length and 2.9-4.3 deg included angle
        assert pairs[k]["error_length_m"] < 0.015 and math.degrees(pairs[k]["included_angle_rad"]) < 1.0
        assert pairs[k]["measured_m"] is not None and abs(pairs[k]["error_pct"]) < 5.0
    # nothing but results/ was written
    assert not (root / "detections.yaml").exists()
