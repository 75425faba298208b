"""Photographic effects of the renderer (calib_core.synth.photo.effects) and the image cases using them.

Each effect is checked to be present where the model puts it (and absent where it should be),
the default renderer is unchanged, and the cases are deterministic.
"""

import numpy as np
import pytest

from calib_core.camera import CameraModel
from calib_core.synth.photo import effects as ph
from calib_core.synth.camera_render import RenderOptions, finish_image, render_radiance
from calib_core.synth.image_cases import render_case
from calib_core.synth.room import AIR
from calib_core.synth.scene import Material, Rect, Scene, Sphere

W, H = 160, 120


def _scene_and_cam():
    """A ball 0.2 m resting on a floor, the camera 2 m in front looking along +x (world z up)."""
    cam = CameraModel(W, H, np.array([[150.0, 0, 79.5], [0, 150.0, 59.5], [0, 0, 1]]), np.zeros(5))
    T_wc = np.eye(4)
    T_wc[:3, :3] = np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], float)  # cam z -> world x, cam y -> -z
    ball = Sphere((2.0, 0.0, 0.0), 0.2, Material((0.5, 0.5, 0.5), 0.9), tag="target")
    floor = Rect((0, 0, -0.2), (0, 0, 1), material=Material((0.6, 0.6, 0.6), 0.5), tag="floor")
    return Scene((ball, floor)), cam, T_wc


def test_default_photo_is_the_plain_lambert_model():
    scene, cam, T = _scene_and_cam()
    L0, hit0 = render_radiance(scene, cam, T, AIR, aa=2)
    L1, hit1 = render_radiance(scene, cam, T, AIR, aa=2, photo=ph.Photo())
    assert np.array_equal(hit0, hit1)
    np.testing.assert_allclose(L0, L1, atol=1e-12)


def test_contact_and_cast_shadow_darken_the_floor_under_the_ball():
    scene, cam, T = _scene_and_cam()
    p = ph.Photo(key_dir=(-0.3, 0.0, 1.0), occluders=(((2.0, 0.0, 0.0), 0.2),))
    L0, hit = render_radiance(scene, cam, T, AIR, aa=1, photo=ph.Photo(key_dir=p.key_dir))
    L1, _ = render_radiance(scene, cam, T, AIR, aa=1, photo=p)
    floor = hit == 1
    ratio = L1[..., 1][floor] / L0[..., 1][floor]
    assert ratio.min() < 0.3  # the contact patch under the ball goes dark
    v_floor = np.nonzero(floor)[0]
    far = floor & (np.arange(H)[:, None] >= v_floor.max() - 2)  # the floor nearest the camera
    assert np.all(L1[far] >= 0.97 * L0[far])
    ball = hit == 0
    assert np.allclose(L1[ball], L0[ball])  # the ball does not shadow itself twice


def test_visibility_and_occlusion_formulas():
    p = ph.Photo(key_dir=(0, 0, 1), softness=0.01, occluders=(((0, 0, 1.0), 0.5),), ao=1.0)
    pts = np.array([[0, 0, 0.0], [2.0, 0, 0.0], [0, 0, 2.0]])
    vis = ph.key_visibility(p, pts)
    assert vis[0] == 0 and vis[1] == 1 and vis[2] == 1  # under, beside, above the sphere
    n = np.tile([0, 0, 1.0], (3, 1))
    keep = ph.ambient_occlusion(p, np.array([[0, 0, 0.5], [0, 0, 0.0], [5.0, 0, 0.0]]), n)
    assert keep[0] == pytest.approx(0.0) and keep[1] == pytest.approx(0.75) and keep[2] > 0.99


def test_glossy_highlight_saturates_with_bloom():
    scene, cam, T = _scene_and_cam()
    look = ph.BallLook((2.0, 0, 0), 0.2, ks=1.5, shininess=80)
    p = ph.Photo(key_dir=(-1.0, 0.3, 0.6), ball=look, bloom_px=2.0)
    L, hit = render_radiance(scene, cam, T, AIR, aa=2, photo=p)
    opts = RenderOptions(aa=2, blur_sigma_px=0.5, noise_dn=0.0, shot_gain=0.0)
    img = finish_image(L, opts, np.random.default_rng(0), p)
    matte = finish_image(render_radiance(scene, cam, T, AIR, aa=2, photo=ph.Photo(key_dir=p.key_dir))[0],
                         opts, np.random.default_rng(0), ph.Photo(key_dir=p.key_dir))
    sat = (img == 255).all(axis=2)
    assert sat.any() and not (matte == 255).all(axis=2).any()
    v, u = np.nonzero(sat)
    assert (hit[v, u] == 0).all()  # the highlight is on the ball


def test_markings_paint_panels_seam_logo_and_valve():
    look = ph.BallLook((0, 0, 0), 1.0, axis=(0, 0, 1), panels=6, panel_rgb=((1, 0, 0), (0, 0, 1)),
                       seam_dir=(1, 0, 0), logo_dir=(0, 1, 0), valve_dir=(0, -1, 0))
    rng = np.random.default_rng(1)
    q = rng.normal(0, 1, (5000, 3))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    alb = ph.marking_albedo(look, q, np.full((5000, 3), 0.5))
    colours = {tuple(np.round(a, 2)) for a in alb}
    assert {(1.0, 0.0, 0.0), (0.0, 0.0, 1.0), tuple(np.round(ph.WHITE, 2))} <= colours
    assert (alb.max(axis=1) < 0.15).sum() > 20  # seam / logo strokes
    valve = q @ np.array([0, -1.0, 0]) > np.cos(np.deg2rad(3.0))
    assert np.allclose(alb[valve], np.asarray(ph.WHITE) * 0.35)


def test_vignetting_and_white_balance():
    img = np.full((H, W, 3), 0.5, np.float32)
    out = ph.apply_lens_and_exposure(img, ph.Photo(vignette=0.4, exposure=2.0, wb_gains=(1.1, 1.0, 0.9)))
    assert out[H // 2, W // 2, 1] == pytest.approx(1.0, abs=1e-3)
    assert out[0, 0, 1] == pytest.approx(0.6, abs=1e-3)
    assert out[H // 2, W // 2, 0] > out[H // 2, W // 2, 2]


def test_motion_blur_keeps_the_centre_and_streaks_the_ball():
    yy, xx = np.mgrid[0:H, 0:W]
    mask = ((xx - 80.0) ** 2 + (yy - 60.0) ** 2 <= 15 ** 2).astype(np.float32)
    L = np.where(mask[..., None] > 0, 1.0, 0.2).astype(np.float32) * np.ones(3, np.float32)
    L0 = np.full((H, W, 3), 0.2, np.float32)
    out = ph.motion_composite(L, L0, mask, (12.0, 0.0))[..., 0]
    w = out - 0.2
    assert np.sum(w * xx) / np.sum(w) == pytest.approx(80.0, abs=0.05)
    assert np.sum(w) == pytest.approx(np.sum(L[..., 0] - 0.2), rel=1e-3)  # radiance is conserved
    assert out[60, 80 + 19] > 0.25 and out[60 + 18, 80] < 0.21  # streaked along x only


@pytest.mark.parametrize("kind", ["glossy", "panels", "motion"])
def test_cases_are_deterministic(kind):
    a, b = render_case(kind, 3, 0.12), render_case(kind, 3, 0.12)
    assert np.array_equal(a.image, b.image) and np.array_equal(a.true_uv_px, b.true_uv_px)
    c = render_case(kind, 3, 0.12, with_ball=False)
    assert c.image.shape == a.image.shape and not np.array_equal(c.image, a.image)


@pytest.mark.parametrize("seed", [0, 6])
def test_glossy_ball_found_not_its_highlight(seed):
    """A glossy ball (s6: black, on a chair, its shadow on the seat) with a clipped highlight:
    the highlight is a clean round outline itself, 10-30 px off the ball's centre; the ball
    must be found, not the highlight."""
    from calib_core.detect.image.detect import detect_sphere_in_image

    case = render_case("glossy", seed, 0.3)
    det = detect_sphere_in_image(case.image, case.cam, case.radius_m)
    assert det.found, det.reason
    assert np.hypot(*(det.center_uv_px - case.true_uv_px)) < 0.5
    assert det.radius_px == pytest.approx(case.radius_px, rel=0.05)
