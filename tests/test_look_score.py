"""The look at the sonar-predicted place and size (issue 11, score round 2): what it records.

- It has no probability, so it writes no ``score``: the share of the outline it saw goes under
  its own key and shows as "outline seen NN %" (one phrase, built in calib_core.detect.reasons).
- Its size is pulled towards the prediction by a prior, so its range must not feed the
  one-camera apparent-size scale (pipeline.correspondences leaves it out).
"""

from __future__ import annotations

from types import SimpleNamespace

import cv2
import numpy as np

from calib_core.camera import CameraModel
from calib_core.detect.image.predicted import PRIOR_REL_SIGMA, detect_at_prediction
from calib_core.detect.reasons import (OUTLINE_SEEN_KEY, RANGE_PRIOR_KEY, entry_score, range_is_measured, score_phrase,
                                       score_text)
from calib_core.pipeline import correspondences

RADIUS_M = 0.3


def _half_hidden_ball():
    """A grey ball whose upper half sits before a backrest of nearly its shade (drawn, 4x supersampled)."""
    cam = CameraModel(960, 600, np.array([[700.0, 0, 480], [0, 700.0, 300], [0, 0, 1]]))
    C = np.array([0.4, 0.1, 3.0])
    uv = cam.project(C[None])[0]
    r = cam.fx * np.tan(np.arcsin(RADIUS_M / np.linalg.norm(C)))
    img = np.full((600, 960, 3), 150.0, np.float32)
    img[: int(uv[1] + 0.1 * r), int(uv[0] - 1.3 * r):int(uv[0] + 1.3 * r)] = 112.0
    ss = 4
    mask = np.zeros((600 * ss, 960 * ss), np.uint8)
    cv2.circle(mask, (int(round((uv[0] + 0.5) * ss - 0.5)), int(round((uv[1] + 0.5) * ss - 0.5))), int(r * ss), 255, -1)
    alpha = cv2.resize(mask.astype(np.float32) / 255.0, (960, 600), interpolation=cv2.INTER_AREA)[..., None]
    img = img * (1 - alpha) + 110.0 * alpha
    rng = np.random.default_rng(1)
    img = np.clip(cv2.GaussianBlur(img, (0, 0), 0.8) + rng.normal(0, 2.0, img.shape), 0, 255).astype(np.uint8)
    return cam, img, uv, r


def test_a_found_look_has_no_probability_but_says_how_much_outline_it_saw():
    cam, img, uv, r = _half_hidden_ball()
    det = detect_at_prediction(img, cam, RADIUS_M, uv + np.array([2.0, -1.5]), 1.01 * r, shift_frac=0.1)
    assert det.found, det.reason
    entry = det.to_entry()
    assert det.score is None and "score" not in entry
    seen = entry[OUTLINE_SEEN_KEY]
    assert 0.3 < seen <= entry["support"] < 0.9  # about half of the outline, discounted by its spread
    assert entry[RANGE_PRIOR_KEY] == PRIOR_REL_SIGMA and not range_is_measured(entry)
    assert score_text(entry) == f"outline seen {100 * seen:.0f} %" == score_phrase(entry)


def test_score_words_built_once():
    assert score_text({"score": 0.934}) == "0.93" and score_phrase({"score": 0.934}) == "score 0.93"
    assert score_text({"outline_seen": 0.62}) == "outline seen 62 %"
    assert score_text({"status": "corrected", "center": [1, 2]}) == "" == score_phrase({})
    assert entry_score({"outline_seen": 0.9}) is None and entry_score({"score": 1}) == 1.0


def test_review_cell_shows_a_look_as_outline_seen_not_as_a_score():
    from app.panels.review import DOTS, cell

    c = cell({"status": "auto", "score": None, "score_text": "outline seen 62 %", "residual_px": 0.5, "found": True,
              "flag": None})
    assert "outline\u00a0seen\u00a062\u00a0%" in c and c.startswith(DOTS["good"])  # judged by its residual alone


def test_apparent_size_scale_leaves_out_ranges_pulled_to_the_prediction():
    caps = [SimpleNamespace(id=f"c{i}", image_paths={"cam1": "x.png"}) for i in range(3)]
    session = SimpleNamespace(cameras={"cam1": None}, captures=caps, manifest_path="session.yaml")
    son = {"status": "auto", "center": [0.0, 0.0, 2.0]}
    free = {"status": "auto", "center": [1.0, 2.0], "range_m": 2.04, "range_sigma_m": 0.01, "score": 0.9}
    look = {"status": "auto", "center": [1.0, 2.0], "range_m": 2.0, "range_sigma_m": 0.01, OUTLINE_SEEN_KEY: 0.6,
            RANGE_PRIOR_KEY: PRIOR_REL_SIGMA}
    click = {"status": "corrected", "center": [1.0, 2.0]}
    dets = {"c0": {"sonar": son, "cam1": free}, "c1": {"sonar": son, "cam1": look}, "c2": {"sonar": son, "cam1": click}}
    corr = correspondences(session, dets, "cam1")
    assert corr.capture_ids == ["c0", "c1", "c2"]  # the look's centre is used ...
    assert corr.range_m[0] == 2.04 and corr.range_sigma_m[0] == 0.01
    assert np.isnan(corr.range_m[1:]).all() and np.isnan(corr.range_sigma_m[1:]).all()  # ... its range is not


def test_one_camera_scale_uses_the_rows_that_have_a_range():
    """Looks (and clicks) have no range: the scale comes from the other rows, not held at 1."""
    from calib_core.geometry import transform_points
    from calib_core.solve.model import camera_data
    from calib_core.solve.outline import RangeModel
    from calib_core.solve.simulate import synthetic_rig
    from calib_core.solve.simulate_ranges import image_ranges
    from calib_core.solve.single import solve_camera

    rig = synthetic_rig(73, n_captures=15, scale=1.02, depth_m=(0.8, 3.0))
    P = transform_points(rig.T_cam_sonar["cam1"], rig.X_true_sonar_m)
    rng_m, sig_m = image_ranges(rig.cameras["cam1"], P, 0.11, 0.0, 1.0, 0.003, np.random.default_rng(2))
    rng_m[[1, 5, 9, 12]] = np.nan  # four rows from looks: range left out
    sig_m[[1, 5, 9, 12]] = np.nan
    cd = camera_data("cam1", rig.cameras["cam1"], rig.capture_ids, rig.uv_px["cam1"], rig.cov_uv_px2["cam1"],
                     rig.X_sonar_m, rig.cov_X_m2, rng_m, sig_m)
    sol = solve_camera(cd, loo=False, estimate_scale=True, range_model=RangeModel(0.001 / 0.22, 0.11, 1.0))
    assert sol.scale_observable and sol.scale_sigma is not None
    assert abs(sol.scale - 1.02) < 3 * sol.scale_sigma and abs(sol.scale - 1.0) > 3 * sol.scale_sigma


def test_the_clear_refit_decision_does_not_move_with_the_calibration(monkeypatch):
    """pipeline keeps a free refit over the look at the logistic's even odds, whatever the score's
    calibration (score round 2 changed it; the decision must not change silently)."""
    from calib_core import pipeline
    from calib_core.detect.image import score as image_score

    base = {"center": [1.0, 2.0], "radius_px": 60.0, "outline_coverage": 0.8, "edge_rms_px": 0.5,
            "outside_mismatch": 0.1, "edge_contrast": 12.0, "runner_up_ratio": 0.0}
    entries = [dict(base, outline_coverage=c, edge_rms_px=r) for c in (0.5, 0.7, 0.9) for r in (0.3, 0.6, 0.9)]
    a, b = image_score.PLATT  # the first round's rule: score (Platt line) >= CLEAR_SCORE
    old = [1 / (1 + np.exp(-(a * image_score.entry_logit(e) + b))) >= pipeline.CLEAR_SCORE for e in entries]
    assert any(old) and not all(old)
    assert [pipeline._clear_refit(e) for e in entries] == old
    monkeypatch.setattr(image_score, "CALIBRATION", (5.0, 0.1, 0.0))
    assert [pipeline._clear_refit(e) for e in entries] == old
    assert pipeline._clear_refit({"center": [1, 2], "score": 0.9}) and not pipeline._clear_refit({"score": 0.5})
