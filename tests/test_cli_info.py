"""``sonarcal info SESSION``: the summary, every problem at once, exit status."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
import yaml
from conftest import VENV_SONARCAL, run_cli, tree_hash


def test_clean_session_summary_exit_0(make_session, tmp_path, capsys):
    root = make_session(tmp_path, n_captures=3, cameras=("cam1", "cam2"), background=True)
    d = yaml.safe_load((root / "session.yaml").read_text())
    d["measured"] = {"cam1-sonar": 0.8656}
    (root / "session.yaml").write_text(yaml.safe_dump(d))
    assert run_cli(["info", str(root)]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    for text in ("test-session", "220.0 mm", "1481.0 m/s", "cam1", "cam2", "64x48", "intrinsics/cam1.yaml",
                 "backgrounds/cam1", "p01", "p03", "clouds/p02.ply", "300", "cam1, cam2", "cam1-sonar 0.8656 m",
                 "no problems found"):
        assert text in out, text


def test_every_problem_listed_at_once(make_session, tmp_path, capsys):
    root = make_session(tmp_path, n_captures=4, cameras=("cam1", "cam2"))
    (root / "clouds" / "p01.ply").unlink()
    (root / "clouds" / "p02.ply").write_bytes(os.urandom(100))
    (root / "images" / "cam2" / "p03.png").write_bytes(b"")
    (root / "intrinsics" / "cam1.yaml").write_text("camera_matrix: [1, 2]\n")
    (root / "detections.yaml").write_text("captures: {p01: {sonar: {status: maybe}}}\n")
    long_name = "x" * 150
    d = yaml.safe_load((root / "session.yaml").read_text())
    d["captures"][3]["cloud"] = f"clouds/{long_name}.ply"
    (root / "session.yaml").write_text(yaml.safe_dump(d))
    before = tree_hash(root)
    assert run_cli(["info", str(root)]) == 2
    out, err = capsys.readouterr()
    errors = [ln for ln in err.splitlines() if ln.strip().startswith("error:")]
    assert "6 problem(s)" in err
    assert len(errors) == 6, err
    for name in ("p01.ply", "p02.ply", "p03.png", "cam1.yaml", "detections.yaml", long_name):
        assert sum(name in ln for ln in errors) == 1, (name, err)
    assert "status 'maybe'" in err
    # the summary still shows what could be read
    assert "cam2" in out and "64x48" in out and "p04" in out
    assert tree_hash(root) == before


def test_unusable_manifest_one_problem_no_summary(tmp_path, capsys):
    (tmp_path / "session.yaml").write_text("sphere: {diameter: -1}\ncameras: {}\n")
    assert run_cli(["info", str(tmp_path)]) == 2
    out, err = capsys.readouterr()
    assert "1 problem(s)" in err and "session.yaml" in err and "sphere.diameter" in err
    assert out == ""


@pytest.mark.parametrize("broken", [False, True])
def test_real_process(make_session, tmp_path, broken):
    """The installed entry point in a real process: exact stderr, nothing else printed there."""
    root = make_session(tmp_path, n_captures=2, cameras=("cam1",), background=True)
    if broken:
        data = (root / "images" / "cam1" / "p02.png").read_bytes()
        (root / "images" / "cam1" / "p02.png").write_bytes(data[: len(data) // 2] + b"IEND")  # decoder warns
        data = (root / "clouds" / "p01.ply").read_bytes()
        (root / "clouds" / "p01.ply").write_bytes(data[: len(data) // 2])  # open3d would warn
    cmd = [str(VENV_SONARCAL)] if VENV_SONARCAL.exists() else [sys.executable, "-m", "sonarcal_cli.main"]
    r = subprocess.run(cmd + ["info", str(root)], capture_output=True, text=True, timeout=120,
                       env=dict(os.environ, COLUMNS="100"))
    assert "Traceback" not in r.stderr
    if not broken:
        assert r.returncode == 0 and r.stderr == "" and "no problems found" in r.stdout
    else:
        assert r.returncode == 2
        lines = r.stderr.splitlines()
        assert lines[0] == "2 problem(s):", r.stderr
        assert len(lines) == 3, f"only our messages on stderr:\n{r.stderr}"
        assert "p01.ply: file is truncated" in lines[1] + lines[2]
        assert "p02.png: cannot decode image" in lines[1] + lines[2]


def test_numbers_in_summary_come_from_the_files(make_session, tmp_path, capsys):
    root = make_session(tmp_path, n_captures=2, cameras=("cam1",), n_points=123, width_px=80, height_px=60)
    from calib_core.io.clouds import Cloud, save_cloud

    save_cloud(root / "clouds" / "p02.ply", Cloud(np.random.default_rng(0).normal(size=(77, 3)) + [0, 0, 3]))
    assert run_cli(["info", str(root)]) == 0
    out = capsys.readouterr().out
    assert "80x60" in out and "123" in out and "77" in out and "62.4 / 62.4" in out
