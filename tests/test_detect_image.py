"""Image sphere detector: accuracy, failure cases with reasons, background model, covariance."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import yaml

import sys
from pathlib import Path

from calib_core.detect.image.detect import background_model, detect_sphere_in_image
from calib_core.detect.image.cone import cone_from_conic, fit_conic_normalised
from calib_core.io.images import load_background_frames

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the analytic image maker next to this file
from test_detect_image_scenes import make_background, make_camera, render, sphere_pose_at  # noqa: E402

R_M = 0.11


def _scene(cam, uv, dist, seed, **kw):
    rng = np.random.default_rng(seed)
    bg = make_background(cam, rng)
    img, truth = render(cam, bg, sphere_pose_at(cam, uv, dist), R_M, rng, **kw)
    return img, truth, bg


@pytest.fixture(scope="module")
def cam_wide():
    # strong barrel distortion: corners move by tens of pixels
    return make_camera(960, 540, 600.0, (-0.32, 0.12, 0.001, -0.0015, -0.02))


@pytest.mark.parametrize("seed", [0, 1])
def test_ellipse_exact_accurate_and_beats_circle_off_axis(cam_wide, seed):
    rng = np.random.default_rng(100 + seed)
    errs_e, errs_h = [], []
    # targets near the corners (large off-axis bias) and one near the centre
    for uv, dist in [((95, 78), 1.0), ((860, 460), 1.0), ((480 + rng.uniform(-40, 40), 270), 1.2)]:
        img, truth, bg = _scene(cam_wide, uv, dist, seed, noise=2.5)
        det = detect_sphere_in_image(img, cam_wide, R_M, background=bg)
        assert det.found, det.reason
        errs_e.append(np.linalg.norm(det.center_uv_px - truth))
        assert det.range_m == pytest.approx(dist, rel=0.01)
        assert 0.8 < det.score <= 1.0
        entry = yaml.safe_load(yaml.safe_dump(det.to_entry()))  # plain YAML types only
        assert entry["status"] == "auto" and len(entry["center"]) == 2 and len(entry["cov_px2"]) == 4
        hough = detect_sphere_in_image(img, cam_wide, R_M, background=bg, method="hough-circle")
        assert hough.found and hough.method == "hough-circle"
        errs_h.append(np.linalg.norm(hough.center_uv_px - truth))
    assert max(errs_e) < 0.25, errs_e
    # at the corners the circle centre carries the perspective + distortion bias
    assert errs_h[0] > 4 * errs_e[0] and errs_h[1] > 4 * errs_e[1] and max(errs_h) > 1.0


def test_full_hd_without_background_finds_the_sphere():
    cam = make_camera(1920, 1080, 1200.0, (-0.25, 0.08, 0, 0, 0))
    for seed, (uv, dist) in enumerate([((1700, 160), 1.5), ((300, 880), 1.0)]):
        img, truth, _ = _scene(cam, uv, dist, seed)
        det = detect_sphere_in_image(img, cam, R_M)
        assert det.found, det.reason
        assert np.linalg.norm(det.center_uv_px - truth) < 0.3
        assert det.range_m == pytest.approx(dist, rel=0.01)


@pytest.mark.parametrize("bright", [True, False])
def test_brighter_or_darker_than_background(bright):
    cam = make_camera(960, 540, 700.0, (-0.1, 0.02, 0, 0, 0))
    rng = np.random.default_rng(5)
    level = 40.0 if bright else 215.0
    bg = np.full((540, 960, 3), level, np.float32) + make_background(cam, rng, texture=6.0) * 0.1
    colour = (235, 240, 230) if bright else (20, 15, 25)
    img, truth = render(cam, bg, sphere_pose_at(cam, (700, 150), 1.4), R_M, rng, colour=colour, hole_mix=0.8)
    for background in (bg, None):
        det = detect_sphere_in_image(img, cam, R_M, background=background)
        assert det.found, det.reason
        assert np.linalg.norm(det.center_uv_px - truth) < 0.3


def test_no_sphere(cam_wide):
    rng = np.random.default_rng(7)
    bg = make_background(cam_wide, rng)
    img = np.clip(bg + rng.normal(0, 2.5, bg.shape), 0, 255).astype(np.uint8)
    for background in (bg, None):
        det = detect_sphere_in_image(img, cam_wide, R_M, background=background)
        assert not det.found and det.reason == "no round outline"
        assert det.to_entry()["reason"] == "no round outline"


def test_cut_by_the_border(cam_wide):
    img, _, bg = _scene(cam_wide, (935, 250), 0.9, 3)
    for background in (bg, None):
        det = detect_sphere_in_image(img, cam_wide, R_M, background=background)
        assert not det.found and det.reason == "sphere cut by the image border"


def test_two_candidates_and_hint(cam_wide):
    rng = np.random.default_rng(11)
    bg = make_background(cam_wide, rng)
    first, t1 = render(cam_wide, bg, sphere_pose_at(cam_wide, (300, 250), 1.2), R_M, rng)
    img, t2 = render(cam_wide, first.astype(np.float32), sphere_pose_at(cam_wide, (700, 320), 1.5), R_M, rng)
    det = detect_sphere_in_image(img, cam_wide, R_M, background=bg)
    assert not det.found and det.reason.startswith("two round objects: (")
    ranges = sorted(c[2] for c in det.extras["two_candidates"])
    assert ranges == pytest.approx([1.2, 1.5], rel=0.01)
    det = detect_sphere_in_image(img, cam_wide, R_M)
    assert not det.found and det.reason.startswith("two round objects: (")
    # an operator's click resolves it
    det = detect_sphere_in_image(img, cam_wide, R_M, background=bg, hint_uv_px=(705, 310))
    assert det.found and np.linalg.norm(det.center_uv_px - t2) < 0.3
    det = detect_sphere_in_image(img, cam_wide, R_M, hint_uv_px=t1 + 20, hint_radius_px=60)
    assert det.found and np.linalg.norm(det.center_uv_px - t1) < 0.3


def test_round_things_of_implausible_size_or_shape_are_ignored(cam_wide):
    rng = np.random.default_rng(13)
    bg = make_background(cam_wide, rng)
    # a tiny bubble (too small for any range up to 4 m) and a flat disc seen obliquely
    disc = np.ascontiguousarray(bg.copy())
    cv2.ellipse(disc, ((650.0, 380.0), (110.0, 60.0), 30.0), (200, 200, 60), -1, cv2.LINE_AA)
    disc = cv2.GaussianBlur(disc, (0, 0), 0.7)
    img, truth = render(cam_wide, disc, sphere_pose_at(cam_wide, (250, 200), 1.3), R_M, rng,
                        distractors=[(800, 120, 3.0, (230, 230, 230))])
    for background in (bg, None):
        det = detect_sphere_in_image(img, cam_wide, R_M, background=background, range_limits_m=(0.3, 4.0))
        assert det.found, det.reason
        assert np.linalg.norm(det.center_uv_px - truth) < 0.3
    # the oblique disc alone is not taken for a sphere
    only_disc = np.clip(disc + rng.normal(0, 2.0, disc.shape), 0, 255).astype(np.uint8)
    det = detect_sphere_in_image(only_disc, cam_wide, R_M, background=bg)
    assert not det.found


def test_covariance_matches_monte_carlo_spread(cam_wide):
    rng = np.random.default_rng(17)
    bg = make_background(cam_wide, rng)
    # (1) pure image-noise Monte Carlo on one scene: the estimate must not be overconfident
    clean, truth = render(cam_wide, bg, sphere_pose_at(cam_wide, (260, 380), 1.6), R_M, rng, noise=0.0)
    centres, covs = [], []
    for _ in range(12):
        img = np.clip(clean + rng.normal(0, 6.0, clean.shape), 0, 255).astype(np.uint8)
        det = detect_sphere_in_image(img, cam_wide, R_M, background=bg)
        assert det.found
        centres.append(det.center_uv_px)
        covs.append(det.cov_uv_px2)
    emp = np.cov(np.array(centres).T)
    assert np.trace(np.mean(covs, axis=0)) > 0.5 * np.trace(emp)
    # (2) total error over random scenes (texture, shading, position, noise): Mahalanobis^2
    # of the true error averages ~2 (chi-square, 2 dof) when the covariance is calibrated;
    # the bounds allow a factor ~2.5 either way in sigma
    z2 = []
    for _ in range(10):
        uv = rng.uniform([120, 100], [840, 440])
        img, truth = render(cam_wide, bg, sphere_pose_at(cam_wide, uv, rng.uniform(0.8, 3.0)), R_M, rng,
                            noise=float(rng.choice([1.0, 3.0, 6.0])))
        det = detect_sphere_in_image(img, cam_wide, R_M, background=bg)
        assert det.found, det.reason
        e = det.center_uv_px - truth
        z2.append(e @ np.linalg.solve(det.cov_uv_px2, e))
    assert 0.3 < np.mean(z2) < 5.0, z2


def test_image_size_mismatch_and_bad_method(cam_wide):
    img = np.zeros((100, 100, 3), np.uint8)
    det = detect_sphere_in_image(img, cam_wide, R_M)
    assert not det.found and "intrinsics" in det.reason
    with pytest.raises(ValueError):
        detect_sphere_in_image(np.zeros((540, 960, 3), np.uint8), cam_wide, R_M, method="magic")


def test_background_model_median_mean_and_video(tmp_path):
    rng = np.random.default_rng(3)
    base = cv2.resize(rng.integers(20, 200, (6, 8, 3)).astype(np.uint8), (64, 48), interpolation=cv2.INTER_LINEAR)
    frames = [np.clip(base.astype(int) + rng.integers(-2, 3, base.shape), 0, 255).astype(np.uint8) for _ in range(9)]
    frames[4][10:20, 10:20] = 255  # a fish passing in one frame
    med = background_model(frames, "median")
    mean = background_model(frames, "mean")
    assert med.dtype == np.float32 and med.shape == base.shape
    assert np.abs(med[10:20, 10:20] - base[10:20, 10:20]).max() <= 2.0
    assert np.abs(mean - np.mean(np.stack(frames), axis=0)).max() < 1e-3
    with pytest.raises(ValueError):
        background_model([], "median")
    with pytest.raises(ValueError):
        background_model(frames, "mode")
    # a video file through the session loader
    path = tmp_path / "bg.avi"
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (64, 48))
    assert vw.isOpened()
    for f in frames:
        vw.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
    vw.release()
    vframes = load_background_frames(path, start_s=0.0, end_s=0.8)
    bgv = background_model(vframes, "median")
    assert np.abs(bgv - base).mean() < 6.0  # MJPG is lossy


def test_cone_from_conic_matches_the_geometry_note():
    """The silhouette conic of a sphere gives back the axis and half-angle (sphere-geometry.md)."""
    w = np.array([0.3, -0.2, 1.0]); w /= np.linalg.norm(w)
    a = np.arcsin(0.11 / 1.3)
    e1 = np.cross(w, [1.0, 0, 0]); e1 /= np.linalg.norm(e1); e2 = np.cross(w, e1)
    phi = np.linspace(0, 2 * np.pi, 50, endpoint=False)
    v = np.cos(a) * w + np.sin(a) * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
    Q = fit_conic_normalised(v[:, :2] / v[:, 2:])
    w_fit, a_fit = cone_from_conic(Q)
    assert np.allclose(w_fit, w, atol=1e-9) and a_fit == pytest.approx(a, abs=1e-9)
    # the ellipse centre is not the projected centre
    xy = v[:, :2] / v[:, 2:]
    assert np.linalg.norm(0.5 * (xy.max(axis=0) + xy.min(axis=0)) - w[:2] / w[2]) > 1e-4


def test_background_median_of_few_frames_is_numpys_median():
    """The median of a few 8-bit frames by sorting them (background_model's fast path) is the value
    np.median gives, odd and even counts (the mean of the two middle values), bit for bit."""
    from calib_core.detect.image.detect import background_model

    rng = np.random.default_rng(3)
    for n in range(2, 11):
        frames = [rng.integers(0, 256, (7, 5, 3), dtype=np.uint8) for _ in range(n)]
        frames[0][0, 0] = frames[1][0, 0]  # ties
        assert np.array_equal(background_model(frames), np.median(np.stack(frames), axis=0).astype(np.float32))
