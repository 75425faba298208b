"""Bad input through the real ``sonarcal`` entry point (a separate process): stderr holds
exactly one line, no native-library warnings, exit status 2, session unchanged."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import VENV_SONARCAL, cli_command_exists, tree_hash


CHECKOUT = Path(__file__).resolve().parents[1]


def _sonarcal(args):
    """The entry point on this checkout's code (PYTHONPATH first: in a git worktree whose .venv is
    another checkout's, the installed script would otherwise import that checkout's code)."""
    cmd = [str(VENV_SONARCAL)] if VENV_SONARCAL.exists() else [sys.executable, "-m", "sonarcal_cli.main"]
    env = dict(os.environ, COLUMNS="120", PYTHONPATH=os.pathsep.join([str(CHECKOUT), os.environ.get("PYTHONPATH", "")]))
    return subprocess.run(cmd + args, capture_output=True, text=True, timeout=180, env=env)


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


def test_points_absurdly_far_are_dropped_not_an_internal_error(make_session, tmp_path):
    """A cloud with one point at 1e308 m and one at float32's maximum (a driver's "no return"):
    detect used to overflow the sonar detector's voxel grid (numpy RuntimeWarnings on stderr,
    then "internal error: ValueError ..." and exit 1). Now they are dropped as no-return points."""
    import numpy as np

    from calib_core.io.clouds import load_cloud

    root = make_session(tmp_path, n_captures=3, cameras=("cam1",))
    pts = load_cloud(root / "clouds" / "p01.ply").points_m
    np.save(root / "clouds" / "p01.npy", np.vstack([pts, [[1e308, 0.0, 1.0]], [[3.4e38, 3.4e38, 3.4e38]]]))
    (root / "session.yaml").write_text((root / "session.yaml").read_text().replace("clouds/p01.ply", "clouds/p01.npy"))
    r = _sonarcal(["detect", str(root)])
    assert r.returncode == 0, r.stderr
    assert "internal error" not in r.stderr and "Warning" not in r.stderr and "Traceback" not in r.stderr, r.stderr
