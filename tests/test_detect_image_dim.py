"""Balls in low light (issue 11, twenty-fourth round: the "dim" kind, calib_core/synth/photo/dim.py).

A matte ball lit from one side on black cloth: its limb steps strongly to the black on the lit
side and weakly on the other, where the shading falls towards the limb and the terminator lies
just inside it; equal weights for every pass-2 edge moved the centre towards the lit side (each
edge is now weighted by its precision, fit.edge_precision). The rim of a lamp's spot on a wall
is a smooth fall-off, not a step: it is no outline (edges.step_ratio).
"""

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter1d

from calib_core.detect.image.detect import detect_sphere_in_image
from calib_core.detect.image.edges import side_lines, step_ratio
from calib_core.detect.image.fit import PRECISION_CAP, edge_precision
from calib_core.synth.image_cases import render_case


def test_side_lit_ball_on_black_centre_not_pulled_to_the_lit_side():
    case = render_case("dim", 1020, 0.25)  # lit ball on black, lamp to one side
    det = detect_sphere_in_image(case.image, case.cam, case.radius_m)
    assert det.found, det.reason
    # (equal edge weights: 1.52 px towards the lit side)
    assert np.hypot(*(det.center_uv_px - case.true_uv_px)) < 0.8


def test_lamp_spot_on_a_wall_is_not_a_ball():
    case = render_case("dim", 1033, 0.5, with_ball=False)  # a wall washer's spot on brick, no ball
    det = detect_sphere_in_image(case.image, case.cam, case.radius_m)
    # (before the step test: found at score 0.92, the spot's rim read as an outline)
    assert not det.found or det.score < 0.5, (det.center_uv_px, det.score)


def test_edge_precision_relative_and_capped():
    w = edge_precision(np.array([1.0, 2.0, 4.0, 2.0, 0.5]))
    assert w == pytest.approx([0.25, 1.0, PRECISION_CAP, 1.0, 0.0625])
    assert edge_precision(np.zeros(3)) == pytest.approx(np.ones(3))


def _profiles_image(kind: str) -> np.ndarray:
    """A 1-D edge across x = 100 (inside x < 100), blurred: float32 (40, 200, 3)."""
    x = np.arange(200) + 0.5 - 100.0
    if kind == "step":
        p = np.where(x < 0, 30.0, 5.0)
    elif kind == "sqrt":  # a limb lit from the camera: brightness ~ sqrt(distance from it)
        p = 5.0 + np.where(x < 0, 8.0 * np.sqrt(np.maximum(-x, 0.0)), 0.0)
    else:  # a lamp's spot: a smooth fall-off
        p = 5.0 + 40.0 * np.exp(-0.5 * ((x + 60.0) / 35.0) ** 2)
    p = gaussian_filter1d(p, 1.7)
    return np.repeat(np.tile(p, (40, 1))[..., None], 3, axis=2).astype(np.float32)


@pytest.mark.parametrize("kind,lo,hi", [("step", 0.9, 1.1), ("sqrt", 0.35, 0.8), ("spot", -0.1, 0.1)])
def test_step_ratio_tells_a_limb_from_a_smooth_fall_off(kind, lo, hi):
    img = _profiles_image(kind)
    pts = np.column_stack([np.full(10, 99.5), np.linspace(10, 30, 10)])
    nrm = np.tile([1.0, 0.0], (10, 1))
    assert lo <= step_ratio(side_lines(img, (0.0, 0.0), pts, nrm, 1.7)) <= hi
