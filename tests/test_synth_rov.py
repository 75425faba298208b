"""The held-out kind "rov" (field and ROV video cameras): its lens, its truth through the lens,
and the video effects, each where its model (module docstrings) puts it."""

import cv2
import numpy as np
import pytest

from calib_core.synth.camera_render import camera_rays
from calib_core.synth.image_cases import render_case
from calib_core.synth.photo import rov_osd, rov_video
from calib_core.synth.photo.rov_parts import wide_lens
from calib_core.synth.rig import silhouette_uv

SCALE = 0.25


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_wide_lens_is_barrel_distorted_and_90_to_120_deg_wide(seed):
    cam = wide_lens(np.random.default_rng(seed), 720, 576)
    k1, k2 = cam.dist[0], cam.dist[1]
    assert -0.35 <= k1 <= -0.25 and 0.05 <= k2 <= 0.15
    xy = cam.normalize(np.array([[cam.width_px - 0.5, cam.cy], [-0.5, cam.cy]]))
    fov = np.degrees(np.arctan(xy[0, 0]) - np.arctan(xy[1, 0]))
    assert 85 <= fov <= 125  # 90-120 deg at the nominal centre; cx is drawn 1 % off it
    corner = np.array([[0.0, 0.0]])  # barrel: the corner's ray is farther out than a pinhole's
    assert np.linalg.norm(cam.normalize(corner)) > np.linalg.norm((corner - [cam.cx, cam.cy]) / cam.fx) * 1.2


@pytest.mark.parametrize("seed", [3, 8])
def test_rov_case_truth_is_the_ball_seen_through_the_lens(seed):
    """The ball's pixels (the frame with the ball minus the same frame without it) fill the
    silhouette projected through the distortion, and the true centre's pixel ray points at the
    ball's centre."""
    a = render_case("rov", seed, SCALE)
    b = render_case("rov", seed, SCALE)
    assert np.array_equal(a.image, b.image) and a.label.startswith("rov/") and a.label.endswith(f"/s{seed}")
    empty = render_case("rov", seed, SCALE, with_ball=False)
    assert empty.image.shape == a.image.shape
    H, W = a.image.shape[:2]
    diff = np.abs(a.image.astype(float) - empty.image).max(axis=2)
    # rebuild the ball's silhouette from the case's truth: its ray and range
    ray = camera_rays(a.cam, a.true_uv_px[None])[0]
    C = ray * a.range_m
    sil = silhouette_uv(a.cam, C, a.radius_m, 180)
    inside = np.zeros((H, W), np.uint8)
    cv2.fillPoly(inside, [np.round(sil * 4).astype(np.int32)], 1, cv2.LINE_8, shift=2)
    core = cv2.erode(inside, np.ones((5, 5), np.uint8)) > 0
    ring = (cv2.dilate(inside, np.ones((9, 9), np.uint8)) > 0) & ~(cv2.dilate(inside, np.ones((5, 5), np.uint8)) > 0)
    base = np.median(diff)  # the frame's exposure is metered with or without the ball
    ball = np.median(diff[core]) - base
    assert ball > 15  # the ball is where the truth says
    assert np.median(diff[ring]) - base < 0.3 * ball  # and not 2-4 px outside its outline


def test_interlaced_fields_straddle_the_true_centre():
    """The two fields' ball centres project either side of the true centre: their mean is the
    truth to far below the detector's tolerance, even in a corner of a strongly distorted lens."""
    cam = wide_lens(np.random.default_rng(5), 720, 576)
    for uv in ([40.0, 40.0], [360.0, 288.0], [690.0, 540.0]):
        C = camera_rays(cam, np.array([uv]))[0] * 1.5
        step = np.array([0.012, -0.008, 0.01])
        pa, pb, pc = cam.project(np.array([C - step / 2, C + step / 2, C]))
        assert np.hypot(*(0.5 * (pa + pb) - pc)) < 0.05  # 0.035 px in the corner for 6 px of combing
        assert np.hypot(*(pa - pb)) > 2.0  # combed by pixels


def test_video_effects():
    rng = np.random.default_rng(0)
    img = np.zeros((96, 128, 3), np.uint8)
    cv2.circle(img, (64, 48), 20, (230, 90, 20), -1)
    img = np.clip(img.astype(int) + rng.integers(0, 20, img.shape), 0, 255).astype(np.uint8)
    y0 = cv2.cvtColor(img, cv2.COLOR_RGB2YCrCb)[:, :, 0].astype(int)
    for scheme in ("420", "411"):
        out = rov_video.chroma_subsample(img, scheme, 1.5, 0.8)
        y1 = cv2.cvtColor(out, cv2.COLOR_RGB2YCrCb)[:, :, 0].astype(int)
        assert np.abs(y1 - y0).mean() < 3.0  # luma kept
        assert np.abs(out.astype(int) - img).max() > 30  # colour bled
    even, odd = np.zeros((6, 4, 3)), np.ones((6, 4, 3))
    frame = rov_video.interlace(even, odd)
    assert (frame[0::2] == 0).all() and (frame[1::2] == 1).all()
    L = np.ones((100, 140, 3), np.float32)
    d = rov_video.dome_edge(L, 80.0, 5.0, (0.0, 0.0, 0.0))
    assert d[50, 70].min() == 1.0 and d[0, 0].max() == 0.0 and d[50, 0].min() == 1.0  # only the corners
    grid = np.zeros((101, 141, 3), np.float32)
    grid[:, 130] = 1.0  # a vertical line near the right edge
    ca = rov_video.chromatic_aberration(grid, 0.01)
    assert np.argmax(ca[50, :, 1]) == 130 and np.argmax(ca[50, :, 0]) > 130 and np.argmax(ca[50, :, 2]) < 130


def test_osd_reticle_is_a_circle_at_the_centre():
    img = np.full((288, 360, 3), 60, np.uint8)
    osd = rov_osd.Osd(lines=(("DEPTH 12.0 M", "tl"),), reticle_px=50.0, crosshair=True)
    out = rov_osd.draw_osd(img, osd)
    changed = np.abs(out.astype(int) - img).max(axis=2) > 30
    yy, xx = np.nonzero(changed)
    r = np.hypot(xx - 180, yy - 144)
    assert ((r > 47) & (r < 53)).sum() > 200  # the circle
    assert changed[:40, :150].any()  # the text in its corner
