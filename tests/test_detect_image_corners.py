"""Small closed shapes that are not balls: corners and flat sides (issue 11, cause 7).

A square tile bounded by grout, fitted by the tight refit, keeps its stretches near the tangent
points inside the 1 px inlier band and looked round (tank ball-free images scored 0.90-0.97).
Its inlier residuals still follow its shape around the outline (harmonics 2-8, which a
sphere's cone cannot absorb): calib_core.detect.image.corners.
"""

import cv2
import numpy as np
import pytest

from calib_core.camera import CameraModel
from calib_core.detect.image.corners import (MAX_GAP_DEG, MAX_WOBBLE_FRACTION, largest_gap_deg, outline_wobble,
                                             wobble)
from calib_core.detect.image.detect import detect_sphere_in_image

W, H = 640, 480
SS = 4
TILE_CENTRE_PX = (145.0, 87.0)  # the dark tile's


def _cam():
    return CameraModel(W, H, np.array([[520.0, 0, W / 2], [0, 520.0, H / 2], [0, 0, 1]]))


def _square_radius(phase, half, corner):
    """Distance from a rounded square's centre to its boundary along ``phase`` (rad)."""
    t = np.mod(phase + np.pi / 4, np.pi / 2) - np.pi / 4  # angle from the nearest side's normal
    r = half / np.cos(t)
    # on the rounded corner (centre at (half - corner) on both axes): ray-circle intersection
    c = (half - corner) * np.array([1.0, 1.0])
    d = np.stack([np.cos(np.abs(t)), np.sin(np.abs(t))], axis=1)
    b = d @ c
    rc = b + np.sqrt(np.maximum(b ** 2 - (c @ c - corner ** 2), 0.0))
    on_corner = (r * np.cos(np.abs(t)) > half - corner) & (r * np.sin(np.abs(t)) > half - corner)
    return np.where(on_corner, rc, r)


def test_a_noisy_circle_has_no_corners_a_square_has():
    rng = np.random.default_rng(0)
    phase = np.linspace(0, 2 * np.pi, 120, endpoint=False)
    circle = wobble(phase, rng.normal(0, 0.4, phase.size), 20.0)
    assert circle is not None and not circle.has_corners
    assert circle.excess_fraction < 0.2 * MAX_WOBBLE_FRACTION
    # a square's points within the tight refit's 1 px band of the best circle (the tangent stretches)
    r_sq = _square_radius(phase, 25.0, 0.0)
    res = r_sq - 26.0
    keep = np.abs(res) <= 1.0
    square = wobble(phase[keep], res[keep] + rng.normal(0, 0.2, keep.sum()), 26.0)
    assert square is not None and square.has_corners, square
    assert "corners" in square.reason


def test_a_partial_outline_gives_no_reading():
    phase = np.linspace(0, 1.2 * np.pi, 80)  # 144 deg of the outline missing
    assert largest_gap_deg(phase) > MAX_GAP_DEG
    assert wobble(phase, np.zeros(80), 30.0) is None
    assert outline_wobble(np.arange(10), 64, np.zeros(10), 30.0) is None  # too few inliers


def _disc_cover(centre, r):
    ss = 8
    m = np.zeros((H * ss, W * ss), np.uint8)
    cv2.circle(m, (int(round(centre[0] * ss + (ss - 1) / 2)), int(round(centre[1] * ss + (ss - 1) / 2))),
               int(r * ss), 255, -1)
    return cv2.resize(m.astype(np.float32) / 255, (W, H), interpolation=cv2.INTER_AREA)[..., None]


def _tiles(rng, corner_px, side_px=50, grout_px=8, blur_px=1.5):
    """A wall of light tiles with grout, one dark tile (column 2, row 1: centre (145, 87) px),
    corners rounded by ``corner_px``; supersampled, then defocused."""
    img = np.empty((H * SS, W * SS, 3), np.float32)
    img[:] = (90, 120, 125)
    pitch = side_px + grout_px
    q = lambda v: int(round(v))  # noqa: E731
    for j, y0 in enumerate(range(0, H, pitch)):
        for i, x0 in enumerate(range(0, W, pitch)):
            col = (np.array([60, 170, 185]) * rng.uniform(0.92, 1.08)).tolist()
            col = col if (i, j) != (2, 1) else [25, 70, 95]
            a = np.array([x0, y0], float) + grout_px / 2
            p0, p1, c = a * SS, (a + side_px) * SS, corner_px * SS
            cv2.rectangle(img, (q(p0[0] + c), q(p0[1])), (q(p1[0] - c), q(p1[1])), col, -1)
            cv2.rectangle(img, (q(p0[0]), q(p0[1] + c)), (q(p1[0]), q(p1[1] - c)), col, -1)
            if c > 0:
                for cx, cy in ((p0[0] + c, p0[1] + c), (p1[0] - c, p0[1] + c), (p0[0] + c, p1[1] - c),
                               (p1[0] - c, p1[1] - c)):
                    cv2.circle(img, (q(cx), q(cy)), q(c), col, -1)
    img = cv2.resize(img, (W, H), interpolation=cv2.INTER_AREA)
    return cv2.GaussianBlur(img, (0, 0), blur_px)


@pytest.mark.parametrize("corner_px", [0.0, 5.0])
def test_a_dark_tile_is_not_a_ball_and_a_ball_of_its_size_beside_it_is(corner_px):
    """Main found the dark tile (half-side 25 px) at 0.98 with either corner; the ball (r 28 px,
    on the optical axis: its outline is a circle centred on the principal point) scored 0.995."""
    rng = np.random.default_rng(7)
    wall = _tiles(rng, corner_px)
    noise = rng.normal(0, 2.0, (H, W, 3))
    det = detect_sphere_in_image(np.clip(wall + noise, 0, 255).astype(np.uint8), _cam(), 0.1)
    on_tile = det.found and np.hypot(*(det.center_uv_px - TILE_CENTRE_PX)) < 10.0
    assert not on_tile or det.score < 0.5, (det.center_uv_px, det.radius_px, det.score)
    cover = _disc_cover((W / 2, H / 2), 28.0)
    with_ball = wall * (1 - cover) + np.float32((25, 70, 95)) * cover
    det = detect_sphere_in_image(np.clip(with_ball + noise, 0, 255).astype(np.uint8), _cam(), 0.1)
    assert det.found, det.reason
    assert np.hypot(*(det.center_uv_px - (W / 2, H / 2))) < 0.5
    assert det.score > 0.9


def test_a_gap_in_the_outline_widens_the_limit():
    """Harmonics of a partly seen outline are less determined (a dim ball seen over 280 deg read
    0.059 of its radius): the limit grows with the square root of the noise's inflation."""
    rng = np.random.default_rng(1)
    full = wobble(np.linspace(0, 2 * np.pi, 250, endpoint=False), rng.normal(0, 0.25, 250), 100.0)
    assert full.inflation == pytest.approx(1.0, abs=0.05)
    assert full.limit_fraction == pytest.approx(MAX_WOBBLE_FRACTION, rel=0.03)
    arc = wobble(np.linspace(0, np.radians(280), 250), rng.normal(0, 0.25, 250), 100.0)
    assert arc.inflation > 5.0
    assert arc.limit_fraction == pytest.approx(MAX_WOBBLE_FRACTION * np.sqrt(arc.inflation))
