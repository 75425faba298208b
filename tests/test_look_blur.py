"""The look at a predicted place on a motion-blurred ball (issue 11, nineteenth round).

A ball carried during the exposure is smeared along the motion: its edge across the motion is a
ramp, the wall's sharp edges show through it. With the size fixed by the prediction, a circle
through those edges can sit anywhere across the ramp (carried-photo s5 p06: 3.35 px off with a
stated 0.19 px). The look must read the ramp's middle and state the blur's floor (the free
search's, calib_core.detect.image.blur), and leave a sharp ball's covariance alone.
"""

import numpy as np
import pytest

from calib_core.detect.image.blur import blur_floor_px2
from calib_core.detect.image.fit import SHARP_EDGE_WIDTH_PX
from calib_core.detect.image.predicted import detect_at_prediction
from tests.test_detect_image_flow import RADIUS_M, _bricks, _cam, _draw_ball, _finish, _truth

COLOUR = (200, 190, 60)


def _smeared(cam, wall, C, motion_m: float, steps: int = 16) -> np.ndarray:
    """The ball moved by ``motion_m`` along x during the exposure, centred on ``C`` (the mean of
    ``steps`` renders: the wall stays sharp, the ball's outline across the motion becomes a ramp)."""
    acc = np.zeros_like(wall)
    for s in np.linspace(-0.5, 0.5, steps):
        acc += _draw_ball(wall, cam, (C[0] + s * motion_m, C[1], C[2]), COLOUR)
    return acc / steps


@pytest.mark.parametrize("seed, C, motion_px", [(5, (-0.5, 0.2, 3.5), 15.0), (6, (0.6, -0.3, 3.0), 12.0)])
def test_a_look_on_a_blurred_ball_reads_the_smears_middle_and_says_how_sure(seed, C, motion_px):
    rng = np.random.default_rng(seed)
    cam = _cam()
    uv, r = _truth(cam, C)
    img = _finish(_smeared(cam, _bricks(cam.height_px, cam.width_px, rng), C, motion_px * C[2] / cam.fx), rng)
    det = detect_at_prediction(img, cam, RADIUS_M, uv + np.array([2.5, -1.0]), 1.01 * r, shift_frac=0.07)
    assert det.found, det.reason
    err = det.center_uv_px - uv
    assert det.extras["edge_width_px"] > SHARP_EDGE_WIDTH_PX
    assert np.hypot(*err) < 1.5, err
    # the stated covariance holds the blur's floor: the error within it (chi2, 2 dof, 1e-3)
    assert float(err @ np.linalg.solve(det.cov_uv_px2, err)) < 13.8
    assert np.linalg.eigvalsh(det.cov_uv_px2).min() >= blur_floor_px2(det.radius_px, det.extras["edge_width_px"]) - 1e-9


def test_a_sharp_ball_gets_no_blur_floor():
    rng = np.random.default_rng(4)
    cam = _cam()
    C = (-0.5, 0.2, 3.5)
    uv, r = _truth(cam, C)
    img = _finish(_draw_ball(_bricks(cam.height_px, cam.width_px, rng), cam, C, COLOUR), rng)
    det = detect_at_prediction(img, cam, RADIUS_M, uv + np.array([2.5, -1.0]), 1.01 * r, shift_frac=0.07)
    assert det.found, det.reason
    assert det.extras["edge_width_px"] <= SHARP_EDGE_WIDTH_PX and det.extras["edge_smoothing_px"] == 0.0
    assert blur_floor_px2(det.radius_px, det.extras["edge_width_px"]) == 0.0
    assert np.sqrt(np.trace(det.cov_uv_px2) / 2) < 0.5
    assert np.hypot(*(det.center_uv_px - uv)) < 0.5
