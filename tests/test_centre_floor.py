"""The image centre's stated covariance carries the floor the whole outline shares
(calib_core.detect.image.fit.centre_floor_px2): a large sharp ball was stated to 0.03-0.06 px
while 0.15-0.36 px off (canal seed 41 cam2 p03: 0.36 px at 0.06 px stated)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from calib_core.detect.image.blur import blur_floor_px2
from calib_core.detect.image.detect import detect_sphere_in_image
from calib_core.detect.image.fit import EDGE_WIDTH_FRACTION, SYS_FRACTION, centre_floor_px2

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_detect_image_scenes import make_background, make_camera, render, sphere_pose_at  # noqa: E402


def test_the_floor_adds_the_lopsided_limb_to_the_old_terms():
    # sharp outline: the edge-RMS share and the limb's share of its width, in quadrature
    assert np.isclose(centre_floor_px2(0.15, 70.0, 2.8), (SYS_FRACTION * 0.15) ** 2 + (EDGE_WIDTH_FRACTION * 2.8) ** 2)
    # a sharp 0.15 px outline of 2.8 px width is floored at ~0.04 px per axis, not 0.03
    assert np.sqrt(centre_floor_px2(0.15, 70.0, 2.8)) >= 0.04
    # blurred: the plateau's floor too, unless the outline is mostly hidden; no width: old terms only
    blurred = centre_floor_px2(0.3, 40.0, 7.0)
    assert np.isclose(blurred - centre_floor_px2(0.3, 40.0, 7.0, blur_allowed=False), blur_floor_px2(40.0, 7.0))
    assert np.isclose(centre_floor_px2(0.3, 40.0, float("nan")), (SYS_FRACTION * 0.3) ** 2)


def test_a_detected_sharp_ball_carries_the_limb_floor(monkeypatch):
    """The stated covariance of a detection is the fit's plus the floor: the limb's share is
    exactly (EDGE_WIDTH_FRACTION x the recorded edge width)^2 per axis."""
    from calib_core.detect.image import fit as image_fit

    cam = make_camera(960, 540, 600.0, (0.0, 0.0, 0.0, 0.0, 0.0))
    rng = np.random.default_rng(5)
    bg = make_background(cam, rng)
    img, truth = render(cam, bg, sphere_pose_at(cam, (480, 270), 1.0), 0.11, rng, noise=1.0, mesh=False, chain=False)
    det = detect_sphere_in_image(img, cam, 0.11, background=bg)
    assert det.found, det.reason
    assert np.hypot(*(det.center_uv_px - truth)) < 1.0
    width = float(det.extras["edge_width_px"])
    monkeypatch.setattr(image_fit, "EDGE_WIDTH_FRACTION", 0.0)
    bare = detect_sphere_in_image(img, cam, 0.11, background=bg)
    assert np.allclose(bare.center_uv_px, det.center_uv_px)
    added = det.cov_uv_px2 - bare.cov_uv_px2
    assert np.allclose(added, (EDGE_WIDTH_FRACTION * width) ** 2 * np.eye(2), rtol=1e-3, atol=1e-9)
    assert EDGE_WIDTH_FRACTION * width > 0.02  # a sharp outline's width (~2.5-3.5 px) gives ~0.03 px
