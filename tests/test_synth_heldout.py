"""The held-out image kinds (sports, outdoor, underwater) and the effects they use: sports-ball
patterns, outdoor textures, underwater light, camera artefacts.

Each kind renders deterministically by seed with its truth; each effect is where its model
(module docstrings) puts it.
"""

import numpy as np
import pytest

from calib_core.synth.photo import artefacts as ca
from calib_core.synth.photo import ball_patterns as bp
from calib_core.synth.photo import water as pw
from calib_core.synth.camera_render import Water
from calib_core.synth.image_cases import render_case
from calib_core.synth.photo.effects import Photo
from calib_core.synth.textures import texture_factor

SCALE = 0.2


@pytest.mark.parametrize("kind", ["sports", "outdoor", "underwater", "mesh", "tank", "dim"])
def test_kind_renders_deterministically_with_its_truth(kind):
    """Every held-out kind (both rounds): the same image and truth for the same seed, another for
    another seed, the ball inside the frame at its size, and the ball's disc differs from the same
    scene rendered without it (over the whole disc: a see-through mesh ball changes its struts'
    pixels only)."""
    a = render_case(kind, 3, SCALE)
    b = render_case(kind, 3, SCALE)
    assert np.array_equal(a.image, b.image) and a.label == b.label
    np.testing.assert_array_equal(a.true_uv_px, b.true_uv_px)
    assert a.label.startswith(kind + "/") and a.label.endswith("/s3")
    H, W = a.image.shape[:2]
    u, v = a.true_uv_px
    assert a.radius_px - 2 <= u <= W - a.radius_px + 2 and a.radius_px - 2 <= v <= H - a.radius_px + 2
    assert 30 * SCALE * 0.9 <= a.radius_px <= 0.5 * H * 1.1
    assert not np.array_equal(a.image, render_case(kind, 4, SCALE).image)
    empty = render_case(kind, 3, SCALE, with_ball=False)  # same scene without the ball
    yy, xx = np.mgrid[:H, :W]
    disc = np.hypot(xx - u, yy - v) < 0.9 * a.radius_px
    assert np.abs(a.image[disc].astype(float) - empty.image[disc]).mean() > 2.0


def test_football_pentagons_black_hexagons_white():
    normals, d, is_pent = bp.truncated_icosahedron()
    assert len(normals) == 32 and is_pent.sum() == 12
    alb = bp.football(normals, 0.01)
    assert (alb[is_pent] < 0.1).all() and (alb[~is_pent] > 0.85).all()
    q = np.random.default_rng(0).normal(size=(20000, 3))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    black = (bp.football(q, 0.0)[:, 0] < 0.1).mean()
    assert 0.1 < black < 0.3  # 12 pentagons among 20 larger hexagons


def test_basketball_tennis_volleyball_markings():
    base = np.tile([0.8, 0.34, 0.1], (3, 1))
    out = bp.basketball(np.array([[1.0, 0, 0], [0.0, 0.6, 0.8], [0.5, 0.5, 0.5 ** 0.5]]), 0.02, base)
    assert (out[:2] < 0.15).all() and np.allclose(out[2], base[2])  # on the z=0 and x=0 seams; on the leather
    curve = bp._tennis_curve(60)
    felt = np.tile([0.78, 0.88, 0.22], (60, 1))
    assert (bp.tennis(curve, 0.02, felt) > 0.85).all()
    assert np.allclose(bp.tennis(np.array([[0.0, 0.0, 1.0]]), 0.02, felt[:1]), felt[:1])
    q = np.random.default_rng(1).normal(size=(5000, 3))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    cols = ((0.92, 0.92, 0.9), (0.1, 0.25, 0.7), (0.95, 0.8, 0.15))
    out = bp.volleyball(q, 0.01, cols)
    for c in cols:
        assert np.all(np.isclose(out, c), axis=1).mean() > 0.2


@pytest.mark.parametrize("kind", ["grass", "gravel", "asphalt", "sand"])
def test_outdoor_textures_vary_and_are_deterministic(kind):
    rng = np.random.default_rng(2)
    p = np.column_stack([rng.uniform(0, 3, 4000), rng.uniform(0, 3, 4000), np.zeros(4000)])
    n = np.tile([0, 0, 1.0], (4000, 1))
    f = texture_factor(kind, p, n, 0.1, 0.6, 7)
    assert np.array_equal(f, texture_factor(kind, p, n, 0.1, 0.6, 7))
    assert f.std() > 0.05 and f.min() >= 0.05 and abs(f.mean() - 1) < 0.4


def test_underwater_light_model():
    water = Water(0.2, (0.1, 0.4, 0.5), attenuation_rgb=(0.6, 0.1, 0.2))
    tr = pw.attenuation(water, np.array([0.0, 2.0]))
    np.testing.assert_allclose(tr[0], 1.0)
    np.testing.assert_allclose(tr[1], np.exp(-2 * np.array([0.6, 0.1, 0.2])))
    photo = Photo(spot_gain=1.0, spot_pos=(0, 0, 0), spot_dir=(1, 0, 0), spot_power=10.0)
    clear = Water(0.0, (0.1, 0.4, 0.5))
    p = np.array([[1.0, 0, 0], [2.0, 0, 0], [2.0, 1.0, 0]])
    n = np.tile([-1.0, 0, 0], (3, 1))
    L = pw.spot_radiance(photo, clear, np.ones((3, 3)), p, n)
    assert L[0, 0] == pytest.approx(1.0) and L[1, 0] == pytest.approx(0.25)  # inverse square
    assert L[2, 0] < 0.5 * L[1, 0]  # off the axis
    c = pw.caustic_factor(Photo(key_dir=(0, 0, 1), caustic=1.0, caustic_scale_m=0.3, caustic_seed=3),
                          np.random.default_rng(3).uniform(0, 2, (5000, 3)))
    assert c.min() >= 0 and c.max() > 2.0 and (c < 0.5).mean() > 0.3  # bright thin network
    veil = Water(0.2, (0.1, 0.4, 0.5), spot_veil=0.5, spot_dir=(1, 0, 0), spot_power=4.0)
    B = veil.veil(np.array([[1.0, 0, 0], [0, 1.0, 0]]))
    assert B[0, 1] > B[1, 1]  # the hot spot along the light's axis


def test_marine_snow_adds_bright_specks():
    L = np.full((60, 80, 3), 0.1, np.float32)
    out = pw.marine_snow(L, np.random.default_rng(0), 30, (0.5, 2.0), 0.8, 2.0)
    assert out.max() > 0.3 and (out >= 0.1 - 1e-6).all() and np.median(out) < 0.15


def test_camera_artefacts_are_centred_and_jpeg_is_lossy():
    k = ca.disc_kernel(2.5)
    assert k.sum() == pytest.approx(1.0)
    yy, xx = np.mgrid[: k.shape[0], : k.shape[1]]
    c = (k.shape[0] - 1) / 2
    assert (k * xx).sum() == pytest.approx(c) and (k * yy).sum() == pytest.approx(c)
    img = np.random.default_rng(0).integers(0, 256, (64, 64, 3), dtype=np.uint8)
    assert np.array_equal(ca.jpeg(img, 0), img)
    j = ca.jpeg(img, 70)
    assert j.shape == img.shape and not np.array_equal(j, img)
    smooth = np.tile(np.linspace(0, 255, 64).astype(np.uint8)[None, :, None], (64, 1, 3))
    assert np.abs(ca.jpeg(smooth, 70).astype(float) - smooth).mean() < 3.0
    rad = np.zeros((21, 21, 3), np.float32)
    rad[10, 10] = 1.0
    out = ca.optical_blur(rad, Photo(shake_px=(4.0, 0.0)))
    cols = out[:, :, 0].sum(axis=0)
    assert (cols * np.arange(21)).sum() / cols.sum() == pytest.approx(10.0, abs=1e-4)
    assert np.array_equal(ca.optical_blur(rad, Photo()), rad)
