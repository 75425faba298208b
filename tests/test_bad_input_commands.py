"""Bad arguments and inputs for the commands outside the session matrix (intrinsics, stereo,
synth, serve, and option values of detect/export): exit 2, one message, nothing written."""

from __future__ import annotations

import os

import numpy as np
import pytest
from conftest import cli_command_exists, run_cli, tree_hash

from calib_core.results import save_calibration


@pytest.fixture
def setup(make_session, tmp_path):
    root = make_session(tmp_path, n_captures=2, cameras=("cam1",))
    save_calibration(root / "results" / "calibration.json",
                     {"format": "sonar-camera-calibration/1", "cameras": {"cam1": {"T_cam_sonar": np.eye(4).tolist()}}})
    (tmp_path / "cb").mkdir()
    (tmp_path / "cb" / "a.png").write_bytes(os.urandom(500))
    (tmp_path / "empty").mkdir()
    return root, tmp_path


CASES = {
    "intrinsics corrupt image": ("intrinsics", lambda r, t: ["intrinsics", f"{t}/cb", "--square", "0.025", "--out", f"{t}/o.yaml"], "a.png"),
    "intrinsics empty folder": ("intrinsics", lambda r, t: ["intrinsics", f"{t}/empty", "--square", "0.025", "--out", f"{t}/o.yaml"], "empty"),
    "intrinsics missing folder": ("intrinsics", lambda r, t: ["intrinsics", f"{t}/nope", "--square", "0.025", "--out", f"{t}/o.yaml"], "nope"),
    "intrinsics negative square": ("intrinsics", lambda r, t: ["intrinsics", f"{r}/images/cam1", "--square", "-1", "--out", f"{t}/o.yaml"], "--square"),
    "intrinsics nan square": ("intrinsics", lambda r, t: ["intrinsics", f"{r}/images/cam1", "--square", "nan", "--out", f"{t}/o.yaml"], "--square"),
    "intrinsics bad pattern": ("intrinsics", lambda r, t: ["intrinsics", f"{r}/images/cam1", "--pattern", "axb", "--square", "0.02", "--out", f"{t}/o.yaml"], "pattern"),
    "stereo empty folder": ("stereo", lambda r, t: ["stereo", f"{t}/cb", f"{t}/empty", "--square", "0.025", "--out", f"{t}/s.yaml"], "empty"),
    "synth unknown preset": ("synth", lambda r, t: ["synth", f"{t}/syn", "--preset", "nonexistent", "--seed", "1"], "nonexistent"),
    "synth over a session": ("synth", lambda r, t: ["synth", str(r), "--preset", "quick", "--seed", "1"], "not empty"),
    "serve broken session": ("serve", lambda r, t: ["serve", str(r), "--port", "0"], "session.yaml"),
    "export unknown camera": ("export", lambda r, t: ["export", str(r), "--format", "json", "--camera", "cam9"], "cam9"),
    "detect unknown capture": ("detect", lambda r, t: ["detect", str(r), "--capture", "p99"], "p99"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_command_bad_input(setup, capsys, case):
    module, argv_of, must_name = CASES[case]
    if not cli_command_exists(module):
        pytest.skip(f"sonarcal_cli/commands/{module}.py does not exist yet")
    root, tmp = setup
    if case == "serve broken session":
        (root / "session.yaml").write_text("sphere: [\n")  # never start a server in a test
    before_session, before_tmp = tree_hash(root), sorted(p.name for p in tmp.iterdir())
    rc = run_cli(argv_of(root, tmp))
    out, err = capsys.readouterr()
    assert rc == 2, (rc, out[-1000:], err[-1000:])
    assert "Traceback" not in out + err and "internal error" not in err
    first = [ln for ln in err.splitlines() if ln.startswith("error:")]
    assert len(first) == 1 and must_name in first[0], err
    assert tree_hash(root) == before_session
    assert sorted(p.name for p in tmp.iterdir()) == before_tmp, "no output file or folder created"
