"""Session-level detection, operator refits, correspondences and `sonarcal detect`."""

from __future__ import annotations

import numpy as np
import pytest

from calib_core.detections import load_detections
from calib_core.pipeline import SessionData, correspondences, detect_session, refit_image, refit_sonar
from calib_core.session import load_session
from calib_core.synth.generate import generate_session
from calib_core.synth.ground_truth import load_ground_truth
from sonarcal_cli.main import main


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    root = generate_session(tmp_path_factory.mktemp("pipe") / "s", "quick", seed=11, scale=0.4, pan_step_deg=1.0)
    session = load_session(root)
    dets = detect_session(SessionData(session), {})
    return session, load_ground_truth(root), dets


def test_detect_session_finds_every_sphere_near_the_truth(quick):
    session, gt, dets = quick
    for cap in session.captures:
        truth = gt["captures"][cap.id]
        son = dets[cap.id]["sonar"]
        assert son["status"] == "auto" and "center" in son, son
        assert np.linalg.norm(np.asarray(son["center"]) - truth["center_sonar_m"]) < 0.015
        for cam in cap.image_paths:
            im = dets[cap.id][cam]
            if not truth["images"][cam]["visible"]:
                continue
            assert "center" in im, im
            # scale 0.4: a pixel here is 2.5 full-resolution pixels
            assert np.linalg.norm(np.asarray(im["center"]) - truth["images"][cam]["center_uv_px"]) < 1.0


def test_operator_entries_are_never_overwritten(quick):
    session, _, dets = quick
    c0, c1 = session.captures[0].id, session.captures[1].id
    edited = {k: {s: dict(e) for s, e in v.items()} for k, v in dets.items()}
    edited[c0]["sonar"] = {"status": "rejected"}
    edited[c1]["cam1"] = {"status": "corrected", "center": [12.5, 34.25]}
    edited[c1]["sonar"]["status"] = "accepted"
    again = detect_session(SessionData(session), edited, captures=[c0, c1])
    assert again[c0]["sonar"] == {"status": "rejected"}
    assert again[c1]["cam1"] == {"status": "corrected", "center": [12.5, 34.25]}
    assert again[c1]["sonar"] == edited[c1]["sonar"]
    assert again[c0]["cam1"]["status"] == "auto"  # re-detected


def test_correspondences_skip_rejected_and_missing(quick):
    session, _, dets = quick
    c0 = session.captures[0].id
    edited = dict(dets)
    edited[c0] = dict(dets[c0], sonar={"status": "rejected"})
    corr = correspondences(session, edited, "cam1")
    assert c0 not in corr.capture_ids and corr.skipped[c0] == "sonar rejected"
    assert corr.uv_px.shape == (len(corr), 2) and corr.cov_X_m2.shape == (len(corr), 3, 3)
    assert np.all(np.linalg.eigvalsh(corr.cov_uv_px2) > 0)


def test_refit_image_near_a_click_and_fallback_to_the_click(quick):
    session, gt, _ = quick
    cap = next(c for c in session.captures if gt["captures"][c.id]["images"]["cam1"]["visible"])
    truth_uv = gt["captures"][cap.id]["images"]["cam1"]["center_uv_px"]
    entry = refit_image(session, cap.id, "cam1", truth_uv + [3.0, -2.0], hint_radius_px=20)
    assert entry["status"] == "corrected" and entry["refit"] is True
    assert np.linalg.norm(np.asarray(entry["center"]) - truth_uv) < 1.0
    # a click far from any sphere keeps the operator's pixel, with a larger uncertainty
    far = np.array([5.0, 5.0]) if np.linalg.norm(truth_uv - 5) > 100 else np.array([700.0, 400.0])
    entry = refit_image(session, cap.id, "cam1", far, hint_radius_px=20)
    assert entry["status"] == "corrected"
    if entry["refit"] is False:
        assert entry["center"] == [float(far[0]), float(far[1])] and entry["method"] == "operator-click"


def test_refit_sonar_near_a_pick(quick):
    session, gt, _ = quick
    cap = session.captures[2]
    truth = gt["captures"][cap.id]["center_sonar_m"]
    entry = refit_sonar(session, cap.id, truth + [0.05, -0.04, 0.03])
    assert entry["status"] == "corrected"
    assert np.linalg.norm(np.asarray(entry["center"]) - truth) < 0.015


def test_cli_detect_writes_detections_and_keeps_operator_entries(tmp_path, capsys):
    root = generate_session(tmp_path / "s", "quick", seed=5, scale=0.3, pan_step_deg=1.5, n_captures=4)
    session = load_session(root)
    assert main(["detect", str(root)]) == 0
    dets = load_detections(session)
    assert set(dets) == {c.id for c in session.captures}
    cid = session.captures[0].id
    text = (root / "detections.yaml").read_text()
    (root / "detections.yaml").write_text(text.replace("status: auto", "status: accepted", 1))
    accepted = load_detections(session)[cid]["sonar"]
    assert accepted["status"] == "accepted"
    assert main(["detect", str(root)]) == 0
    assert load_detections(session)[cid]["sonar"] == accepted
    assert main(["detect", str(root), "--capture", "nope"]) == 2
    assert "no capture nope" in capsys.readouterr().err


def test_refits_after_a_reload_use_the_beam_width_of_the_first_detection(quick):
    session, _, dets = quick
    widths = {e["beam_width_deg"] for d in dets.values() for s, e in d.items() if s == "sonar"}
    assert len(widths) == 1
    data = SessionData(session)
    data.adopt_beam_width(dets)
    assert data.effective_beam_width_deg == widths.pop()
    assert SessionData(session).effective_beam_width_deg == session.beam_width_deg


def test_stated_sonar_covariance_matches_the_true_errors(quick):
    session, gt, dets = quick
    m2 = []
    for cap in session.captures:
        e = dets[cap.id]["sonar"]
        err = np.asarray(e["center"]) - gt["captures"][cap.id]["center_sonar_m"]
        m2.append(err @ np.linalg.solve(np.asarray(e["cov_m2"]).reshape(3, 3), err) / 3)
    # ~1 when honest; the fit's range-noise covariance alone gave ~7 (errors ~2.7x the stated sigma)
    assert 0.15 < np.mean(m2) < 2.5, np.mean(m2)


def test_detection_stops_when_its_progress_callback_cancels(quick):
    """The workbench stops a running detection (Ctrl+C on `serve`) by raising Cancelled from the
    progress callback: it reaches the caller through the process pool (whose queued captures are dropped)."""
    from calib_core.errors import Cancelled
    from calib_core.parallel import run_detections

    session, _truth, _dets = quick
    todo = [(c.id, s) for c in session.captures for s in ("sonar", *c.image_paths)]
    calls = []

    def progress(done, total, label):
        calls.append(done)
        if done >= 1:
            raise Cancelled("stop")

    with pytest.raises(Cancelled):
        run_detections(SessionData(session), todo, progress, workers=2)
    assert max(calls) < len(todo)


def test_a_cancelled_job_ends_quietly_and_no_new_job_starts():
    import threading

    from app.common import JobRunner

    errors, started = [], threading.Event()

    def job(progress):
        started.set()
        for i in range(10_000):
            progress(i, 10_000, "step")
            threading.Event().wait(0.01)

    runner = JobRunner(on_progress=lambda *a: None, on_error=lambda name, e: errors.append(e))
    runner.start("detection", job)
    assert started.wait(10)
    runner.cancel(30)
    assert runner.running is None and errors == []
    runner.start("detection", job)  # refused once shutting down
    assert runner.running is None


def _without_timing(dets: dict) -> dict:
    drop = {"detected_at", "time_ms", "region_ms"}
    return {cid: {s: {k: v for k, v in e.items() if k not in drop} for s, e in d.items()} for cid, d in dets.items()}


def test_process_pool_gives_the_in_process_detections(quick):
    """Two worker processes (crops, beam-width scan and sonar in priority order; background
    models shared through files) return exactly what one process returns."""
    session, _gt, dets = quick
    assert any(spec.background_path for spec in session.cameras.values())
    pooled = detect_session(SessionData(session), {}, workers=2)
    single = detect_session(SessionData(session), {}, workers=1)
    assert _without_timing(pooled) == _without_timing(single) == _without_timing(dets)
