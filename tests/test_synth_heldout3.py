"""The third round's held-out image kinds (mesh, tank, dim): their effects, see-through shells,
mirrors seen from under water (Fresnel, total internal reflection), low-light exposure, each where
its model (module docstrings) puts it. That each kind renders by seed with its truth is tested
with the other held-out kinds (tests/test_synth_heldout.py)."""

import numpy as np
import pytest

from calib_core.synth.camera_render import Water
from calib_core.synth.photo import mirrors
from calib_core.synth.photo.dim import _contrast_exposure
from calib_core.synth.photo.see_through import OpenShell, fibonacci_sphere
from calib_core.synth.scene import Rect, Scene, Sphere, raycast


def _shoot(shell, n=400):
    """Fraction of rays through the shell's disc (seen from 2 m) that hit it, at the centre
    and near the limb."""
    lim = np.arcsin(shell.radius_m / 2.0)
    out = []
    for lo, hi in ((0.0, 0.7), (0.985, 0.999)):
        rng = np.random.default_rng(0)
        a = lim * np.sqrt(rng.uniform(lo ** 2, hi ** 2, n))
        p = rng.uniform(0, 2 * np.pi, n)
        d = np.column_stack([np.cos(a), np.sin(a) * np.cos(p), np.sin(a) * np.sin(p)])
        t, _, _ = raycast(Scene((shell,)), np.array([-2.0, 0, 0]), d)
        out.append(np.isfinite(t).mean())
    return out


@pytest.mark.parametrize("kw", [dict(pattern="lattice", n_lat=8, n_lon=12, wire_m=0.004),
                                dict(pattern="net", n_lon=12, twist=1.0, wire_m=0.004),
                                dict(pattern="holes", n_holes=12, hole_deg=20.0, wire_m=0.003)])
def test_open_shells_show_the_background_and_pile_up_at_the_limb(kw):
    shell = OpenShell((0.0, 0, 0), 0.2, samples=16, **kw)
    centre, limb = _shoot(shell)
    assert centre < 0.95  # the background shows through the middle
    assert limb > 0.6  # seen edge-on, struts pile up (a wiffle ball's holes notch its outline)
    if kw["pattern"] != "holes":
        assert limb > centre


def test_fibonacci_sphere_is_even():
    q = fibonacci_sphere(50)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0)
    assert np.abs(q.mean(axis=0)).max() < 0.05


def test_fresnel_total_internal_reflection_and_snells_window():
    crit = np.arcsin(1 / mirrors.N_WATER)
    R = mirrors.fresnel_reflectance(np.cos(np.array([0.0, crit - 0.05, crit + 0.01, 1.2])))
    assert R[0] == pytest.approx(((1.33 - 1) / 2.33) ** 2, rel=1e-6)  # ~2 % at normal incidence
    assert R[1] < 0.5 and R[2] == 1.0 and R[3] == 1.0


def test_reflected_pose_sees_the_mirror_image():
    T = np.eye(4)
    T[:3, 3] = [0.3, -0.2, 0.0]
    Tm = mirrors.reflect_pose(T, (0, 0, 1.0), (0, 0, -1.0))
    assert np.linalg.det(Tm[:3, :3]) == pytest.approx(-1.0)
    np.testing.assert_allclose(Tm[:3, 3], [0.3, -0.2, 2.0])
    # a ball below a mirror at z = 1: seen from the reflected pose where the mirror shows it
    ball = Sphere((2.0, -0.2, 0.6), 0.1)
    d_up = np.array([2.0 - 0.3, 0.0, 1.4]) / np.linalg.norm([1.7, 0, 1.4])  # towards its image at z = 1.4
    d_cam = np.linalg.solve(T[:3, :3], d_up)
    t, hit, _ = raycast(Scene((ball,)), Tm[:3, 3], (Tm[:3, :3] @ d_cam)[None])
    assert hit[0] == 0


def test_mirror_composite_puts_the_ball_above_the_surface():
    from calib_core.camera import CameraModel
    from calib_core.synth.camera_render import render_radiance
    from calib_core.synth.scene import Material
    cam = CameraModel(80, 60, np.array([[60.0, 0, 40], [0, 60.0, 30], [0, 0, 1]]), np.zeros(5))
    T = np.eye(4)
    T[:3, :3] = np.column_stack([(0, -1.0, 0), (0, 0, -1.0), (1.0, 0, 0)])  # looking along +x
    ball = Sphere((2.0, 0, 0.2), 0.1, Material((1.0, 0.0, 0.0)), tag="target")
    scene = Scene((ball, Rect((0, 0, 0.5), (0, 0, -1.0), tag="surface")))
    water = Water(0.0, (0.0, 0.1, 0.1), up_gain=0.0, side_gain=0.0, ambient=1.0, diffuse=0.0)
    L, hit = render_radiance(scene, cam, T, water, aa=1)
    out = mirrors.composite_mirror(L, hit, scene, mirrors.Mirror("surface", (0, 0, 0.5), (0, 0, -1.0), (1, 1, 1)),
                                   cam, T, water, None, aa=1)
    v_img = int(round(30 - 60 * 0.8 / 2))  # the image of the ball at z = 0.8 (past the critical angle)
    assert out[v_img, 40, 0] > 0.9 and out[v_img, 40, 1] < 0.05 and L[v_img, 40, 1] > 0.3  # red ball, not the grey plane
    v_gap = int(round(30 - 60 * 0.5 / 2))  # the surface between ball and image: the mirrored water
    assert out[v_gap, 40, 0] < 0.1


def test_dim_exposure_sets_the_ball_contrast():
    rng = np.random.default_rng(1)
    L = np.full((80, 80, 3), 0.02)
    hit = np.full((80, 80), 0)
    yy, xx = np.mgrid[:80, :80]
    ball = np.hypot(xx - 40, yy - 40) < 15
    hit[ball] = 1
    L[ball] = 0.01
    e = _contrast_exposure(rng, L, hit, [1])
    diff = 255 * e * 0.01
    level = 255 * e * 0.02
    assert (10 - 1e-6 <= diff <= 40 + 1e-6) or level <= 70 + 1e-6
    assert level <= 70 + 1e-6
