"""The border rule (issue 11, the lead's decision in round 21): a clean, credible whole outline
beside a stronger outline cut by the image border is "two round objects" with both places and
sizes (the session's sonar prediction chooses), never a silent "cut by the border"; a ball cut
by the border beside ragged clutter is still reported as cut."""

from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from calib_core.detect.image import detect as D
from calib_core.detect.image.fit import CandidateFit
from calib_core.detect.image.region import Candidate

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the analytic image maker next to this file
from test_detect_image_scenes import make_background, make_camera, render, sphere_pose_at  # noqa: E402

R_M = 0.11


@pytest.fixture(scope="module")
def scene():
    """A ball whole at 1.6 m and a ball at 0.8 m cut by the right border (the stronger outline)."""
    cam = make_camera(960, 540, 600.0, (-0.1, 0.02, 0.0, 0.0, 0.0))
    rng = np.random.default_rng(0)
    bg = make_background(cam, rng)
    first, t_whole = render(cam, bg, sphere_pose_at(cam, (300, 250), 1.6), R_M, rng)
    img, t_cut = render(cam, first.astype(np.float32), sphere_pose_at(cam, (935, 300), 0.8), R_M, rng)
    return cam, img, bg, t_whole, t_cut


@pytest.mark.parametrize("with_background", [False, True])
def test_whole_ball_beside_a_stronger_cut_one_is_two_round_objects(scene, with_background):
    cam, img, bg, t_whole, t_cut = scene
    det = D.detect_sphere_in_image(img, cam, R_M, background=bg if with_background else None)
    assert not det.found and det.reason.startswith("two round objects: (")
    assert "cut by the image border" in det.reason and " r 43 px" in det.reason
    rows = np.asarray(det.extras["two_candidates"], float)
    assert len(rows) == 2
    whole = rows[np.argmin(np.hypot(*(rows[:, :2] - t_whole).T))]
    cut = rows[np.argmin(np.hypot(*(rows[:, :2] - t_cut).T))]
    assert np.hypot(*(whole[:2] - t_whole)) < 0.5 and whole[2] == pytest.approx(1.6, rel=0.01)
    assert np.hypot(*(cut[:2] - t_cut)) < 2.0 and cut[2] == pytest.approx(0.8, rel=0.03)
    notes = det.extras["two_candidates_notes"]
    assert sorted(notes) == ["", "cut by the image border"]
    assert len(det.extras["two_candidates_radius_px"]) == 2


def test_a_click_on_the_whole_ball_finds_it(scene):
    cam, img, _, t_whole, _ = scene
    det = D.detect_sphere_in_image(img, cam, R_M, hint_uv_px=t_whole + 10)
    assert det.found and np.hypot(*(det.center_uv_px - t_whole)) < 0.5


def _circle_fit(centre, r, ok, credible, score, reason="", support=None, contrast=40.0) -> CandidateFit:
    t = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    sil = np.column_stack([centre[0] + r * np.cos(t), centre[1] + r * np.sin(t)])
    cone = SimpleNamespace(a_rad=float(np.arcsin(R_M / 1.0)), cov_params=np.eye(3) * 1e-8, sigma_px=0.2)
    return CandidateFit(ok, reason, fit=cone, centre_uv_px=np.asarray(centre, float), cov_uv_px2=np.eye(2) * 0.01,
                        silhouette_px=sil, support=score if support is None else support, score=score,
                        contrast=contrast, range_m=1.0, credible=credible)


def _verdict(fits):
    look = SimpleNamespace(d_min=0.3, d_max=12.0, radius_m=R_M, img=None)
    cands = [Candidate(f.centre_uv_px, 20.0, (20.0, 20.0), 0.0, False, 10.0, "votes") for f in fits]
    return D._verdict(look, list(zip(cands, fits)), cands, "ellipse-exact", False)


def test_cut_ball_beside_ragged_clutter_is_still_cut():
    """The rule's original purpose: the accepted outline beside the cut ball is ragged (not
    credible, a low fit score): the ball is there, cut; the clutter is no whole find."""
    cut = _circle_fit((950, 300), 110, False, True, 0.6, D.CUT)
    clutter = _circle_fit((300, 250), 40, True, False, 0.45)
    det = _verdict([clutter, cut])
    assert not det.found and det.reason == D.CUT
    assert det.extras["partial_center_uv_px"] == [950.0, 300.0]


def test_clean_whole_outline_beside_a_stronger_cut_one_is_not_silenced():
    cut = _circle_fit((950, 300), 110, False, True, 0.6, D.CUT)
    whole = _circle_fit((300, 250), 40, True, True, 0.95)
    det = _verdict([whole, cut])
    assert not det.found
    assert det.reason == "two round objects: (950, 300) r 110 px, cut by the image border and (300, 250) r 40 px"
    assert [r[:2] for r in det.extras["two_candidates"]] == [[950.0, 300.0], [300.0, 250.0]]


def test_weak_cut_outline_does_not_block_a_clean_whole_one():
    cut = _circle_fit((950, 300), 20, False, True, 0.6, D.CUT)
    whole = _circle_fit((300, 250), 40, True, True, 0.95)
    det = _verdict([whole, cut])
    assert det.found and np.allclose(det.center_uv_px, (300, 250))


def test_rival_share_counts_credible_round_objects_of_a_similar_size():
    best = _circle_fit((300, 250), 40, True, True, 0.95)
    twin = _circle_fit((700, 300), 36, True, True, 0.9)  # another round object of its size
    cut = _circle_fit((950, 300), 44, False, True, 0.8, D.CUT)
    small = _circle_fit((100, 100), 12, True, True, 0.95)  # much smaller: not a rival
    ragged = _circle_fit((500, 100), 40, True, True, 0.3)  # not clean: not a rival
    fits = [(None, f) for f in (best, twin, cut, small, ragged)]
    ev = [D._evidence(f) for f in (best, twin, cut)]
    assert D._rival_share(fits, best) == pytest.approx((ev[1] + ev[2]) / sum(ev))
    assert D._rival_share([(None, best), (None, small), (None, ragged)], best) == 0.0
