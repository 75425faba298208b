"""The second round of the session's sonar choices (calib_core.disambiguate.sonar_rounds): the
image cue once round 1 settled captures, and a look past a plain sonar detection that is scenery."""

from __future__ import annotations

import numpy as np

from calib_core.disambiguate.sonar_rounds import past_scenery, past_scenery_phrase, settle_sonar
from conftest import SPHERE_DIAMETER_M, tiny_camera

R = SPHERE_DIAMETER_M / 2
ROCK_SONAR_M = np.array([1.0, -0.2, 2.2])  # a boulder of the sphere's size, never moved
CAM = tiny_camera(width_px=640, height_px=480)  # T_cam_sonar = identity in these detections


def _image(c) -> dict:
    c = np.asarray(c, float)
    return {"status": "auto", "center": CAM.project(c[None])[0].tolist(), "range_m": float(np.linalg.norm(c))}


def _targets(n, seed=3):
    rng = np.random.default_rng(seed)
    return [np.array([rng.uniform(-0.8, 0.8), rng.uniform(-0.6, 0.6), rng.uniform(1.6, 2.8)]) for _ in range(n)]


def _ambiguous_session(n=7):
    """Every cloud shows the target and the boulder ("two candidates"); the images found the target."""
    dets = {}
    for i, t in enumerate(_targets(n)):
        dets[f"p{i:02d}"] = {"sonar": {"status": "auto", "two_candidates": [t.tolist(), ROCK_SONAR_M.tolist()]},
                             "cam1": _image(t)}
    return dets


def test_round_two_settles_with_the_captures_round_one_settled():
    dets = _ambiguous_session()
    targets = [np.asarray(d["sonar"]["two_candidates"][0]) for d in dets.values()]
    # p06 also shows a third round object seen nowhere else: the scenery cue cannot decide it
    far = np.array([-1.5, 0.5, 4.0])
    dets["p06"]["sonar"]["two_candidates"].append(far.tolist())
    out = settle_sonar(dets, {"cam1": CAM}, R, list(dets), [], [])
    assert set(out) == set(dets)
    assert np.allclose(out["p06"].center_sonar_m, targets[6]) and out["p06"].resolved_by.startswith("camera cam1")
    # without the second round (round 1 only) p06 stays open
    from calib_core.disambiguate.sonar import choose_sonar_candidates
    assert "p06" not in choose_sonar_candidates(dets, {"cam1": CAM}, R, list(dets))


def test_a_plain_detection_on_scenery_is_looked_at_where_the_camera_puts_the_sphere():
    dets = _ambiguous_session()
    settled = {c: {"sonar": {"status": "auto", "center": d["sonar"]["two_candidates"][0],
                             "other_candidates": [ROCK_SONAR_M.tolist()]}, "cam1": d["cam1"]} for c, d in dets.items()}
    target = np.array([0.2, 0.1, 2.0])
    settled["p07"] = {"sonar": {"status": "auto", "center": (ROCK_SONAR_M + 0.002).tolist()}, "cam1": _image(target)}
    out = past_scenery(settled, {"cam1": CAM}, R, list(settled))
    assert list(out) == ["p07"]
    assert np.linalg.norm(out["p07"].center_sonar_m - target) < 0.01
    assert out["p07"].resolved_by == past_scenery_phrase(7, 7, ["cam1"])


def test_no_look_past_a_winner_the_camera_agrees_with_or_that_moves():
    dets = _ambiguous_session()
    settled = {c: {"sonar": {"status": "auto", "center": d["sonar"]["two_candidates"][0],
                             "other_candidates": [ROCK_SONAR_M.tolist()]}, "cam1": d["cam1"]} for c, d in dets.items()}
    # the camera also sees the round object on the boulder: it vetoes
    settled["p07"] = {"sonar": {"status": "auto", "center": ROCK_SONAR_M.tolist()}, "cam1": _image(ROCK_SONAR_M)}
    assert past_scenery(settled, {"cam1": CAM}, R, ["p07"]) == {}
    # a winner seen in few other captures is not scenery
    for c in list(settled)[:5]:
        settled[c]["sonar"]["other_candidates"] = []
    settled["p07"]["cam1"] = _image([0.2, 0.1, 2.0])
    assert past_scenery(settled, {"cam1": CAM}, R, ["p07"]) == {}
    # no camera detection: nothing to look at
    settled["p07"].pop("cam1")
    assert past_scenery(settled, {"cam1": CAM}, R, ["p07"]) == {}
