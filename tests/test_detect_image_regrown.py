"""An outline that outgrows the region cut for its candidate is refined again in a region cut
for itself (fit._outgrew_region, fit._regrown; issue 11, dim s1018).

A small candidate on one arc of a large dark ball (a lamp's lit patch on the wall beside it)
fits the whole ball's cone from that arc, but pass 2 reads only the normals whose band lies in
the candidate's region: the rest of the outline counted as unseen, and the ball was refused as
mostly hidden. Constructed image: a dark disc before a dim wall with a lit patch, sensor noise.
"""

import cv2
import numpy as np
import pytest

from calib_core.camera import CameraModel
from calib_core.detect.image import fit as fit_mod
from calib_core.detect.image.detect import detect_sphere_in_image
from calib_core.detect.image.fit import refine_candidate
from calib_core.detect.image.region import Candidate

W, H = 640, 480
CENTRE, R_PX = np.array([320.0, 240.0]), 150.0  # at the principal point: the outline is a circle
RADIUS_M = 0.2
A_RANGE = (np.arcsin(RADIUS_M / 12.0), np.arcsin(RADIUS_M / 0.3))


def _cam():
    return CameraModel(W, H, np.array([[520.0, 0, W / 2], [0, 520.0, H / 2], [0, 0, 1]]))


def _scene(with_ball: bool, seed: int = 3) -> np.ndarray:
    """A dim wall (grey level ~40) brightening towards a lamp's patch at the upper left, a
    dark ball (grey level ~8) at the centre, Gaussian noise of 3 grey levels."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    wall = 40.0 + 120.0 * np.exp(-((xx - 150.0) ** 2 + (yy - 80.0) ** 2) / (2 * 90.0 ** 2))
    img = np.repeat(wall[..., None], 3, axis=2) * np.array([1.0, 0.8, 0.7], np.float32)
    if with_ball:
        m = np.zeros((H, W), np.uint8)
        cv2.circle(m, (int(CENTRE[0] * 16), int(CENTRE[1] * 16)), int(R_PX * 16), 255, -1, cv2.LINE_AA, shift=4)
        a = (m.astype(np.float32) / 255.0)[..., None]
        img = img * (1 - a) + 8.0 * a
    img = cv2.GaussianBlur(img, (0, 0), 0.8) + rng.normal(0, 3.0, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8)


def _small_candidate() -> Candidate:
    """A candidate a quarter of the ball's size on its lit upper-left arc."""
    d = np.array([-1.0, -1.0]) / np.sqrt(2)
    r = 0.25 * R_PX
    return Candidate(CENTRE + 0.9 * R_PX * d, r, (r, r), 0.0, False, 30.0, "contrast")


@pytest.mark.parametrize("regrow", [True, False])
def test_small_candidate_on_a_large_ball_finds_it_only_when_regrown(regrow):
    fit = refine_candidate(_scene(True), _cam(), _small_candidate(), RADIUS_M, A_RANGE, None,
                           np.random.default_rng(0), regrow=regrow)
    if regrow:
        assert fit.ok and fit.credible, fit.reason
        assert np.hypot(*(fit.centre_uv_px - CENTRE)) < 1.0
        assert fit.support > 0.8
        assert fit.extras["regrown_from_px"] == pytest.approx(0.25 * R_PX, abs=0.1)
    else:  # (what main did: the region of a small candidate holds a fraction of the outline)
        assert not fit.ok
        assert fit.support < fit_mod.MIN_SUPPORT


def test_regrowth_needs_an_outline_much_larger_than_its_candidate():
    # a candidate of about the ball's size: its region holds the outline, nothing is refined again
    r = 0.9 * R_PX
    cand = Candidate(CENTRE + 5.0, r, (r, r), 0.0, False, 30.0, "contrast")
    fit = refine_candidate(_scene(True), _cam(), cand, RADIUS_M, A_RANGE, None, np.random.default_rng(0))
    assert fit.ok and "regrown_from_px" not in fit.extras
    assert np.hypot(*(fit.centre_uv_px - CENTRE)) < 1.0


def test_the_wall_alone_gives_no_outline_from_the_same_candidate():
    fit = refine_candidate(_scene(False), _cam(), _small_candidate(), RADIUS_M, A_RANGE, None,
                           np.random.default_rng(0))
    assert not fit.ok


def test_the_whole_detector_finds_the_ball_and_nothing_without_it():
    found = detect_sphere_in_image(_scene(True), _cam(), RADIUS_M)
    assert found.found, found.reason
    assert np.hypot(*(found.center_uv_px - CENTRE)) < 1.0
    empty = detect_sphere_in_image(_scene(False), _cam(), RADIUS_M)
    assert not empty.found
