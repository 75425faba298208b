"""``sonarcal plan`` and the session-level planner on a small two-camera session with accepted detections."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from conftest import _T_cam_sonar, build_session, run_cli, tiny_camera, tree_hash


def planning_session(root, n_captures: int = 7, cameras=("cam1", "cam2"), seed: int = 0):
    """build_session plus a detections.yaml with accepted, slightly noisy centres for every capture."""
    sess = build_session(root, n_captures=n_captures, cameras=cameras)
    rng = np.random.default_rng(seed)
    caps = {}
    for i in range(n_captures):
        X = np.array([0.4 * (i % 3 - 1), 0.1 * (i % 2), 1.6 + 0.2 * i])
        entry = {"sonar": {"center": (X + rng.normal(0, 0.002, 3)).tolist(), "status": "accepted",
                           "cov_m2": (np.eye(3) * 0.002**2).tolist()}}
        for j, cam in enumerate(cameras):
            T = _T_cam_sonar(j)
            uv = tiny_camera(cam).project((T[:3, :3] @ X + T[:3, 3])[None])[0] + rng.normal(0, 0.05, 2)
            entry[cam] = {"center": uv.tolist(), "status": "accepted", "cov_px2": (np.eye(2) * 0.05**2).tolist()}
        caps[f"p{i + 1:02d}"] = entry
    (sess / "detections.yaml").write_text(yaml.safe_dump({"format": "sonar-camera-detections/1", "captures": caps}))
    return sess


def test_plan_session_suggests_visible_positions_that_help(tmp_path):
    from calib_core.detections import load_detections
    from calib_core.plan.coverage import coverage
    from calib_core.plan.session_plan import plan_session
    from calib_core.session import load_session

    s = load_session(planning_session(tmp_path))
    sp = plan_session(s, load_detections(s), count=3)
    assert sp.cameras == ["cam1", "cam2"] and len(sp.taken_sonar_m) == 7
    assert sp.field.R_field_sonar[0].tolist() == [0, 0, 1]  # this sonar writes z forward: found from the clouds
    plan = sp.plan
    assert len(plan.suggestions) == 3 and plan.met == (plan.ratio_now <= 1)
    ratios = [plan.ratio_now] + [x.ratio_after for x in plan.suggestions]
    assert all(b <= a + 1e-12 for a, b in zip(ratios, ratios[1:])) and ratios[-1] < ratios[0]
    for sug in plan.suggestions:
        assert sug.uv_px, "each suggestion is seen by at least one camera"
        for cam, uv in sug.uv_px.items():
            assert 0 <= uv[0] < 64 and 0 <= uv[1] < 48
        assert np.linalg.norm(sp.taken_sonar_m - sug.X_sonar_m, axis=1).min() >= sp.limits.min_separation_m - 1e-9
    pics = coverage(sp, {c: s.camera_model(c) for c in sp.cameras})
    assert set(pics) == {"cam1", "cam2", "depth", "fan"}
    for img, num in pics.values():
        assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3 and num >= 0
    r = [np.linalg.norm([0.4 * (i % 3 - 1), 0.1 * (i % 2), 1.6 + 0.2 * i]) for i in range(7)]
    assert 0 < pics["cam1"][1] <= 1 and pics["depth"][1] == pytest.approx(max(r) - min(r), abs=0.02)


def test_cli_prints_suggestions_in_the_sonar_frame_and_pixels(tmp_path, capsys):
    sess = planning_session(tmp_path)
    before = tree_hash(sess)
    assert run_cli(["plan", str(sess), "--count", "2", "--target", "0.01deg,0.1mm"]) == 0
    out = capsys.readouterr().out
    assert "not yet" in out and "worst axis" in out and "sonar x, y, z (m)" in out and "cam1 u, v (px)" in out and "cam2 u, v (px)" in out
    assert out.count("(r ") >= 2
    assert tree_hash(sess) == before  # plan writes nothing
    assert run_cli(["plan", str(sess), "--target", "1000deg,1000mm", "--criterion", "d", "--range", "1,3"]) == 0
    out = capsys.readouterr().out
    assert "enough" in out and "D-optimal" in out and "working range 1-3 m" in out


@pytest.mark.parametrize("args,words", [
    (["--target", "fast"], "--target"),
    (["--count", "0"], "--count"),
    (["--range", "4,1"], "--range"),
    (["--range", "x"], "--range"),
])
def test_cli_bad_options_one_line_exit_2(tmp_path, capsys, args, words):
    sess = planning_session(tmp_path)
    assert run_cli(["plan", str(sess), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err and "Traceback" not in err


def test_cli_too_few_captures_or_no_session(tmp_path, capsys):
    sess = planning_session(tmp_path, n_captures=2, cameras=("cam1",))
    assert run_cli(["plan", str(sess)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "detections.yaml" in err and "at least 4" in err
    assert run_cli(["plan", str(tmp_path / "nowhere")]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_sonar_field_from_session_yaml_and_bad_values(tmp_path, capsys):
    sess = planning_session(tmp_path)
    man = yaml.safe_load((sess / "session.yaml").read_text())
    # this test sonar writes z forward, so a declared x-forward field sees none of it: nothing to suggest
    man["sonar"]["field"] = {"azimuth_deg": [-30, 30], "elevation_deg": [-20, 20], "range_m": [0.5, 6]}
    (sess / "session.yaml").write_text(yaml.safe_dump(man))
    assert run_cli(["plan", str(sess)]) == 0
    out = capsys.readouterr().out
    assert "session.yaml sonar.field" in out and "0 candidate positions" in out and "no position" in out
    man["sonar"]["field"] = {"azimuth_deg": [30, -30], "elevation_deg": [-20, 20], "range_m": [0.5, 6]}
    (sess / "session.yaml").write_text(yaml.safe_dump(man))
    assert run_cli(["plan", str(sess)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "session.yaml" in err and "sonar.field" in err and "azimuth_deg" in err


def test_broken_cloud_one_line_in_a_real_process(tmp_path):
    import os
    import subprocess
    import sys

    from conftest import VENV_SONARCAL

    sess = planning_session(tmp_path)
    (sess / "clouds" / "p01.ply").write_bytes(b"ply\nformat ascii 1.0\nelement vertex 5\nend_header\n1 2\n")
    before = tree_hash(sess)
    cmd = [str(VENV_SONARCAL)] if VENV_SONARCAL.exists() else [sys.executable, "-m", "sonarcal_cli.main"]
    r = subprocess.run(cmd + ["plan", str(sess)], capture_output=True, text=True, timeout=180,
                       env=dict(os.environ, COLUMNS="120"))
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1 and "p01.ply" in lines[0] and "Traceback" not in r.stderr, r.stderr
    assert tree_hash(sess) == before
