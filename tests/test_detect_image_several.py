"""A ball whose outline is neither the outermost nor the strongest edge on its rays (issue 11,
eighth round).

Held-out ``chair`` cases 1016 and 1079: a dark or grey ball before the chair's dark backrest,
whose own edge runs 10-20 px outside the ball's outline and is stronger than the ball's
dark-on-dark edge; the seat and a block cross the rest of the outline. The first pass read one
edge per ray (the outermost, or the strongest) and fitted the backrest and the seat: "no round
outline". The third reading fits the few strongest edges of every ray together.
"""

import numpy as np
import pytest

from calib_core.detect.image.detect import detect_sphere_in_image
from calib_core.detect.image.edges import edge_peaks
from calib_core.synth.image_cases import render_case


def test_edge_peaks_strongest_first_with_subpixel_offsets():
    t = np.arange(0.0, 20.0, 1.0)
    g = np.zeros((2, len(t)))
    g[0, [4, 9, 15]] = [1.0, 3.0, 2.0]  # three isolated peaks
    g[0, 14] = g[0, 16] = 1.0  # symmetric shoulders: the peak at 15 stays at 15
    g[1, 9] = 0.05  # below the threshold
    te = edge_peaks(t, g, 0.1, 4)
    assert te.shape == (2, 4)
    np.testing.assert_allclose(te[0, :3], [9.0, 15.0, 4.0])
    assert np.isnan(te[0, 3]) and np.isnan(te[1]).all()


@pytest.mark.parametrize("seed", [1016, 1079])
def test_ball_before_a_dark_backrest_is_found(seed):
    case = render_case("chair", seed, 0.5)
    det = detect_sphere_in_image(case.image, case.cam, case.radius_m)
    assert det.found, det.reason
    assert np.hypot(*(det.center_uv_px - case.true_uv_px)) < 1.0
    assert det.score >= 0.5


def _fit(centre, r, support, score, credible, ok, sigma_px=0.3):
    from calib_core.detect.image.cone import ConeFit
    from calib_core.detect.image.fit import CandidateFit

    phi = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    sil = np.asarray(centre, float) + r * np.column_stack([np.cos(phi), np.sin(phi)])
    cone = ConeFit(np.array([0.0, 0.0, 1.0]), 0.1, np.ones(10, bool), np.zeros(10), 0.5, np.eye(3), np.eye(3))
    return CandidateFit(ok, "" if ok else "round outline inside a larger object", cone, np.asarray(centre, float),
                        sigma_px ** 2 * np.eye(2), sil, support, score, 20.0, 3.0, credible=credible)


def test_an_outline_read_two_ways_is_refused_when_the_weaker_reading_was_accepted():
    from calib_core.detect.image.detect import _disputed_by

    accepted = _fit((400.0, 300.0), 60.0, 0.57, 0.34, credible=False, ok=True)
    better_refused = _fit((403.1, 300.3), 59.0, 0.83, 0.48, credible=False, ok=False)
    assert _disputed_by([(None, accepted), (None, better_refused)], accepted) is better_refused
    # a credible accepted outline is not questioned; a rival that agrees (1 px) or explains
    # less, or is another object, disputes nothing
    credible = _fit((400.0, 300.0), 60.0, 0.9, 0.9, credible=True, ok=True)
    assert _disputed_by([(None, credible), (None, better_refused)], credible) is None
    agreeing = _fit((401.0, 300.0), 60.0, 0.83, 0.48, credible=False, ok=False)
    weaker = _fit((403.1, 300.3), 59.0, 0.5, 0.3, credible=False, ok=False)
    elsewhere = _fit((440.0, 300.0), 60.0, 0.83, 0.48, credible=False, ok=False)
    for rival in (agreeing, weaker, elsewhere):
        assert _disputed_by([(None, accepted), (None, rival)], accepted) is None
