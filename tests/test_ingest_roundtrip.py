"""synth -> ROS 2 (MCAP) / ROS 1 bag -> sonarcal import -> calibrate: same data, same accuracy,
the drifting capture flagged by name and no still one."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from calib_core.detections import load_detections
from calib_core.geometry import pose_error
from calib_core.io.clouds import load_cloud
from calib_core.io.images import load_image
from calib_core.session import load_session, validate_session
from calib_core.solve.calibrate import calibrate_session
from calib_core.synth.bag import write_session_bag
from calib_core.synth.generate import generate_session
from sonarcal_cli.main import main

SEED = 4


@pytest.fixture(scope="module")
def synth(tmp_path_factory):
    root = tmp_path_factory.mktemp("rt")
    folder = generate_session(root / "folder", "drift", SEED, scale=0.25)
    gt = yaml.safe_load((folder / "ground_truth.yaml").read_text())
    drift_id = next(c for c, e in gt["captures"].items() if "drift" in e)
    return root, folder, gt, drift_id


@pytest.fixture(scope="module", params=["ros2", "ros1"])
def imported(request, synth):
    root, folder, gt, drift_id = synth
    kind = request.param
    bag = write_session_bag(folder, root / ("bag.bag" if kind == "ros1" else "bag_ros2"), kind, seed=SEED)
    out = root / f"imported_{kind}"
    rc = main(["import", str(bag), "--out", str(out), "--diameter", str(load_session(folder).sphere_diameter_m),
               "--background", "0:2"])
    assert rc == 0
    return out


def _calibrate(folder: Path) -> dict:
    s = load_session(folder)
    return calibrate_session(s, load_detections(s), {"leave_one_out": False})


def test_imported_session_is_valid_and_holds_the_same_data(synth, imported):
    _, folder, _, drift_id = synth
    check = validate_session(imported)
    assert check.session is not None and check.problems == []
    a, b = load_session(folder), load_session(imported)
    assert [c.id for c in a.captures] == [c.id for c in b.captures]
    for ca, cb in zip(a.captures, b.captures):
        pa, pb = load_cloud(ca.cloud_path), load_cloud(cb.cloud_path)
        assert len(pa) == len(pb)
        # same points (the bag slices a scan by pan angle: compare as sorted sets)
        np.testing.assert_allclose(np.sort(pa.points_m, axis=0), np.sort(pb.points_m, axis=0), atol=1e-6)
        # the kept frame is the one recorded mid-scan: the still (the drifting capture's too)
        np.testing.assert_array_equal(load_image(ca.image_paths["cam1"]), load_image(cb.image_paths["cam1"]))
    ka, kb = a.camera_model("cam1"), b.camera_model("cam1")
    np.testing.assert_allclose(ka.K, kb.K)
    np.testing.assert_allclose(ka.dist, kb.dist)
    src = b.raw["source"]
    assert src["sonar_topic"] == "/sonar/points" and src["cameras"]["cam1"]["image_topic"] == "/cam1/image_raw"
    n_bg = len(list(Path(a.cameras["cam1"].background_path).iterdir()))
    assert len(list(Path(b.cameras["cam1"].background_path).iterdir())) == n_bg


def test_drifting_capture_flagged_and_no_still_one(synth, imported):
    _, _, gt, drift_id = synth
    motion = load_session(imported).raw["target_motion"]
    moved = sorted(c for c, e in motion["captures"].items() if e["moved"])
    assert moved == [drift_id]
    ent = motion["captures"][drift_id]["cameras"]["cam1"]
    # the sphere drifts 8 cm in a horizontal line centred on the kept frame: 4 cm each side at most
    assert 0.015 < ent["motion_m"] <= 0.045
    assert ent["found"] == ent["frames"] == 5
    still = [e["cameras"]["cam1"] for c, e in motion["captures"].items() if c != drift_id]
    assert max(m["motion_px"] for m in still) < 0.5
    truth_uv = gt["captures"][drift_id]["drift"]["frames"]["cam1"]["center_uv_px"]
    np.testing.assert_allclose(np.array(ent["uv_px"]), np.array(truth_uv), atol=1.0)


def test_bag_calibrates_like_the_folder(synth, imported):
    _, folder, gt, _ = synth
    T_true = np.asarray(gt["cameras"]["cam1"]["T_cam_sonar"])
    errs = []
    for f in (folder, imported):
        cal = _calibrate(f)
        errs.append(pose_error(np.asarray(cal["cameras"]["cam1"]["T_cam_sonar"]), T_true))
    (r0, t0), (r1, t1) = errs
    assert t1 <= 1.1 * t0 + 1e-4 and r1 <= 1.1 * r0 + 1e-5


def test_report_section_names_the_drifting_capture(synth, imported):
    from calib_core.report.motion import motion_section

    _, _, _, drift_id = synth
    html = motion_section(load_session(imported))
    assert "Target moved during scan: " + drift_id in html
    assert html.count("<tr class='bad'>") == 1
    assert motion_section(load_session(synth[1])) == ""  # a folder session without a track: no section


def test_workbench_shows_the_track(synth, imported):
    from app.panels.motion import motion_markdown
    from app.server import Workbench

    _, folder, _, drift_id = synth
    assert f"moved in {drift_id}" in motion_markdown(load_session(imported))
    assert "no track" in motion_markdown(load_session(folder))
    wb = Workbench(imported, port=0)
    try:
        wb.wait_idle(60)
        assert f"moved in {drift_id}" in wb.motion_panel.md.content
        assert wb.motion_panel.md.content.count("MOVED") == 1
    finally:
        wb.stop()


def test_median_of_frames_and_drop_moved(synth, tmp_path):
    """--median 5: a still capture gets the median of its 5 frames (the still and 4 noisy copies:
    within 1 DN of the still); --drop-moved leaves the drifting capture out, saying why."""
    root, folder, _, drift_id = synth
    bag = root / "bag_ros2"
    if not bag.exists():
        write_session_bag(folder, bag, "ros2", seed=SEED)
    out = tmp_path / "median"
    assert main(["import", str(bag), "--out", str(out), "--diameter", str(load_session(folder).sphere_diameter_m),
                 "--background", "0:2", "--median", "5", "--drop-moved"]) == 0
    a, b = load_session(folder), load_session(out)
    assert [c.id for c in b.captures] == [c.id for c in a.captures if c.id != drift_id]
    assert b.raw["source"]["captures"][drift_id]["skipped"] == "target moved during the scan"
    motion = b.raw["target_motion"]["captures"]
    assert motion[drift_id]["moved"] and motion[drift_id]["cameras"]["cam1"]["image"] == "mid-scan frame"
    for cb in b.captures:
        ca = a.capture(cb.id)
        assert motion[cb.id]["cameras"]["cam1"]["image"] == "median of 5 frames"
        diff = np.abs(load_image(ca.image_paths["cam1"]).astype(int) - load_image(cb.image_paths["cam1"]).astype(int))
        assert 0 < diff.mean() < 1.0 and diff.max() <= 6
