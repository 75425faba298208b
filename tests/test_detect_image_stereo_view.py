"""Round-outline votes in the stereographic view: a ball in a wide lens's corner (issue 11).

Behind a 90 deg+ lens a ball near a corner is an ellipse 1.3-1.7x longer one way than the other
(the pinhole's off-axis stretch and the lens's distortion); circle votes do not meet at its
centre and no cue put a candidate on it (`chair` s1024, a grey ball on a seat near the top
right corner: "no round outline"). In the stereographic view every sphere is a circle.
"""

import cv2
import numpy as np
import pytest

import calib_core.detect.image.detect as im
from calib_core.camera import CameraModel
from calib_core.detect.image import conformal as cf
from calib_core.detect.image.region import choose_scale, downscale
from calib_core.detect.image.votes import candidates_by_votes
from calib_core.synth.image_cases import render_case


def _wide_cam(k1=0.12, k2=-0.03):
    """960 x 540, fx 463 px (92 deg across), with radial distortion."""
    K = np.array([[463.0, 0, 474.0], [0, 464.0, 279.0], [0, 0, 1]])
    return CameraModel(960, 540, K, np.array([k1, k2, 0.0, 0.0, 0.0]))


def _narrow_cam():
    K = np.array([[1400.0, 0, 480.0], [0, 1400.0, 270.0], [0, 0, 1]])
    return CameraModel(960, 540, K)


def _silhouette_rays(centre_dir, half_angle_rad, n=90):
    """Unit rays of a sphere's silhouette cone about ``centre_dir``."""
    c = np.asarray(centre_dir, float) / np.linalg.norm(centre_dir)
    a = np.cross(c, [0.0, 1.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(c, a)
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return (np.cos(half_angle_rad) * c[None, :]
            + np.sin(half_angle_rad) * (np.cos(t)[:, None] * a + np.sin(t)[:, None] * b))


def test_view_round_trip():
    rng = np.random.default_rng(0)
    d = rng.normal(size=(200, 3))
    d[:, 2] = np.abs(d[:, 2]) + 0.2
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    assert np.allclose(cf.view_to_rays(cf.rays_to_view(d)), d, atol=1e-12)


@pytest.mark.parametrize("off_axis_deg", [0.0, 25.0, 50.0, 70.0])
def test_a_sphere_is_a_circle_in_the_view(off_axis_deg):
    th = np.radians(off_axis_deg)
    q = cf.rays_to_view(_silhouette_rays([np.sin(th), 0.3 * np.sin(th), np.cos(th)], np.radians(6.0)))
    (cx, cy), r = cv2.minEnclosingCircle(q.astype(np.float32))
    # a least-squares circle through the points: every point on it
    A = np.column_stack([2 * q, np.ones(len(q))])
    sol, *_ = np.linalg.lstsq(A, (q ** 2).sum(axis=1), rcond=None)
    centre, rad = sol[:2], np.sqrt(sol[2] + sol[:2] @ sol[:2])
    assert np.ptp(np.linalg.norm(q - centre, axis=1)) < 1e-9 * rad


def test_elongation_wide_and_narrow():
    # an undistorted pinhole stretches a small sphere radially by 1 / cos(theta): the largest at
    # the frame point farthest off the axis (the grid's corner, 0.5 px in)
    for cam in (_narrow_cam(), _wide_cam(0.0, 0.0)):
        corner = (np.array([0.5, 0.5]) - [cam.cx, cam.cy]) / [cam.fx, cam.fy]
        expected = np.sqrt(1.0 + corner @ corner)  # 1 / cos(theta)
        assert cf.view_elongation(cam) == pytest.approx(expected, rel=0.01)
    assert cf.view_elongation(_narrow_cam()) < im.STEREO_MIN_ELONGATION
    assert cf.view_elongation(_wide_cam(0.0, 0.0)) > 1.5  # the pinhole's stretch alone
    assert cf.view_elongation(_wide_cam(0.12, 0.0)) > cf.view_elongation(_wide_cam(0.0, 0.0))


def _drawn_ellipse_ball(cam, centre_dir, half_angle_rad, seed=0):
    """A grey ball drawn exactly (its silhouette projected through the lens) on brick-like
    texture; returns (image, true centre px: the projection of the sphere's centre)."""
    rng = np.random.default_rng(seed)
    img = np.zeros((cam.height_px, cam.width_px, 3), np.uint8)
    img[:] = (150, 70, 50)
    for y in range(0, cam.height_px, 14):  # mortar lines, offset per course
        img[y:y + 3] = (200, 190, 180)
        for x in range(((y // 14) % 2) * 20, cam.width_px, 40):
            img[y:y + 14, x:x + 3] = (200, 190, 180)
    sil = cam.project(_silhouette_rays(centre_dir, half_angle_rad, 360))
    cv2.fillPoly(img, [np.round(sil * 16).astype(np.int32)], (110, 110, 115), lineType=cv2.LINE_AA, shift=4)
    img = np.clip(cv2.GaussianBlur(img, (0, 0), 0.8) + rng.normal(0, 2.0, img.shape), 0, 255).astype(np.uint8)
    true_uv = cam.project(np.asarray(centre_dir, float)[None, :])[0]
    return img, sil, true_uv


def test_view_votes_find_the_corner_ellipse_with_more_of_its_outline():
    cam = _wide_cam()
    # 40 deg off the axis towards the top right corner, whole in the frame: aspect 1.43 in raw px
    centre_dir = cam.rays(np.array([[850.0, 120.0]]))[0]
    img, sil, true_uv = _drawn_ellipse_ball(cam, centre_dir, np.radians(5.0))
    assert cam.in_image(sil, 10.0).all()
    (ex, ey), (d1, d2), _ = cv2.fitEllipse(sil.astype(np.float32))
    assert max(d1, d2) / min(d1, d2) > 1.4  # the case is what it says
    outline_centre = np.array([ex, ey])  # (a candidate places the outline; the fit, the centre)
    r_bounds = (10.0, 300.0)
    s = choose_scale(r_bounds[0], cam.width_px)
    small = downscale(img, s)
    raw = candidates_by_votes(small, s, r_bounds, max_candidates=8)
    view = cf.stereographic_view(cam, s)
    got = cf.candidates_in_view(small, cam, view, r_bounds, 8)
    near = [c for c in got if np.hypot(*(c.centre_px - outline_centre)) < 0.1 * c.radius_px]
    assert near, [c.centre_px for c in got]
    c = near[0]
    assert c.axes_px[0] / c.axes_px[1] == pytest.approx(max(d1, d2) / min(d1, d2), rel=0.1)  # the ellipse it is
    assert c.source == "votes-stereo"
    # in the view the whole outline votes at one centre: a larger share than in the raw image
    raw_near = [o.strength for o in raw if np.hypot(*(o.centre_px - outline_centre)) < 0.1 * o.radius_px]
    print("view vote", c.strength, "raw votes near", raw_near)
    assert c.strength > max(raw_near, default=0.0)


@pytest.fixture(scope="module")
def corner_chair():
    return render_case("chair", 1024, 0.5)


def test_ball_in_a_wide_lens_corner_found_with_the_view(corner_chair):
    case = corner_chair
    det = im.detect_sphere_in_image(case.image, case.cam, case.radius_m)
    assert det.found, det.reason
    assert np.hypot(*(det.center_uv_px - case.true_uv_px)) < 1.0


def test_ball_in_a_wide_lens_corner_missed_without_the_view(corner_chair, monkeypatch):
    monkeypatch.setattr(im, "STEREO_MIN_ELONGATION", np.inf)
    case = corner_chair
    det = im.detect_sphere_in_image(case.image, case.cam, case.radius_m)
    assert not det.found or np.hypot(*(det.center_uv_px - case.true_uv_px)) > 3.0


def test_the_same_wide_lens_scene_without_the_ball_finds_nothing():
    # the cue runs on every image where nothing clear was found: on the ball-free scene it must
    # not make a round outline of the seat, the wall's edge or the brick courses
    case = render_case("chair", 1024, 0.5, with_ball=False)
    assert im.view_elongation(case.cam) >= im.STEREO_MIN_ELONGATION  # the cue looks here
    det = im.detect_sphere_in_image(case.image, case.cam, case.radius_m)
    assert not det.found, (det.center_uv_px, det.score)
