"""The third candidate cue (colour-distance discs) and the pass-2 region growth (issue 11).

Constructed images: a red ball before red brick (little colour contrast, strong texture all
around; the outline votes and the plain contrast cue miss it), brick alone, and a large clean
disc refined from a candidate far off its centre.
"""

import cv2
import numpy as np
import pytest

from calib_core.camera import CameraModel
from calib_core.detect.image.detect import detect_sphere_in_image
from calib_core.detect.image.discs import candidates_by_discs
from calib_core.detect.image.fit import refine_candidate
from calib_core.detect.image.region import Candidate

W, H = 640, 480


def _cam():
    return CameraModel(W, H, np.array([[520.0, 0, W / 2], [0, 520.0, H / 2], [0, 0, 1]]))


def _brick(rng) -> np.ndarray:
    """Red-brown bricks (random shade each) with grey mortar lines, float32 RGB."""
    img = np.empty((H, W, 3), np.float32)
    bw, bh = 34, 14
    for row in range(H // bh + 1):
        off = (bw // 2) * (row % 2)
        for col in range(-1, W // bw + 1):
            x0, y0 = col * bw + off, row * bh
            img[y0:y0 + bh, max(0, x0):max(0, x0 + bw)] = np.array([150, 62, 45]) * rng.uniform(0.75, 1.15)
    img[::bh] = img[1::bh] = (120, 112, 104)  # mortar
    for row in range(H // bh + 1):
        off = (bw // 2) * (row % 2)
        for x in range(off, W, bw):
            img[row * bh:(row + 1) * bh, x:x + 2] = (120, 112, 104)
    return img


def _with_disc(img, centre, r, colour, shade=0.25) -> np.ndarray:
    """A matte disc (anti-aliased, lit from the upper left) painted on ``img``."""
    ss = 8
    mask = np.zeros((H * ss, W * ss), np.uint8)
    cv2.circle(mask, (int(round(centre[0] * ss + (ss - 1) / 2)), int(round(centre[1] * ss + (ss - 1) / 2))),
               int(r * ss), 255, -1)
    cover = cv2.resize(mask.astype(np.float32) / 255, (W, H), interpolation=cv2.INTER_AREA)[..., None]
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    light = 1.0 + shade * (-(xx - centre[0]) - (yy - centre[1])) / (2 * r)
    ball = np.asarray(colour, np.float32) * np.clip(light, 0.5, 1.5)[..., None]
    return img * (1 - cover) + ball * cover


def _finish(img, rng) -> np.ndarray:
    return np.clip(cv2.GaussianBlur(img, (0, 0), 0.8) + rng.normal(0, 2.0, img.shape), 0, 255).astype(np.uint8)


def test_red_ball_before_red_brick_is_a_disc_candidate_and_found():
    rng = np.random.default_rng(11)
    centre, r = (371.3, 212.6), 46.0
    img = _finish(_with_disc(_brick(rng), centre, r, (185, 48, 36)), rng)  # votes miss it (checked)
    cands = candidates_by_discs(img, 1, (12.0, 240.0), max_candidates=6)
    near = [i for i, c in enumerate(cands)
            if np.hypot(*(c.centre_px - centre)) < 0.35 * r and 0.6 < c.radius_px / r < 1.6]
    assert near and near[0] <= 1, [(c.centre_px, c.radius_px) for c in cands]
    det = detect_sphere_in_image(img, _cam(), 0.2)
    assert det.found, det.reason
    # the circle's centre, not the sphere's projection (off axis they differ): within 1.5 px
    assert np.hypot(*(det.center_uv_px - centre)) < 1.5


def test_the_disc_cue_looks_when_the_other_cues_propose_nothing_at_all(monkeypatch):
    # outline votes and region contrast with no candidate at all (not even a ragged one): the
    # third cue must still look, as it does when they propose only clutter
    import calib_core.detect.image.detect as image

    monkeypatch.setattr(image, "candidates_by_votes", lambda *a, **k: [])
    monkeypatch.setattr(image, "candidates_single_frame", lambda *a, **k: [])
    rng = np.random.default_rng(11)
    centre, r = (371.3, 212.6), 46.0
    img = _finish(_with_disc(_brick(rng), centre, r, (185, 48, 36)), rng)
    det = detect_sphere_in_image(img, _cam(), 0.2)
    assert det.found, det.reason
    assert np.hypot(*(det.center_uv_px - centre)) < 1.5


def test_plain_texture_gives_no_strong_disc():
    rng = np.random.default_rng(13)
    img = _finish(_brick(rng), rng)
    cands = candidates_by_discs(img, 1, (20.0, 240.0), max_candidates=6)
    assert all(c.radius_px < 20 or c.strength < 100 for c in cands), [(c.radius_px, c.strength) for c in cands]


def _textured_ball_on_brick(rng, centre, r):
    img = _with_disc(_brick(rng), centre, r, (200, 180, 40))
    blotch = cv2.GaussianBlur(rng.normal(0, 1, (H, W)).astype(np.float32), (0, 0), 4)
    yy, xx = np.mgrid[0:H, 0:W]
    inside = (xx - centre[0]) ** 2 + (yy - centre[1]) ** 2 < r * r
    img[inside] *= (1 + 0.15 * blotch[inside] / blotch.std())[:, None]  # foam-like blotches
    return _finish(img, rng)


@pytest.mark.parametrize("angle_deg,dist_r,cand_r", [(150, 1.5, 0.74), (90, 1.7, 0.9), (240, 1.7, 0.9)])
def test_candidate_far_off_a_large_ball_gives_no_outline_off_its_centre(angle_deg, dist_r, cand_r):
    # a candidate ~1.5-1.7 ball radii from a 150 px ball sees one arc of it; the outline fitted
    # from that arc reaches beyond the candidate's region, where samples would be the region's
    # replicated border: those normals are not used (before: accepted fits 1.6-5.6 px off)
    rng = np.random.default_rng(14)
    centre, r = np.array([320.0, 240.0]), 150.0  # at the principal point: a sphere's outline
    img = _textured_ball_on_brick(rng, centre, r)
    a = np.radians(angle_deg)
    xy = centre + dist_r * r * np.array([np.cos(a), np.sin(a)])
    R = cand_r * r
    cand = Candidate(xy, R, (R, R), 0.0, False, 50.0, "contrast")
    a_range = (np.arcsin(0.2 / 12.0), np.arcsin(0.2 / 0.3))
    fit = refine_candidate(img, _cam(), cand, 0.2, a_range, None, np.random.default_rng(0))
    if fit.ok:
        assert np.hypot(*(fit.centre_uv_px - centre)) < 0.5
