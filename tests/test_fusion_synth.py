"""Fusion on a synthetic flange session (calib_core.synth) with its exact ground-truth T_cam_sonar."""

from __future__ import annotations

import numpy as np
import pytest

from calib_core import fusion as F
from calib_core.geometry import invert_T, transform_points
from calib_core.io.clouds import load_cloud
from calib_core.io.images import load_image
from calib_core.session import load_session

synth = pytest.importorskip("calib_core.synth.generate")
from calib_core.synth.ground_truth import load_ground_truth  # noqa: E402

PAN_STEP_DEG = 1.0


@pytest.fixture(scope="module", params=[3, 11])  # 11: sphere in a corner, pincushion lens
def flange(request, tmp_path_factory):
    root = tmp_path_factory.mktemp(f"flange{request.param}")
    synth.generate_session(root, "flange", request.param, scale=0.25, pan_step_deg=PAN_STEP_DEG, sub_rays=9, n_captures=2,
                           n_flange=1, n_backgrounds=0)
    session = load_session(root)
    gt = load_ground_truth(root)
    assert gt["range_scale"] == 1.0
    return session, gt


def _capture(session, gt, target: bool):
    for cap in session.captures:
        if bool(gt["captures"][cap.id].get("target")) == target:
            yield cap, gt["captures"][cap.id]


def _flange_view(session, gt):
    """cam1's model, true T_cam_sonar, cloud and image of the first flange (non-target) capture."""
    cap, _ = next(_capture(session, gt, False))
    T = np.asarray(gt["cameras"]["cam1"]["T_cam_sonar"], float)
    return session.camera_model("cam1"), T, load_cloud(cap.cloud_path).points_m, load_image(cap.image_paths["cam1"])


def test_mask_of_the_sphere_cloud_covers_the_sphere(flange):
    session, gt = flange
    cam = session.camera_model("cam1")
    T = np.asarray(gt["cameras"]["cam1"]["T_cam_sonar"], float)
    R = gt["sphere_diameter_m"] / 2
    radius_px = np.ceil(0.75 * cam.fx * np.radians(PAN_STEP_DEG)) + 1  # closes the gaps between scan lines
    checked = 0
    for cap, g in _capture(session, gt, True):
        im = g["images"]["cam1"]
        if not im["visible"]:
            continue
        P = load_cloud(cap.cloud_path).points_m
        near = np.linalg.norm(P - np.asarray(g["center_sonar_m"]), axis=1) < 1.2 * R
        uv, _, valid = F.project_cloud(P[near], T, cam)
        mask = F.segmentation_mask(cam, uv, radius_px, valid)
        c = np.asarray(im["center_uv_px"])
        r_img = cam.fx * R / im["distance_m"]
        yy, xx = np.mgrid[0:cam.height_px, 0:cam.width_px]
        d = np.hypot(xx - c[0], yy - c[1])
        assert mask[int(round(c[1])), int(round(c[0]))]
        assert mask[d < 0.8 * r_img].mean() > 0.9
        # the sphere's own points stay inside the image of the 1.25 R ball (lens distortion included)
        dirs = np.random.default_rng(0).normal(size=(4000, 3))
        ball = np.asarray(g["center_sonar_m"]) + 1.25 * R * dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
        reach = np.nanmax(np.hypot(*(cam.project(transform_points(T, ball)) - c).T))
        assert not mask[d > reach + radius_px + 1].any()
        checked += 1
    assert checked >= 1


def test_flange_back_surface_stays_uncoloured(flange):
    """A copy of every visible point pushed 0.4 m further along its camera ray is a back surface
    exactly behind the front one: none of it may take a colour, and the front keeps its colours."""
    cam, T, P, img = _flange_view(*flange)
    colours, ok = F.colour_cloud(P, img, cam, T)
    assert ok.sum() > 50
    eye = invert_T(T)[:3, 3]
    rays = P - eye
    back = P + 0.4 * rays / np.linalg.norm(rays, axis=1, keepdims=True)
    colours2, ok2 = F.colour_cloud(np.vstack([P, back]), img, cam, T)
    n = len(P)
    assert not ok2[n:][ok].any()
    assert (ok2[:n] == ok).mean() > 0.98
    same = ok & ok2[:n]
    assert np.array_equal(colours2[:n][same], colours[same])
    # colours are the image's, sampled at the projection
    uv, _, _ = F.project_cloud(P[ok], T, cam)
    np.testing.assert_array_equal(colours[ok], F.sample_bilinear(img, uv)[:, :3])


def test_flange_isolated_front_points_are_coloured(flange):
    """A point with nothing nearer within 40 px (beyond any splat's reach) is seen by the camera."""
    cam, T, P, img = _flange_view(*flange)
    _, ok = F.colour_cloud(P, img, cam, T)
    uv, depth, valid = F.project_cloud(P, T, cam)
    idx = np.flatnonzero(valid)
    d2 = np.hypot(uv[idx, None, 0] - uv[None, idx, 0], uv[idx, None, 1] - uv[None, idx, 1])
    nearer = depth[idx][None, :] < depth[idx][:, None] - 0.05
    free = ~np.any((d2 < 40) & nearer, axis=1)
    assert free.sum() > 20
    assert ok[idx[free]].all()
