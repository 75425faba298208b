"""calib_core.diagnose: the three causes are told apart and worded differently, before any Solve."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import yaml

from calib_core.diagnose import MIN_CAPTURES, diagnose_session, wording
from calib_core.diagnose.outline import find_outline
from calib_core.detections import save_detections
from calib_core.pipeline import SessionData, detect_session
from calib_core.session import load_session


@pytest.fixture(scope="module")
def review(tmp_path_factory):
    from conftest import review_session_with_decoy_taken

    from calib_core.synth.generate import generate_session

    root = generate_session(tmp_path_factory.mktemp("diag") / "review", "review", 11, scale=0.25,
                            pan_step_deg=1.0, sub_rays=7)
    return review_session_with_decoy_taken(root)


def _truth(gt):
    moved = [c for c, v in gt["captures"].items() if v.get("moved_m", 0) > 0.05]
    hidden = [c for c, v in gt["captures"].items() if v["images"]["cam1"].get("occluded_fraction", 0) > 0.3]
    return moved, hidden


def test_decoy_and_moved_are_told_apart(review):
    data, dets, gt = review
    moved, hidden = _truth(gt)
    assert len(moved) == 1 and len(hidden) == 1 and moved != hidden
    flags = {f.capture: f for f in diagnose_session(data, dets)}
    assert set(flags) == {moved[0], hidden[0]}
    img, mv = flags[hidden[0]], flags[moved[0]]
    assert (img.cause, img.sensor) == ("image", "cam1") and (mv.cause, mv.sensor) == ("moved", "capture")
    true_uv = gt["captures"][hidden[0]]["images"]["cam1"]["center_uv_px"]
    r_px = data.camera("cam1").fx * data.session.sphere_radius_m / 1.0
    assert np.linalg.norm(np.subtract(img.predicted_uv_px, true_uv)) < 0.2 * r_px  # the ring marks the true sphere
    assert img.text != mv.text and "image detection is wrong" in img.text and "moved" in mv.text


def test_a_wrong_sonar_centre_is_blamed_on_the_sonar(review):
    data, dets, gt = review
    moved, hidden = _truth(gt)
    cid = next(c for c in gt["captures"] if c not in moved + hidden)
    bad = copy.deepcopy(dets)
    bad[moved[0]]["sonar"]["status"] = "rejected"  # two bad captures of seven, not three of eight
    c = bad[cid]["sonar"]["center"]
    bad[cid]["sonar"]["center"] = [c[0] + 0.5, c[1] - 0.3, c[2]]
    f = {f.capture: f for f in diagnose_session(data, bad)}[cid]
    assert (f.cause, f.sensor) == ("sonar", "sonar")
    assert np.linalg.norm(np.subtract(f.predicted_sonar_m, c)) < 0.1  # points back at the true centre
    assert f.text.startswith(f"{cid} sonar: the sonar detection is wrong")


def test_no_flags_without_enough_pairs_and_none_on_clean_data(review):
    data, dets, gt = review
    moved, hidden = _truth(gt)
    few = {c: dets[c] for c in list(dets)[:MIN_CAPTURES - 1]}
    assert diagnose_session(data, few) == []
    clean = {c: e for c, e in dets.items() if c not in moved + hidden}
    assert diagnose_session(data, clean) == []


def test_outline_support_half_hidden_vs_empty():
    img = np.full((120, 160, 3), 200, np.uint8)
    import cv2

    cv2.circle(img, (80, 60), 20, (40, 40, 40), -1)
    img[:, 80:] = 60  # a panel hides the right half (its edge runs through the centre)
    assert find_outline(img, (80, 60), 20).found
    assert not find_outline(img, (30, 30), 12).found
    blank = np.full((120, 160, 3), 200, np.uint8)
    assert not find_outline(blank, (80, 60), 20).found


def test_verdicts_follow_the_stated_thresholds():
    assert wording.verdict(0.97, 0.5, False) == "good"
    assert wording.verdict(0.97, 3.0, False) == "doubtful"
    assert wording.verdict(0.6, None, False) == "doubtful"
    assert wording.verdict(0.75, None, False) == "good"
    assert wording.verdict(0.97, 0.5, True) == "bad"
    assert wording.verdict(0.3, None, False) == "bad"
    assert wording.verdict(None, 6.0, False) == "bad"
    assert "2 px" in wording.THRESHOLDS_NOTE and "0.7" in wording.THRESHOLDS_NOTE


def test_cli_detect_prints_the_same_flags(review, capsys):
    from conftest import run_cli

    data, dets, gt = review
    assert run_cli(["detect", str(data.session.root), "--missing-only"]) == 0
    err = capsys.readouterr().err
    texts = [f.text for f in diagnose_session(data, dets)]
    assert len(texts) == 2 and all(f"flag: {t}" in err.replace("\n", " ") or t[:60] in err for t in texts)


def test_a_wrong_image_centre_with_the_sphere_in_plain_view_is_found_by_the_detector(review):
    data, dets, gt = review
    moved, hidden = _truth(gt)
    cid = [c for c in gt["captures"] if c not in moved + hidden][1]
    bad = copy.deepcopy(dets)
    u, v = bad[cid]["cam1"]["center"]
    bad[cid]["cam1"]["center"] = [u + 90.0 if u < 240 else u - 90.0, v]
    f = {f.capture: f for f in diagnose_session(data, bad)}[cid]
    assert (f.cause, f.sensor) == ("image", "cam1")
    assert f.suggestion.get("method") != "outline"  # the detector itself found the sphere there
    assert np.linalg.norm(np.subtract(f.suggestion["center"], [u, v])) < 1.0
