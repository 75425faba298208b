"""Balls in low light (issue 11, twenty-fourth round: the "dim" kind, calib_core/synth/photo/dim.py).

A matte ball lit from one side on black cloth: its limb steps strongly to the black on the lit
side and weakly on the other, where the shading falls towards the limb and the terminator lies
just inside it; equal weights for every pass-2 edge moved the centre towards the lit side (each
edge's precision now weights the cone that gives the centre, fit.edge_precision).
"""

import numpy as np
import pytest

from calib_core.detect.image.detect import detect_sphere_in_image
from calib_core.detect.image.fit import PRECISION_CAP, edge_precision
from calib_core.synth.image_cases import render_case


def test_side_lit_ball_on_black_centre_not_pulled_to_the_lit_side():
    case = render_case("dim", 1020, 0.25)  # lit ball on black, lamp to one side
    det = detect_sphere_in_image(case.image, case.cam, case.radius_m)
    assert det.found, det.reason
    # (equal edge weights: 1.52 px towards the lit side)
    assert np.hypot(*(det.center_uv_px - case.true_uv_px)) < 0.8


def test_edge_precision_relative_and_capped():
    w = edge_precision(np.array([1.0, 2.0, 4.0, 2.0, 0.5]))
    assert w == pytest.approx([0.25, 1.0, PRECISION_CAP, 1.0, 0.0625])
    assert edge_precision(np.zeros(3)) == pytest.approx(np.ones(3))
