"""Which candidates the image detector skips once a clean outline is accepted (the no-background
speed: issue 11's 60 ms per 1080p frame)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from calib_core.detect.image.detect import _dominated, _same_outline, detect_sphere_in_image
from calib_core.detect.image.fit import CandidateFit
from calib_core.detect.image.region import Candidate

sys.path.insert(0, str(Path(__file__).parent))
from test_detect_image_scenes import make_background, make_camera, render, sphere_pose_at  # noqa: E402


def _cand(uv, r, strength, source="votes"):
    return Candidate(np.asarray(uv, float), float(r), (float(r), float(r)), 0.0, False, float(strength), source)


def _accepted(uv, r, score=0.98, credible=True):
    th = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    sil = np.asarray(uv, float) + r * np.column_stack([np.cos(th), np.sin(th)])
    f = CandidateFit(True, "", None, np.asarray(uv, float), np.eye(2), sil, 0.95, score, 40.0, 2.0)
    f.credible = credible
    return f


def test_a_candidate_on_the_accepted_outline_is_skipped_a_larger_one_is_not():
    ok = [(_cand((500, 400), 80, 140), _accepted((500, 400), 80))]
    assert _same_outline(_cand((520, 410), 40, 90), ok)  # smaller, centred on it
    assert _same_outline(_cand((490, 395), 100, 60), ok)  # the same outline at another radius
    assert not _same_outline(_cand((500, 400), 140, 60), ok)  # may be a sphere around it
    assert not _same_outline(_cand((580, 400), 60, 60), ok)  # off its centre
    ok_rough = [(ok[0][0], _accepted((500, 400), 80, credible=False))]
    assert not _same_outline(_cand((520, 410), 40, 90), ok_rough)


def test_out_voted_only_by_a_clean_confident_vote_outline():
    strong = _cand((500, 400), 80, 140)
    ok = [(strong, _accepted((500, 400), 80))]
    assert _dominated(_cand((900, 300), 120, 60), ok)  # under half the vote
    assert not _dominated(_cand((900, 300), 120, 80), ok)  # more than half: refined
    assert not _dominated(_cand((900, 300), 120, 30, source="contrast"), ok)  # other cue: refined
    assert not _dominated(_cand((900, 300), 120, 60), [(strong, _accepted((500, 400), 80, score=0.8))])
    assert not _dominated(_cand((900, 300), 120, 60), [(strong, _accepted((500, 400), 80, credible=False))])


def test_clean_sphere_without_background_refines_few_candidates():
    cam = make_camera(1920, 1080, 1200.0, (-0.25, 0.08, 0, 0, 0))
    rng = np.random.default_rng(4)
    img, truth = render(cam, make_background(cam, rng), sphere_pose_at(cam, (400, 300), 1.0), 0.11, rng)
    det = detect_sphere_in_image(img, cam, 0.11)
    assert det.found and np.linalg.norm(det.center_uv_px - truth) < 0.3
    # the weaker vote peaks on the background texture are left alone (img3's code refined 6 of the 8)
    assert det.extras["refined"] <= det.extras["candidates"] // 2, det.extras
