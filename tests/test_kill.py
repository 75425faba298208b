"""No data loss: SIGKILL a process writing detections.yaml and results/calibration.json
at random moments; each file must always be a complete old or new version that parses.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np

from calib_core.detections import load_detections
from calib_core.results import calibration_path, load_calibration
from calib_core.session import load_session, validate_session

N_KILLS = 30

# Content for sequence number ``seq``: shared by the writer and the checks (exec'd in both).
CONTENT = r"""
import random


def detections_content(seq):
    rnd = random.Random(seq)
    return {
        "p01": {"sonar": {"center": [float(seq), 0.5, 2.0], "status": "auto", "seq": seq,
                          "samples": [round(rnd.gauss(0, 1), 6) for _ in range(500)]}},
        "p02": {"cam1": {"center": [float(seq), 12.0], "status": "accepted", "seq": seq}},
    }


def calibration_content(seq):
    rnd = random.Random(10_000 + seq)
    T = [[1.0, 0.0, 0.0, float(seq)], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
    return {"format": "sonar-camera-calibration/1", "session": "kill", "seq": seq,
            "cameras": {"cam1": {"T_cam_sonar": T, "residuals": [rnd.gauss(0, 1) for _ in range(4000)]}}}
"""

# The writer: light imports (no OpenCV) so it starts fast; continues the sequence found on
# disk and writes new content through the real writers until it is killed. It says
# "writing" after its first cycle, so that kills land anywhere in the write loop.
WRITER = CONTENT + r"""
import sys
from pathlib import Path
from types import SimpleNamespace

import yaml

from calib_core.detections import save_detections
from calib_core.results import save_calibration

root = Path(sys.argv[1])
session = SimpleNamespace(root=root, captures=[SimpleNamespace(id="p01"), SimpleNamespace(id="p02")])
try:
    seq = int(yaml.safe_load((root / "detections.yaml").read_text())["captures"]["p01"]["sonar"]["seq"])
except FileNotFoundError:
    seq = 0
while True:
    seq += 1
    save_detections(session, detections_content(seq))
    save_calibration(root / "results" / "calibration.json", calibration_content(seq))
    if not sys.stdout.closed:
        print("writing", flush=True)  # after the first cycle: the test kills from now on
        sys.stdout.close()
"""
_ns: dict = {}
exec(CONTENT, _ns)
detections_content, calibration_content = _ns["detections_content"], _ns["calibration_content"]


def test_sigkill_at_random_moments_never_leaves_a_broken_file(make_session, tmp_path):
    root = make_session(tmp_path, n_captures=2, cameras=("cam1",))
    session = load_session(root)
    rng = np.random.default_rng(1234)
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    last_det, last_cal, changed = 0, 0, 0
    for _ in range(N_KILLS):
        proc = subprocess.Popen([sys.executable, "-c", WRITER, str(root)], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, env=env)
        try:
            line = proc.stdout.readline()
            assert line.strip() == b"writing", proc.stderr.read().decode()[-2000:]
            time.sleep(rng.uniform(0.0, 0.12))
        finally:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait()
        assert proc.returncode == -signal.SIGKILL
        dets = load_detections(session)  # raises on a partial / unparsable file
        if dets:
            seq = dets["p01"]["sonar"]["seq"]
            assert dets == _as_loaded(detections_content(seq)), "a complete version, not a mix"
            assert seq >= last_det
            changed += seq != last_det
            last_det = seq
        cal_path = calibration_path(session)
        if cal_path.exists():
            cal = load_calibration(cal_path)
            assert cal == calibration_content(cal["seq"])
            assert cal["seq"] >= last_cal
            last_cal = cal["seq"]
    assert changed == N_KILLS, "each writer wrote at least once before it was killed"
    # leftovers of killed writers are hidden temp files that no loader picks up
    temps = [p for p in root.rglob("*") if p.name.endswith(".tmp")]
    assert all(p.name.startswith(".") for p in temps)
    check = validate_session(root)
    assert check.problems == []
    print(f"{len(temps)} of {N_KILLS} kills landed inside a write (temp file left behind)")


def _as_loaded(dets: dict) -> dict:
    """What load_detections returns for a saved dict (centres as floats)."""
    out = {}
    for cid, sensors in dets.items():
        out[cid] = {s: dict(e, center=[float(v) for v in e["center"]]) for s, e in sensors.items()}
    return out
