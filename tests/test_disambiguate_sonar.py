"""Session-level choice between sonar candidates ("two candidates"): static scenery, images."""

from __future__ import annotations

import numpy as np
import pytest

from calib_core.detect.sonar.detect import detect_sphere_in_cloud
from calib_core.disambiguate.sonar import (choose_by_image, choose_by_scenery, choose_sonar_candidates, image_phrase,
                                         reexamine_winners, winner_phrase)
from calib_core.geometry import T_from_rotvec, transform_points
from calib_core.io.clouds import Cloud, load_cloud, save_cloud
from calib_core.pipeline import detect_session
from calib_core.session import load_session
from conftest import SPHERE_DIAMETER_M, build_session, edit_yaml, tiny_camera

R = SPHERE_DIAMETER_M / 2
ROCK_SONAR_M = np.array([1.0, -0.2, 2.2])  # a scenery object of the sphere's size, never moved


def _cap(center_m, rng, n=150):
    d = rng.normal(size=(3 * n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d = d[(d @ -center_m) > 0][:n]
    return center_m + R * d + rng.normal(scale=0.002, size=(len(d), 3))


def _add_object(cloud_path, center_m, rng):
    c = load_cloud(cloud_path)
    extra = _cap(np.asarray(center_m, float), rng, n=int(np.sum(c.intensity > 100)))
    inten = None if c.intensity is None else np.concatenate([c.intensity, np.full(len(extra), 200.0)])
    save_cloud(cloud_path, Cloud(np.vstack([c.points_m, extra]), inten))


# --- the cues on their own -------------------------------------------------------------------

def test_scenery_cue_picks_the_candidate_that_moves():
    rng = np.random.default_rng(0)
    others = {f"p{i}": np.vstack([rng.uniform(-1, 1, (1, 3)) + [0, 0, 2], ROCK_SONAR_M + 0.01 * rng.normal(size=3)])
              for i in range(6)}
    target = np.array([0.3, 0.0, 1.8])
    for order in ([target, ROCK_SONAR_M], [ROCK_SONAR_M, target]):
        k, why = choose_by_scenery(np.array(order), others, R)
        assert np.allclose(np.array(order)[k], target) and "6 of 6" in why


def test_scenery_cue_stays_silent_when_it_cannot_tell():
    rng = np.random.default_rng(1)
    target = np.array([0.3, 0.0, 1.8])
    moving = {f"p{i}": rng.uniform(-1, 1, (1, 3)) + [0, 0, 2] for i in range(6)}
    # nothing static: the refusal stays
    assert choose_by_scenery(np.array([target, ROCK_SONAR_M]), moving, R)[0] is None
    # both static (the target left in place as well): no choice
    both = {c: np.vstack([target, ROCK_SONAR_M]) for c in moving}
    assert choose_by_scenery(np.array([target, ROCK_SONAR_M]), both, R)[0] is None
    # too few other captures to say "static"
    few = {c: ROCK_SONAR_M[None] for c in list(moving)[:2]}
    assert choose_by_scenery(np.array([target, ROCK_SONAR_M]), few, R)[0] is None


def test_image_cue_picks_the_candidate_on_the_image_detection():
    cam = tiny_camera(width_px=640, height_px=480)
    T = T_from_rotvec([0.02, -0.03, 0.01], [0.1, 0.05, 0.0])
    target, decoy = np.array([0.2, 0.1, 2.0]), np.array([-0.6, 0.0, 3.0])
    X_cam = transform_points(T, target[None])[0]
    uv = cam.project(X_cam[None])[0]
    img = {"status": "auto", "center": uv.tolist(), "range_m": float(np.linalg.norm(X_cam)) * 1.03}
    assert choose_by_image(np.array([decoy, target]), cam, T, img) == 1
    assert choose_by_image(np.array([target, decoy]), cam, T, img) == 0
    # the image found nothing, or a rejected one: no choice
    assert choose_by_image(np.array([target, decoy]), cam, T, {"status": "auto", "reason": "x"}) is None
    assert choose_by_image(np.array([target, decoy]), cam, T, dict(img, status="rejected")) is None
    # two candidates both on the image's line of sight and range gate: no choice
    near = target + np.array([0.0, 0.0, 0.03])
    assert choose_by_image(np.array([target, near]), cam, T, img) is None


def test_a_clear_winner_records_the_round_object_it_beat():
    """The losers' centres are sightings for the scenery cue in other captures."""
    from conftest import _sphere_cloud

    rng = np.random.default_rng(0)
    target, u = np.array([0.4, 0.1, 1.8]), -ROCK_SONAR_M / np.linalg.norm(ROCK_SONAR_M)
    recorded = 0
    for cos_min in (0.3, 0.5, 0.7, 0.8):  # rocks showing less and less of themselves, noisier than the ball
        pts, _ = _sphere_cloud(target, R, 400, rng)
        d = rng.normal(size=(2000, 3))
        d = (d / np.linalg.norm(d, axis=1, keepdims=True))
        d = d[d @ u > cos_min][:150]
        rock = ROCK_SONAR_M + R * d + rng.normal(scale=0.008, size=d.shape)
        det = detect_sphere_in_cloud(np.vstack([pts, rock]), R, beam_width_deg=0.1)
        if det.found and "another round object" in det.extras.get("warning", ""):
            assert np.linalg.norm(det.center_sonar_m - target) < 0.01
            assert np.min(np.linalg.norm(np.asarray(det.extras["other_candidates"]) - ROCK_SONAR_M, axis=1)) < 0.03
            recorded += 1
    assert recorded >= 1


# --- in detect_session ------------------------------------------------------------------------

@pytest.fixture(scope="module")
def rock_session(tmp_path_factory):
    """Eight captures; every cloud holds the moving target and a rock of its size that never moves."""
    root = build_session(tmp_path_factory.mktemp("rock"), n_captures=8, n_points=400, seed=3)
    # every cloud refused: the session cannot estimate the beam width; these clouds have no blooming
    edit_yaml(root / "session.yaml", lambda m: m["sonar"].update(beam_width_deg=0.1))
    rng = np.random.default_rng(4)
    for cap in load_session(root).captures:
        _add_object(cap.cloud_path, ROCK_SONAR_M + 0.002 * rng.normal(size=3), rng)
    return root


def test_every_cloud_alone_is_refused_as_two_candidates(rock_session):
    s = load_session(rock_session)
    for cap in s.captures[:2]:
        # the test clouds have no beam blooming: a near-zero beam width, as session.yaml says
        det = detect_sphere_in_cloud(load_cloud(cap.cloud_path).points_m, R, beam_width_deg=0.1)
        assert det.reason.startswith("two candidates"), det.reason
        cands = np.asarray(det.extras["two_candidates"])
        assert np.min(np.linalg.norm(cands - ROCK_SONAR_M, axis=1)) < 0.02


def test_detect_session_settles_them_with_the_static_scenery(rock_session):
    s = load_session(rock_session)
    dets = detect_session(s, {}, workers=1)
    for i, cap in enumerate(s.captures):
        son = dets[cap.id]["sonar"]
        truth = np.array([0.4 * (i % 3 - 1), 0.1 * (i % 2), 1.6 + 0.2 * i])
        assert son.get("center") is not None, son.get("reason")
        assert np.linalg.norm(np.asarray(son["center"]) - truth) < 0.01
        assert son["resolved_by"].startswith("static scenery") and len(son["two_candidates"]) == 2
        assert son["status"] == "auto"
    # a second run keeps the settled entries as they are (their fingerprints record the seed)
    again = detect_session(s, dets, workers=1)
    assert all(again[c]["sonar"] == dets[c]["sonar"] for c in dets)


def test_detect_session_settles_a_lone_decoy_with_the_images(tmp_path):
    root = build_session(tmp_path, n_captures=8, n_points=400, seed=5, width_px=320, height_px=240)
    s = load_session(root)
    rng = np.random.default_rng(6)
    _add_object(s.capture("p04").cloud_path, np.array([-1.2, -0.3, 3.4]), rng)  # not in the image
    dets = detect_session(s, {}, workers=1)
    son = dets["p04"]["sonar"]
    assert son.get("center") is not None, son.get("reason")
    assert np.linalg.norm(np.asarray(son["center"]) - [0.4 * (3 % 3 - 1), 0.1, 1.6 + 0.6]) < 0.01
    assert son["resolved_by"] == image_phrase("cam1")
    assert all("resolved_by" not in dets[c]["sonar"] for c in dets if c != "p04")


def test_undecidable_refusals_stay():
    """No static scenery and no usable image: the entry keeps its reason."""
    two = {"status": "auto", "reason": "two candidates: ...", "two_candidates": [[0.3, 0, 1.8], [1.0, -0.2, 2.2]]}
    dets = {"p01": {"sonar": two, "cam1": {"status": "auto", "reason": "no round outline"}}}
    rng = np.random.default_rng(2)
    for i in range(2, 8):
        dets[f"p{i:02d}"] = {"sonar": {"status": "auto", "center": (rng.uniform(-1, 1, 3) + [0, 0, 2]).tolist()},
                             "cam1": {"status": "auto", "reason": "no round outline"}}
    assert choose_sonar_candidates(dets, {"cam1": tiny_camera()}, R, ["p01"]) == {}


# --- a clear winner that is scenery -------------------------------------------------------------

def _winner_dets(target, n_others=6, seed=7):
    """Detections where p00's clear winner is the rock and the target is what it beat; the other
    captures found the (moving) target and recorded the rock as the round object they beat."""
    rng = np.random.default_rng(seed)
    dets = {"p00": {"sonar": {"status": "auto", "center": (ROCK_SONAR_M + 0.003).tolist(),
                              "other_candidates": [target.tolist()], "warning": "another round object ..."}}}
    for i in range(1, n_others + 1):
        dets[f"p{i:02d}"] = {"sonar": {"status": "auto", "center": (rng.uniform(-1, 1, 3) + [0, 0, 2]).tolist(),
                                       "other_candidates": [(ROCK_SONAR_M + 0.005 * rng.normal(size=3)).tolist()]}}
    return dets


def test_a_clear_winner_that_is_scenery_gives_way_to_the_target():
    target = np.array([0.3, 0.0, 1.8])
    dets = _winner_dets(target)
    out = reexamine_winners(dets, {}, R, ["p00"])
    assert np.allclose(out["p00"].center_sonar_m, target)
    assert out["p00"].resolved_by == winner_phrase(6, 6)
    # the other captures' winners move: none of them is re-examined into the rock
    assert reexamine_winners(dets, {}, R, [f"p{i:02d}" for i in range(1, 7)]) == {}


def test_a_winner_is_kept_when_the_scenery_cue_cannot_tell():
    target = np.array([0.3, 0.0, 1.8])
    dets = _winner_dets(target)
    # the "loser" is seen as often as the winner (both static): keep the winner
    for i in range(1, 7):
        dets[f"p{i:02d}"]["sonar"]["other_candidates"].append(target.tolist())
    assert reexamine_winners(dets, {}, R, ["p00"]) == {}
    # too few other captures
    assert reexamine_winners(_winner_dets(target, n_others=2), {}, R, ["p00"]) == {}
    # the winner seen in only one other capture: not scenery
    few = _winner_dets(target)
    for i in range(2, 7):
        few[f"p{i:02d}"]["sonar"]["other_candidates"] = []
    assert reexamine_winners(few, {}, R, ["p00"]) == {}


def test_a_camera_that_puts_the_target_on_the_winner_vetoes():
    cam = tiny_camera(width_px=640, height_px=480)
    T = np.eye(4)
    target = np.array([0.3, 0.0, 1.8])
    dets = _winner_dets(target)
    for cid, d in dets.items():  # every image detection lands on its sonar entry's winner
        c = np.asarray(d["sonar"]["center"])
        d["cam1"] = {"status": "auto", "center": cam.project(c[None])[0].tolist(), "range_m": float(np.linalg.norm(c))}
    assert reexamine_winners(dets, {"cam1": cam}, R, ["p00"]) == {}
    # the image on the target instead: the choice stands
    dets["p00"]["cam1"] = {"status": "auto", "center": cam.project(target[None])[0].tolist(),
                           "range_m": float(np.linalg.norm(target))}
    assert np.allclose(reexamine_winners(dets, {"cam1": cam}, R, ["p00"])["p00"].center_sonar_m, target)


def test_detect_session_refits_a_scenery_winner_at_the_target(rock_session):
    """The pipeline's second look: p00's entry says the rock won clearly (as a cloud where the
    ball is far, partly seen or noisier would); the others recorded the rock; the refit seeded
    at the target finds the ball in the cloud."""
    from calib_core.pipeline import SessionData, _resolve_ambiguous_sonar

    s = load_session(rock_session)
    dets = {}
    for i, cap in enumerate(s.captures):
        truth = [0.4 * (i % 3 - 1), 0.1 * (i % 2), 1.6 + 0.2 * i]
        if i == 0:
            son = {"center": ROCK_SONAR_M.tolist(), "other_candidates": [truth]}
        else:
            son = {"center": truth, "other_candidates": [ROCK_SONAR_M.tolist()]}
        dets[cap.id] = {"sonar": dict(son, status="auto")}
    out = _resolve_ambiguous_sonar(SessionData(s), dets, only={c.id for c in s.captures})
    assert set(out) == {s.captures[0].id}
    son = out[s.captures[0].id]
    assert np.linalg.norm(np.asarray(son["center"]) - [-0.4, 0.0, 1.6]) < 0.01
    assert son["resolved_by"] == winner_phrase(7, 7) and len(son["two_candidates"]) == 2
