"""Fusion: projection, segmentation masks, overlays, coloured clouds with occlusion.

Scenes are built here with numpy (planes, a pipe, a sphere) and images are ray-cast,
so every expected colour and pixel is known exactly.
"""

from __future__ import annotations

import numpy as np
import pytest

from calib_core import fusion as F
from calib_core.camera import CameraModel
from calib_core.geometry import T_from_rotvec, invert_T, transform_points

RED, BLUE = np.array([230, 20, 20]), np.array([20, 40, 220])


def _cam(w=320, h=240, f=300.0, dist=(0, 0, 0, 0, 0)):
    return CameraModel(w, h, [[f, 0, w / 2 - 0.5], [0, f, h / 2 - 0.5], [0, 0, 1]], dist, "cam")


def _T(seed):
    rng = np.random.default_rng(seed)
    return T_from_rotvec(rng.normal(size=3) * 0.8, rng.normal(size=3) * 0.5)


def _grid(x0, x1, y0, y1, z, step):
    xs, ys = np.meshgrid(np.arange(x0, x1 + 1e-9, step), np.arange(y0, y1 + 1e-9, step))
    return np.column_stack([xs.ravel(), ys.ravel(), np.full(xs.size, z)])


def _pixel_rays(cam):
    vv, uu = np.mgrid[0:cam.height_px, 0:cam.width_px]
    return cam.rays(np.column_stack([uu.ravel(), vv.ravel()]).astype(float))


# ---------------------------------------------------------------- projection
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_project_cloud_matches_camera_model(seed):
    rng = np.random.default_rng(seed)
    cam = _cam(640, 480, 500.0, dist=(-0.2, 0.05, 0.001, -0.002, 0.01))
    T = _T(seed)
    P_cam = np.column_stack([rng.uniform(-3, 3, 5000), rng.uniform(-2, 2, 5000), rng.uniform(-1, 5, 5000)])
    P = transform_points(invert_T(T), P_cam)
    uv, depth, valid = F.project_cloud(P, T, cam)
    ref = cam.project(P_cam)
    np.testing.assert_allclose(depth, P_cam[:, 2], atol=1e-5)
    inside = cam.in_image(ref) & (P_cam[:, 2] > 1e-3)
    near_fov = np.abs(P_cam[:, 0] / P_cam[:, 2]) < 1.0
    assert np.array_equal(valid[near_fov], inside[near_fov])
    assert np.nanmax(np.abs(uv[valid] - ref[valid])) < 2e-3
    assert np.isnan(uv[~valid]).all() and not valid[P_cam[:, 2] <= 0].any()


def test_project_cloud_refuses_distortion_fold_over_and_nonfinite():
    cam = _cam(640, 480, 500.0, dist=(-0.1, 0.0, 0, 0, 0))  # radial factor turns negative at r^2 = 10
    P = np.array([[3.1, 0.0, 1.0], [0.1, 0.0, 1.0], [np.nan, 0, 1], [np.inf, 0, 1], [0, 0, 0]])
    fold = cam.project(P[:1])
    assert cam.in_image(fold)[0]  # the raw polynomial folds this far-off point into the image
    _, _, valid = F.project_cloud(P, np.eye(4), cam)
    assert valid.tolist() == [False, True, False, False, False]
    uv, depth, valid = F.project_cloud(np.zeros((0, 3)), np.eye(4), cam)
    assert uv.shape == (0, 2) and depth.shape == (0,) and valid.shape == (0,)


# -------------------------------------------------------------- segmentation
@pytest.mark.parametrize("radius", [0.0, 2.0, 3.5, 6.0, 12.0, 25.0])
def test_segmentation_mask_is_the_radius_disk(radius):
    cam = _cam(200, 150)
    rng = np.random.default_rng(int(radius * 10))
    uv = np.column_stack([rng.integers(0, 200, 6), rng.integers(0, 150, 6)]).astype(float)
    uv = np.vstack([uv, [[np.nan, np.nan], [500, 20]]])  # ignored
    mask = F.segmentation_mask(cam, uv, radius)
    vv, uu = np.mgrid[0:150, 0:200]
    d = np.min(np.hypot(uu[..., None] - uv[None, None, :6, 0], vv[..., None] - uv[None, None, :6, 1]), axis=2)
    tol = 0.0 if radius <= 8 else 0.03 * radius + 0.5
    assert mask[d <= max(radius - tol, 0)].all()
    assert not mask[d > radius + tol].any()


def _sphere_scene(seed, n=20000):
    rng = np.random.default_rng(seed)
    centre_cam = np.array([rng.uniform(-0.3, 0.3), rng.uniform(-0.2, 0.2), rng.uniform(1.5, 3.0)])
    radius = 0.11
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return centre_cam, radius, centre_cam + radius * d


@pytest.mark.parametrize("seed", [3, 4])
def test_mask_of_sphere_cloud_covers_the_sphere_pixels(seed):
    cam = _cam(320, 240, 300.0, dist=(-0.05, 0.01, 0, 0, 0))
    T = _T(seed)
    c, r, P_cam = _sphere_scene(seed)
    uv, _, valid = F.project_cloud(transform_points(invert_T(T), P_cam), T, cam)
    mask = F.segmentation_mask(cam, uv, 3.0, valid)
    rays = _pixel_rays(cam)
    # pixels whose ray passes through the sphere (closest approach < r)
    along = rays @ c
    miss = np.linalg.norm(rays * along[:, None] - c, axis=1)
    sphere_px = (miss < r * 0.97).reshape(cam.height_px, cam.width_px)
    far_px = (miss > r + 6 * c[2] / 300.0).reshape(cam.height_px, cam.width_px)
    assert sphere_px.sum() > 50
    assert mask[sphere_px].mean() > 0.99
    assert not mask[far_px].any()


# ------------------------------------------------------------------- overlay
def test_overlay_blends_inside_only_and_draws_outline():
    img = np.full((60, 80, 3), 100, np.uint8)
    mask = np.zeros((60, 80), bool)
    mask[20:40, 30:50] = True
    out = F.overlay(img, mask, colour=(0, 200, 0), opacity=0.5, outline=False)
    assert np.array_equal(out[~mask], img[~mask])
    np.testing.assert_allclose(out[30, 40], [50, 150, 50], atol=1)
    assert np.array_equal(img, np.full((60, 80, 3), 100, np.uint8))  # input untouched
    out2 = F.overlay(img, mask, colour=(0, 200, 0), opacity=0.0, outline=True)
    assert np.array_equal(out2[30, 40], img[30, 40]) and (out2[20, 30:50] != 100).any()


def test_draw_detection_marks_centre_ellipse_and_reprojection():
    img = np.zeros((1080, 1920, 3), np.uint8)
    out = F.draw_detection(img, (960.3, 540.7), [960.3, 540.7, 200, 180, 15.0], (1000.0, 560.0))
    assert not img.any()
    assert out[541, 940:980].any()  # the cross
    assert out[540, 1055:1065].any() or out[540, 855:865].any()  # the ellipse (semi-axis ~100 px)
    assert (out[560, 990:1010] > 0).any()  # the reprojected centre
    assert out[0:300, 0:300].sum() == 0
    same = F.draw_detection(img, None, None, None)
    assert not same.any()


def test_sample_bilinear():
    img = np.zeros((4, 5, 3), np.uint8)
    img[:, 2:] = 200
    s = F.sample_bilinear(img, np.array([[1.5, 1.0], [3.0, 2.0], [0.0, 0.0]]))
    np.testing.assert_allclose(s, [[100] * 3, [200] * 3, [0] * 3], atol=1)
    big = F.sample_bilinear(img, np.tile([[3.0, 1.0]], (10000, 1)))
    assert big.shape == (10000, 3) and (big == 200).all()


# ------------------------------------------------------------------ colouring
def _two_planes(step_front=0.01, step_back=0.015):
    front = _grid(-0.3, 0.3, -0.3, 0.3, 2.0, step_front)
    back = _grid(-1.4, 1.4, -1.0, 1.0, 3.0, step_back)
    return front, back


def _render_two_planes(cam):
    rays = _pixel_rays(cam)
    hit = rays[:, :2] / rays[:, 2:] * 2.0
    on_front = (np.abs(hit) <= 0.3).all(axis=1)
    img = np.where(on_front[:, None], RED, BLUE).reshape(cam.height_px, cam.width_px, 3)
    return img.astype(np.uint8)


@pytest.mark.parametrize("seed,splat", [(5, "auto"), (6, "auto"), (7, 3)])
def test_colour_cloud_occlusion_front_and_back(seed, splat):
    cam = _cam()
    T = _T(seed)
    front, back = _two_planes()
    img = _render_two_planes(cam)
    P = transform_points(invert_T(T), np.vstack([front, back]))
    colours, ok = F.colour_cloud(P, img, cam, T, splat_radius_px=splat, depth_tolerance_m=0.05)
    nf = len(front)
    # front: coloured, red (away from its border, where bilinear sampling mixes)
    inner = (np.abs(front[:, :2]) < 0.27).all(axis=1)
    assert ok[:nf][inner].all()
    assert np.abs(colours[:nf][inner].astype(int) - RED).max() <= 2
    # back: hidden behind the front square -> uncoloured; clearly outside -> blue
    shadow = np.abs(back[:, :2] * 2.0 / 3.0).max(axis=1)
    hidden, clear = shadow < 0.25, shadow > 0.36
    in_view = F.project_cloud(P[nf:], T, cam)[2]
    assert hidden.sum() > 500
    assert not ok[nf:][hidden].any()
    assert ok[nf:][clear & in_view].mean() > 0.99
    assert np.abs(colours[nf:][clear & ok[nf:]].astype(int) - BLUE).max() <= 2
    # without occlusion the back would take the front's red: the test above can fail
    c2, ok2 = F.colour_cloud(P, img, cam, T, occlusion=False)
    assert ok2[nf:][hidden].all() and (np.abs(c2[nf:][hidden].astype(int) - RED).max(axis=1) <= 2).mean() > 0.9


@pytest.mark.parametrize("seed", [8, 9])
def test_colour_cloud_pipe_back_half_stays_uncoloured(seed):
    """A flange-like pipe across the view: its far half must not take the near half's colour."""
    cam = _cam()
    T = _T(seed)
    R_pipe, zc, n_ang = 0.15, 2.0, 180
    ang = np.linspace(0, 2 * np.pi, n_ang, endpoint=False)
    xs = np.arange(-0.8, 0.8, 0.01)
    A, X = np.meshgrid(ang, xs)
    pipe = np.column_stack([X.ravel(), R_pipe * np.sin(A.ravel()), zc + R_pipe * np.cos(A.ravel())])
    near = pipe[:, 2] < zc - 0.05
    far = pipe[:, 2] > zc + 0.05
    # image: the pipe (rays hitting the cylinder y^2 + (z-zc)^2 <= R^2) green, the rest black
    rays = _pixel_rays(cam)
    b = rays[:, 2] * zc
    a = rays[:, 1] ** 2 + rays[:, 2] ** 2
    hits = (b * b - a * (zc * zc - R_pipe**2) >= 0)
    img = np.where(hits[:, None], [30, 200, 60], [0, 0, 0]).reshape(cam.height_px, cam.width_px, 3).astype(np.uint8)
    P = transform_points(invert_T(T), pipe)
    colours, ok = F.colour_cloud(P, img, cam, T)
    in_view = F.project_cloud(P, T, cam)[2]
    assert ok[near & in_view].mean() > 0.98
    assert not ok[far].any()


def test_colour_cloud_sparse_points_auto_splat_closes_gaps():
    cam = _cam()
    T = _T(10)
    front, back = _two_planes(step_front=0.04, step_back=0.015)  # front spacing ~6 px
    img = _render_two_planes(cam)
    P = transform_points(invert_T(T), np.vstack([front, back]))
    _, ok = F.colour_cloud(P, img, cam, T)
    shadow = np.abs(back[:, :2] * 2.0 / 3.0).max(axis=1)
    assert not ok[len(front):][shadow < 0.25].any()
    _, ok_thin = F.colour_cloud(P, img, cam, T, splat_radius_px=0)
    assert ok_thin[len(front):][shadow < 0.25].mean() > 0.3  # a 1-px z-buffer leaks through the gaps


@pytest.mark.parametrize("splat", [24, "auto"])
def test_back_point_right_behind_a_sparse_front_stays_uncoloured(splat):
    """A wide splat's depth tolerance (24 px at ~4.3 m, f 300: 0.05 + 0.34 m) must not let a point
    0.3 m straight behind a front point take a colour: the occluder in its own pixel is at most
    a pixel or two away, so its reach is that, not the splat's (found on the flange's border row)."""
    cam = _cam()
    front = _grid(-1.6, 1.6, -1.2, 1.2, 4.0, 0.4)  # 30 px apart: the auto splat is at its widest
    back = front + 0.3 * front / np.linalg.norm(front, axis=1, keepdims=True)
    uv, depth, valid = F.project_cloud(np.vstack([front, back]), np.eye(4), cam)
    n = len(front)
    assert valid.all() and np.abs(uv[:n] - uv[n:]).max() < 1e-3
    if splat == "auto":
        _, _, pix = F.zbuffer.pixel_index(uv, valid, cam.width_px, cam.height_px)
        r_cell = F.zbuffer.splatted_zbuffer(pix, depth, cam.width_px, cam.height_px, "auto", 0.05)[1]
        assert r_cell.max() == 24
    vis = F.visible_points(uv, depth, valid, cam, splat_radius_px=splat)
    assert vis[:n].all()
    assert not vis[n:].any()


def test_colour_cloud_multi_picks_a_camera_that_sees_the_point():
    cam = _cam()
    wall = _grid(-4.0, 4.0, -1.0, 1.0, 3.0, 0.02)  # sonar frame == cam1 frame here
    T1 = np.eye(4)
    T2 = T_from_rotvec([0, 0, 0], [-2.0, 0, 0])  # cam2 2 m to the right, looking the same way
    img1 = np.full((cam.height_px, cam.width_px, 3), 11, np.uint8)
    img2 = np.full_like(img1, 77)
    views = [F.CameraView("cam1", img1, cam, T1), F.CameraView("cam2", img2, cam, T2)]
    colours, ok, which = F.colour_cloud_multi(wall, views)
    in1, in2 = F.project_cloud(wall, T1, cam)[2], F.project_cloud(wall, T2, cam)[2]
    only2, both = in2 & ~in1, in1 & in2
    assert only2.sum() > 100 and both.sum() > 100
    assert (which[only2] == 1).all() and (colours[only2] == 77).all()
    assert (which[in1 & ~in2] == 0).all() and (colours[in1 & ~in2] == 11).all()
    # in the overlap the nearer / more central camera wins
    x = wall[:, 0]
    assert (which[both & (x < 0.9)] == 0).all() and (which[both & (x > 1.1)] == 1).all()
    assert (which[~ok] == -1).all() and (colours[~ok] == 0).all() and not ok[~(in1 | in2)].any()
    # with normals the most frontal view wins: a wall turned towards cam2
    normals = np.tile([0.6, 0.0, -0.8], (len(wall), 1))
    _, _, which_n = F.colour_cloud_multi(wall, views, normals_sonar=normals)
    assert (which_n[both] == 1).all()


def test_colour_cloud_multi_respects_occlusion_per_camera():
    cam = _cam()
    front, back = _two_planes()
    pts = np.vstack([front, back])
    img = _render_two_planes(cam)
    T2 = T_from_rotvec([0, 0, 0], [-0.05, 0, 0])
    views = [F.CameraView("a", img, cam, np.eye(4)), F.CameraView("b", img, cam, T2)]
    _, ok, _ = F.colour_cloud_multi(pts, views)
    shadow = np.abs(back[:, :2] * 2.0 / 3.0).max(axis=1)
    assert not ok[len(front):][shadow < 0.2].any()
    assert ok[:len(front)][(np.abs(front[:, :2]) < 0.27).all(axis=1)].all()


def test_empty_and_all_invisible_clouds():
    cam = _cam()
    img = np.zeros((cam.height_px, cam.width_px, 3), np.uint8)
    for P in (np.zeros((0, 3)), np.array([[0.0, 0.0, -1.0], [np.nan, 0, 1]])):
        colours, ok = F.colour_cloud(P, img, cam, np.eye(4))
        assert colours.shape == (len(P), 3) and not ok.any()
        c2, ok2, which = F.colour_cloud_multi(P, [F.CameraView("a", img, cam, np.eye(4))])
        assert c2.shape == (len(P), 3) and not ok2.any() and (which == -1).all()
        uv, _, valid = F.project_cloud(P, np.eye(4), cam)
        assert not F.segmentation_mask(cam, uv, 5, valid).any()
        assert np.isinf(F.depth_buffer(uv, np.zeros(len(P)), valid, cam.width_px, cam.height_px)).all()
    with pytest.raises(ValueError, match="auto"):
        F.colour_cloud(np.ones((3, 3)), img, cam, np.eye(4), splat_radius_px="big")
