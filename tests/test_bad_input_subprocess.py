"""Bad input through the real ``sonarcal`` entry point (a separate process): stderr holds
exactly one line, no native-library warnings, exit status 2, session unchanged."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from conftest import VENV_SONARCAL, cli_command_exists, tree_hash


def _sonarcal(args):
    cmd = [str(VENV_SONARCAL)] if VENV_SONARCAL.exists() else [sys.executable, "-m", "sonarcal_cli.main"]
    return subprocess.run(cmd + args, capture_output=True, text=True, timeout=180, env=dict(os.environ, COLUMNS="120"))


@pytest.mark.parametrize("command", ["detect"])
def test_truncated_png_one_line_on_stderr(make_session, tmp_path, command):
    if not cli_command_exists(command):
        pytest.skip(f"sonarcal_cli/commands/{command}.py does not exist yet")
    root = make_session(tmp_path, n_captures=3, cameras=("cam1",))
    p = root / "images" / "cam1" / "p02.png"
    data = p.read_bytes()
    p.write_bytes(data[: len(data) // 2] + b"IEND")  # OpenCV's decoder would log a warning
    before = tree_hash(root)
    r = _sonarcal([command, str(root)])
    assert r.returncode == 2, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "p02.png" in lines[0], r.stderr
    assert tree_hash(root) == before


def test_symlink_out_of_session_refused_in_real_process(make_session, tmp_path):
    root = make_session(tmp_path, n_captures=2, cameras=("cam1",))
    secret = tmp_path / "secret.yaml"
    secret.write_text((root / "intrinsics" / "cam1.yaml").read_text())
    (root / "intrinsics" / "cam1.yaml").unlink()
    os.symlink(secret, root / "intrinsics" / "cam1.yaml")
    before = tree_hash(root)
    r = _sonarcal(["info", str(root)])
    assert r.returncode == 2
    assert "session.yaml: cameras.cam1.intrinsics: path 'intrinsics/cam1.yaml' leaves the session folder" in r.stderr
    assert "Traceback" not in r.stderr
    assert tree_hash(root) == before
