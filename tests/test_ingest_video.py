"""``sonarcal import VIDEO --scans CSV --intrinsics FILE``: a video plus the sonar's own cloud files
(one of them a ProScan .off) -> a session; the drifting capture is flagged by name."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import yaml

from calib_core.io.clouds import load_cloud
from calib_core.io.images import list_frames, load_image
from calib_core.session import load_session, validate_session
from calib_core.synth.generate import generate_session
from sonarcal_cli.main import main

FPS = 5


def _write_off(path, cloud):
    inten = np.clip(np.nan_to_num(cloud.intensity if cloud.intensity is not None else np.zeros(len(cloud))), 0, 1)
    g = (inten * 255).astype(int)
    rows = "\n".join(f"{x:.5f} {y:.5f} {z:.5f} {v} {v} {v} 255" for (x, y, z), v in zip(cloud.points_m, g))
    path.write_text(f"OFF\n{len(cloud)} 0 0\n{rows}\n")


def test_video_with_scan_csv(tmp_path, capsys):
    folder = generate_session(tmp_path / "f", "drift", 6, scale=0.25, n_captures=4)
    gt = yaml.safe_load((folder / "ground_truth.yaml").read_text())
    drift_id = next(c for c, e in gt["captures"].items() if "drift" in e)
    s = load_session(folder)
    rng = np.random.default_rng(0)
    frames = [load_image(p) for p in list_frames(s.cameras["cam1"].background_path)] * 3  # ~1.8 s of background
    n_bg = len(frames)
    rows = ["id,start_s,end_s,cloud"]
    for cap in s.captures:
        own = sorted((folder / "frames" / "cam1").glob(f"{cap.id}_*.jpg"))
        still = load_image(cap.image_paths["cam1"])
        shots = [load_image(p) for p in own] if own else [
            still if j == 2 else np.clip(still + rng.normal(0, 1.5, still.shape), 0, 255).astype(np.uint8)
            for j in range(5)]
        start = len(frames) / FPS
        frames += shots
        cloud_rel = cap.cloud_path.relative_to(folder)
        if cap.id == s.captures[0].id:  # the sonar's own .off export for one scan
            _write_off(folder / "clouds" / "first.off", load_cloud(cap.cloud_path))
            cloud_rel = "clouds/first.off"
        rows.append(f"{cap.id},{start - 0.01:.3f},{start + 4.9 / FPS:.3f},{cloud_rel}")
        frames += [frames[0]] * 3  # target being moved between scans: not in any scan window
    video = tmp_path / "cam1.avi"
    h, w = frames[0].shape[:2]
    vw = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), FPS, (w, h))
    for f in frames:
        vw.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
    vw.release()
    (folder / "scans.csv").write_text("\n".join(rows) + "\n")
    out = tmp_path / "session"
    rc = main(["import", str(video), "--scans", str(folder / "scans.csv"), "--intrinsics",
               str(s.cameras["cam1"].intrinsics_path), "--out", str(out), "--diameter",
               str(s.sphere_diameter_m), "--background", f"0:{(n_bg - 0.5) / FPS}"])
    assert rc == 0, capsys.readouterr().err
    check = validate_session(out)
    assert check.problems == []
    b = load_session(out)
    assert [c.id for c in b.captures] == [c.id for c in s.captures]
    assert len(load_cloud(b.captures[0].cloud_path)) == len(load_cloud(s.captures[0].cloud_path))
    motion = b.raw["target_motion"]["captures"]
    assert sorted(c for c, e in motion.items() if e["moved"]) == [drift_id]
    assert all(e["cameras"]["cam1"]["found"] == 5 for e in motion.values())
    assert b.raw["source"]["kind"] == "video"


def test_video_bad_csv(tmp_path, capsys):
    video = tmp_path / "v.avi"
    video.write_bytes(b"not a video")
    csv = tmp_path / "scans.csv"
    csv.write_text("id,start,end\np01,0,1\n")
    intr = tmp_path / "cam1.yaml"
    rc = main(["import", str(video), "--scans", str(csv), "--intrinsics", str(intr), "--out", str(tmp_path / "s"),
               "--diameter", "0.2"])
    err = capsys.readouterr().err
    assert rc == 2 and "scans.csv" in err and "id,start_s,end_s,cloud" in err
    csv.write_text("id,start_s,end_s,cloud\np01,5,1,a.ply\n")
    rc = main(["import", str(video), "--scans", str(csv), "--intrinsics", str(intr), "--out", str(tmp_path / "s"),
               "--diameter", "0.2"])
    assert rc == 2 and "line 2" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


@pytest.mark.parametrize("body", [b"p01,0,1," + b"c" * 200_000 + b"\n",  # a field over csv's 128 kB limit
                                  b"p01,0,1,a.ply\n\xff\xfe\n"])  # not UTF-8
def test_video_hostile_csv_is_one_line(tmp_path, capsys, body):
    """A field over the csv module's limit was "internal error: Error: field larger than field
    limit" (exit 1); invalid UTF-8 a UnicodeDecodeError. Session 25 (sec)."""
    video = tmp_path / "v.avi"
    video.write_bytes(b"not a video")
    csv = tmp_path / "scans.csv"
    csv.write_bytes(b"id,start_s,end_s,cloud\n" + body)
    rc = main(["import", str(video), "--scans", str(csv), "--intrinsics", str(tmp_path / "cam1.yaml"),
               "--out", str(tmp_path / "s"), "--diameter", "0.2"])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert rc == 2 and len(err) == 1 and "scans.csv" in err[0] and "internal error" not in err[0], err
    assert not (tmp_path / "s").exists()
