"""A ball's print taken for the ball (issue 11, patterned sports balls): a pentagon or a panel
inside the ball's outline is not the ball, and a circle found on noise peaks is no outline
(calib_core.detect.image.pattern, detect._good_fits, fit._outline_held)."""

import numpy as np

from calib_core.detect.image import detect as im
from calib_core.detect.image.cone import ConeFit
from calib_core.detect.image.fit import CandidateFit
from calib_core.detect.image.pattern import is_body, lies_inside
from calib_core.synth.image_cases import render_case


def _fit(u, v, r, rms, support=1.0, outside=0.0, ok=True, reason=""):
    ang = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    sil = np.column_stack([u + r * np.cos(ang), v + r * np.sin(ang)])
    cone = ConeFit(np.array([0, 0, 1.0]), 0.1, np.ones(90, bool), np.zeros(90), float(rms), np.eye(3), np.eye(3))
    return CandidateFit(ok, reason, cone, np.array([u, v], float), np.eye(2), sil, support, 0.8, 50.0, 1.0,
                        {"outside_mismatch": outside}, credible=ok)


def test_an_outline_wholly_inside_a_larger_body_is_its_print():
    ball = _fit(300, 200, 70, rms=1.0, ok=False, reason="outline not round (edge RMS 1.0 px)")
    pent = _fit(270, 205, 20, rms=0.3)
    assert is_body(ball, 0.2, 0.6, 2.0) and lies_inside(pent, ball)
    assert not lies_inside(ball, pent)
    # straddling the limb: not inside; a second fit of the same outline, a little larger: not a print
    assert not lies_inside(_fit(360, 200, 20, rms=0.3), ball)
    assert not lies_inside(_fit(301, 200, 69, rms=0.3), ball)
    # a body must be mostly seen, like its surroundings outside, and at most twice the roundness limit
    assert not is_body(_fit(300, 200, 70, rms=1.0, support=0.5), 0.2, 0.6, 2.0)
    assert not is_body(_fit(300, 200, 70, rms=1.0, outside=0.5), 0.2, 0.6, 2.0)
    assert not is_body(_fit(300, 200, 70, rms=2.0), 0.2, 0.6, 2.0)
    good = im._good_fits([(None, ball), (None, pent)])
    assert good == []  # the pentagon dropped; the ball itself was refused
    # a circle run through clutter around a ball: the clutter goes on outside it
    clutter = _fit(300, 200, 70, rms=1.0, outside=0.27, ok=False, reason="outline not round (edge RMS 1.0 px)")
    assert im._good_fits([(None, clutter), (None, pent)])[0][1] is pent


def test_a_clear_pentagon_lets_the_pattern_cue_find_the_ball():
    # football in a hand (jpeg + gain + defocus): a pentagon was accepted 7.5 px off (score 0.30)
    case = render_case("sports", 1097, 0.5)
    det = im.detect_sphere_in_image(case.image, case.cam, case.radius_m)
    assert det.found and np.hypot(*(det.center_uv_px - case.true_uv_px)) < 1.0


def test_a_pentagon_inside_a_rough_ball_outline_is_no_detection():
    # football in a hand, jpeg + shake: the ball's outline is refused as not round (1.0 px RMS),
    # a pentagon inside it was accepted 40 px off at 0.72
    case = render_case("sports", 1092, 0.5)
    det = im.detect_sphere_in_image(case.image, case.cam, case.radius_m)
    assert not det.found or np.hypot(*(det.center_uv_px - case.true_uv_px)) < 3.0


def test_a_circle_on_noise_peaks_in_a_square_is_no_outline():
    # ball-free: a circle inscribed in a defocused pale square of a checkered block was found at
    # 0.99 from edges 1.5 px wide (narrower than any step after the smoothing)
    case = render_case("sports", 1093, 0.5, with_ball=False)
    assert not im.detect_sphere_in_image(case.image, case.cam, case.radius_m).found


def test_a_ball_inside_a_rough_circle_through_clutter_is_kept():
    # tennis ball in a hand (jpeg + gain + shake 5.8 px): a circle through a block's edges
    # around it (2.3 px RMS at r 75, 2.5x the roundness limit) is no body
    case = render_case("sports", 1091, 0.5)
    det = im.detect_sphere_in_image(case.image, case.cam, case.radius_m)
    assert det.found and np.hypot(*(det.center_uv_px - case.true_uv_px)) < 0.5


def test_a_ball_inside_a_circle_through_clutter_is_kept():
    # volleyball on the floor (jpeg + shake): a circle through clutter around it (r 115, 1.95x
    # the roundness limit, outside mismatch 0.27) is no body
    case = render_case("sports", 1000, 0.5)
    det = im.detect_sphere_in_image(case.image, case.cam, case.radius_m)
    assert det.found and np.hypot(*(det.center_uv_px - case.true_uv_px)) < 1.5
