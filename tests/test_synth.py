"""Synthetic session generator: validity, exact ground truth, physics (blooming, range scale,
anti-aliasing), seeds, and the ``sonarcal synth`` command. Small resolutions throughout."""

from __future__ import annotations

import argparse

import numpy as np
import pytest
from scipy.optimize import least_squares

from calib_core.camera import CameraModel
from calib_core.geometry import invert_T, look_at_T_cam_world, transform_points
from calib_core.io.clouds import load_cloud
from calib_core.io.images import load_background_frames, load_image
from calib_core.session import load_session, validate_session
from calib_core.synth.camera_render import Water, render_radiance
from calib_core.synth.generate import generate_session
from calib_core.synth.ground_truth import load_ground_truth
from calib_core.synth.presets import PRESETS
from calib_core.synth.rig import sample_rig
from calib_core.synth.scene import (Box, Capsule, Cylinder, Disc, Group, Material, MeshSphere, Rect, Scene,
                                    Sphere, raycast)
from calib_core.synth.sonar_sim import SonarConfig, simulate_scan

FAST = dict(scale=0.15, n_captures=3, pan_step_deg=2.0, sub_rays=7)


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    """Every preset generated once at a small size (seed 3)."""
    root = tmp_path_factory.mktemp("synth")
    out = {}
    for name, preset in PRESETS.items():
        kw = dict(FAST, n_flange=min(preset.n_flange, 1), n_backgrounds=min(preset.n_backgrounds, 2))
        out[name] = generate_session(root / name, name, 3, **kw)
    return out


@pytest.mark.parametrize("name", list(PRESETS))
def test_every_preset_is_a_valid_session(sessions, name):
    check = validate_session(sessions[name])
    assert check.problems == []
    gt = load_ground_truth(sessions[name])
    assert gt["format"] == "sonar-camera-ground-truth/1" and gt["preset"] == name and gt["seed"] == 3
    s = check.session
    assert set(gt["cameras"]) == set(s.cameras)
    assert [c.id for c in s.captures] == list(gt["captures"])


@pytest.mark.parametrize("name", list(PRESETS))
def test_ground_truth_projects_to_stored_pixels(sessions, name):
    s = load_session(sessions[name])
    gt = load_ground_truth(sessions[name])
    n_visible = 0
    for cid, cap in gt["captures"].items():
        if not cap["target"]:
            continue
        for cam_name, im in cap["images"].items():
            cam = s.camera_model(cam_name)
            X = transform_points(gt["cameras"][cam_name]["T_cam_sonar"], cap["center_sonar_at_image_m"][None])
            uv = cam.project(X)[0]
            assert np.allclose(uv, im["center_uv_px"], atol=1e-6)
            n_visible += im["visible"]
    assert n_visible >= 1


def test_stereo_is_the_composition_and_session_stereo_is_close(sessions):
    gt = load_ground_truth(sessions["canal"])
    T1, T2 = gt["cameras"]["cam1"]["T_cam_sonar"], gt["cameras"]["cam2"]["T_cam_sonar"]
    assert np.allclose(gt["stereo"]["T_cam2_cam1"], T2 @ invert_T(T1), atol=1e-8)
    s = load_session(sessions["canal"])
    T_s = s.stereo["T_cam2_cam1"]
    assert 1e-5 < np.linalg.norm(T_s[:3, 3] - gt["stereo"]["T_cam2_cam1"][:3, 3]) < 0.02  # checkerboard-like error
    b = np.linalg.norm(gt["stereo"]["T_cam2_cam1"][:3, 3])
    assert 0.6 < b < 0.9 and abs(s.measured_m["cam1-cam2"] - b) < 0.02
    for c in ("cam1", "cam2"):
        assert 0.7 < np.linalg.norm(gt["cameras"][c]["T_cam_sonar"][:3, 3]) < 1.0


def test_images_show_the_sphere_where_truth_says(sessions):
    """The image differs from the background around the true centre, not far from it."""
    for name in ("canal", "bright", "seabed"):
        s = load_session(sessions[name])
        gt = load_ground_truth(sessions[name])
        for cam_name, spec in s.cameras.items():
            start, end = spec.background_window_s
            frames = load_background_frames(spec.background_path, start_s=start, end_s=end)
            bg = np.mean([f.astype(float) for f in frames], axis=0)
            cam = s.camera_model(cam_name)
            for cap in s.captures:
                im = gt["captures"][cap.id]["images"][cam_name]
                if not im["visible"]:
                    continue
                diff = np.abs(load_image(cap.image_paths[cam_name]).astype(float) - bg).mean(axis=2)
                r_px = cam.fx * gt["sphere_diameter_m"] / 2 / im["distance_m"]
                v, u = np.mgrid[0:cam.height_px, 0:cam.width_px]
                d = np.hypot(u - im["center_uv_px"][0], v - im["center_uv_px"][1])
                inside = diff[d < 0.8 * r_px].mean()
                assert inside > 8, (name, cap.id, inside)


def test_background_video_shows_the_target_only_before_the_window(sessions):
    s = load_session(sessions["seabed"])
    spec = s.cameras["cam1"]
    assert spec.background_path.suffix == ".avi" and spec.background_window_s[0] > 1.0
    early = load_background_frames(spec.background_path, start_s=0.0, end_s=0.8)
    late = load_background_frames(spec.background_path, start_s=spec.background_window_s[0], end_s=None)
    first = load_image(s.captures[0].image_paths["cam1"]).astype(float)
    im = load_ground_truth(sessions["seabed"])["captures"][s.captures[0].id]["images"]["cam1"]
    u, v = np.round(im["center_uv_px"]).astype(int)
    roi = (slice(max(v - 4, 0), v + 5), slice(max(u - 4, 0), u + 5))
    d_early = np.abs(early[0].astype(float) - first)[roi].mean()
    d_late = np.abs(late[-1].astype(float) - first)[roi].mean()
    assert d_early + 3 < d_late  # the first second still shows capture p01's target


def test_moved_capture_really_moved(sessions):
    gt = load_ground_truth(sessions["moved"])
    moved = {k: c for k, c in gt["captures"].items() if c["moved_m"] > 0}
    assert len(moved) == 1
    (cap,) = moved.values()
    assert 0.1 <= cap["moved_m"] <= 0.2
    assert np.isclose(np.linalg.norm(cap["center_sonar_at_image_m"] - cap["center_sonar_m"]), cap["moved_m"])
    for k, c in gt["captures"].items():
        if k not in moved:
            assert np.allclose(c["center_sonar_m"], c["center_sonar_at_image_m"])


def test_preset_specifics(sessions):
    gt = {k: load_ground_truth(v) for k, v in sessions.items()}
    assert gt["soundspeed"]["range_scale"] == pytest.approx(1.02)
    ratio = gt["wrongdiam"]["session_diameter_m"] / gt["wrongdiam"]["sphere_diameter_m"]
    assert 0.25 < abs(ratio - 1) < 0.35
    assert load_session(sessions["wrongdiam"]).sphere_diameter_m == pytest.approx(gt["wrongdiam"]["session_diameter_m"])
    assert all(spec.background_path is None for spec in load_session(sessions["nobg"]).cameras.values())
    flange = [c for c in gt["flange"]["captures"].values() if not c["target"]]
    assert len(flange) == 1 and flange[0]["center_sonar_m"] is None
    assert gt["seabed"]["world"]["seabed_z_m"] is not None
    assert load_session(sessions["decoys"]).captures[0].cloud_path.suffix == ".xyz"
    assert load_session(sessions["seabed"]).captures[0].cloud_path.suffix == ".npy"


def test_seabed_cloud_has_a_dominant_plane_and_canal_cloud_is_sparse(sessions):
    s_sb, s_c = load_session(sessions["seabed"]), load_session(sessions["canal"])
    n_sb = len(load_cloud(s_sb.captures[0].cloud_path))
    n_c = len(load_cloud(s_c.captures[0].cloud_path))
    assert n_sb > 3 * n_c


def _fit_sphere(P, r_fixed=None, x0=None):
    x0 = P.mean(axis=0) if x0 is None else x0
    if r_fixed is None:
        f = least_squares(lambda x: np.linalg.norm(P - x[:3], axis=1) - x[3], np.r_[x0, 0.1])
        return f.x[:3], f.x[3]
    f = least_squares(lambda x: np.linalg.norm(P - x, axis=1) - r_fixed, x0)
    return f.x, r_fixed


def test_sonar_blooming_makes_the_sphere_bigger_and_closer():
    rng = np.random.default_rng(0)
    c = np.array([2.2, 0.3, -0.4])
    r = 0.11
    scene = Scene((MeshSphere(tuple(c), r),))
    cfg = SonarConfig(pan_step_deg=0.5, range_noise_m=0.0, range_quantum_m=0.0, spurious_rate=0.0)
    cloud = simulate_scan(scene, np.eye(4), cfg, rng)
    P = cloud.points_m
    assert len(P) > 50 and np.all(np.linalg.norm(P - c, axis=1) < 0.3)
    centre_free, r_free = _fit_sphere(P, x0=c)
    assert r_free > 1.1 * r  # blooms
    centre_fixed, _ = _fit_sphere(P, r, x0=c)
    toward = (c - centre_fixed) @ (c / np.linalg.norm(c))
    assert toward > 0.005  # a naive known-radius fit is pulled towards the sonar
    # every point sits on a beam from the origin, never farther than the far side of the sphere
    assert np.all(np.linalg.norm(P, axis=1) <= np.linalg.norm(c) + r)


def test_range_scale_multiplies_ranges():
    scene = Scene((Sphere((3.0, -0.5, 0.2), 0.3, Material(reflectivity=0.9)),
                   Rect((0, 0, -1.5), (0, 0, 1), material=Material(reflectivity=0.6))))
    base = dict(pan_step_deg=3.0, range_noise_m=0.0, range_quantum_m=0.0, spurious_rate=0.0)
    a = simulate_scan(scene, np.eye(4), SonarConfig(**base), np.random.default_rng(1)).points_m
    b = simulate_scan(scene, np.eye(4), SonarConfig(range_scale=1.02, **base), np.random.default_rng(1)).points_m
    assert len(a) == len(b) > 100
    assert np.allclose(b, 1.02 * a, atol=1e-9)


def test_sonar_frame_is_x_forward_y_left_z_up():
    """A target left of and above the sonar's forward axis shows at +y, +z in the cloud."""
    scene = Scene((Sphere((2.0, 0.8, 0.5), 0.15, Material(reflectivity=0.9)),))
    cfg = SonarConfig(pan_step_deg=1.0, range_noise_m=0.0, spurious_rate=0.0)
    P = simulate_scan(scene, np.eye(4), cfg, np.random.default_rng(0)).points_m
    m = P.mean(axis=0)
    assert m[0] > 1.5 and m[1] > 0.5 and m[2] > 0.3


def test_seeds_change_the_rig(sessions, tmp_path):
    rigs = [sample_rig(np.random.default_rng(s), 2, 1920, 1080) for s in range(6)]
    T = np.array([r.T_cam_sonar("cam1")[:3, 3] for r in rigs])
    f = np.array([r.cams["cam1"][0].fx for r in rigs])
    assert np.ptp(T, axis=0).max() > 0.05 and np.ptp(f) > 100
    other = generate_session(tmp_path / "s4", "quick", 4, **FAST)
    a = load_ground_truth(sessions["quick"])["cameras"]["cam1"]["T_cam_sonar"]
    b = load_ground_truth(other)["cameras"]["cam1"]["T_cam_sonar"]
    assert np.abs(a - b).max() > 0.01


def test_raycast_primitives_analytic():
    scene = Scene((Sphere((0, 0, 5), 1.0), Capsule((3, 0, 5), (3, 0, 8), 0.5), Cylinder((-3, 0, 5), (-3, 0, 8), 0.5),
                   Box((0, 3, 5), (0.5, 0.5, 0.5)), Disc((0, -3, 5), (0, 0, -1), 0.5),
                   Group((Sphere((0, 0, -5), 0.5), Sphere((0, 0, -8), 0.5))), Rect((0, 0, 20), (0, 0, -1))))
    d = np.array([[0, 0, 1], [3, 0, 5], [-3, 0, 6], [0, 3, 5], [0, -3, 5.0], [0, 0, -1], [0.5, 0.5, 1]])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t, hit, n = raycast(scene, np.zeros(3), d)
    expect = [4.0, np.sqrt(34) - 0.5, 5 / (6 / np.sqrt(45)), np.linalg.norm([0, 2.7, 4.5]), np.sqrt(34), 4.5]
    assert np.allclose(t[:6], expect, atol=1e-9)
    assert hit.tolist() == [0, 1, 2, 3, 4, 5, 6]
    assert np.allclose(n[0], [0, 0, -1]) and np.allclose(n[3], [0, 0, -1])
    assert np.allclose(np.linalg.norm(n, axis=1), 1)
    # per-ray origins give the same answer as one shared origin
    t2, hit2, _ = raycast(scene, np.zeros((len(d), 3)), d)
    assert np.allclose(t2, t) and (hit2 == hit).all()


def test_mesh_sphere_is_open_but_its_outline_is_the_sphere():
    c = np.array([0, 0, 3.0])
    scene = Scene((MeshSphere(tuple(c), 0.11),))
    rng = np.random.default_rng(0)
    xy = rng.uniform(-0.04, 0.04, (20000, 2))
    d = np.column_stack([xy, np.ones(len(xy))])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t, hit, _ = raycast(scene, np.zeros(3), d)
    miss_dist = np.linalg.norm(np.cross(d, c), axis=1)  # ray's distance from the centre
    assert np.all(hit[miss_dist > 0.11] == -1)  # nothing outside the sphere
    frac = (hit[miss_dist < 0.09] == 0).mean()
    assert 0.2 < frac < 0.95  # open lattice: holes and wires
    ta, hita, _ = raycast(scene, np.zeros(3), d, acoustic=True)
    assert np.all(hita[miss_dist < 0.1099] == 0)  # acoustically the envelope is solid


def test_antialiased_silhouette_is_geometrically_exact():
    """Coverage area and centroid of a rendered solid sphere match the analytic ellipse."""
    W, H, f = 320, 240, 300.0
    cam = CameraModel(W, H, [[f, 0, 150.3], [0, f, 118.7], [0, 0, 1]], np.zeros(5))
    T_cw = look_at_T_cam_world([0, 0, 0], [3, 0, 0])
    c = np.array([2.5, 0.55, 0.3])  # off-axis: the ellipse is elongated and off the projected centre
    r = 0.2
    scene = Scene((Sphere(tuple(c), r, Material((0, 0, 0), 0.5)),))
    water = Water(attenuation_per_m=0.0, water_rgb=(1, 1, 1), up_gain=0.0, side_gain=0.0)
    L, _ = render_radiance(scene, cam, invert_T(T_cw), water, aa=8)
    cover = 1 - L[..., 0]
    v, u = np.mgrid[0:H, 0:W].astype(float)
    area = cover.sum()
    cu, cv = (cover * u).sum() / area, (cover * v).sum() / area
    # analytic: cone conic Q = cos^2(a) I - w w^T in normalised coordinates
    C = transform_points(T_cw, c[None])[0]
    w = C / np.linalg.norm(C)
    a = np.arcsin(r / np.linalg.norm(C))
    Q = np.cos(a) ** 2 * np.eye(3) - np.outer(w, w)
    M, b, f0 = Q[:2, :2], Q[:2, 2], Q[2, 2]
    centre_n = -np.linalg.solve(M, b)
    k = b @ np.linalg.solve(M, b) - f0
    area_px = np.pi * k / np.sqrt(np.linalg.det(M)) * f * f
    centre_px = cam.distort(centre_n[None])[0]
    assert abs(area - area_px) / area_px < 0.002
    assert np.hypot(cu - centre_px[0], cv - centre_px[1]) < 0.02


def _run_cli(argv):
    from sonarcal_cli.commands import synth as cmd_synth

    p = argparse.ArgumentParser()
    cmd_synth.add_parser(p.add_subparsers())
    args = p.parse_args(["synth", *argv])
    return args.run(args)


def test_cli_refuses_non_empty_folder_and_unknown_preset(tmp_path, capsys):
    out = tmp_path / "s"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    assert _run_cli([str(out), "--preset", "quick", "--scale", "0.1"]) == 2
    assert "not empty" in capsys.readouterr().err
    assert _run_cli([str(tmp_path / "t"), "--preset", "nosuch"]) == 2
    err = capsys.readouterr().err
    assert "unknown preset" in err and "canal" in err and "wrongdiam" in err
    assert _run_cli([str(out), "--preset", "quick", "--seed", "2", "--scale", "0.1", "--force"]) == 0
    assert validate_session(out).problems == []
    assert (out / "keep.txt").read_text() == "mine"  # --force only replaces what synth writes
    assert load_ground_truth(out)["seed"] == 2


@pytest.mark.parametrize("n", [2, 7, 13, 19, 20])
def test_cone_offsets_average_on_the_beam_axis(n):
    """The simulated beam's sub-rays fill the cone, average exactly on its axis and spread alike in
    every direction: a plain sunflower of 13 averaged 0.025 deg off, tilting every simulated sonar
    centre (and the truth)."""
    from calib_core.synth.sonar_sim import cone_offsets

    h = np.radians(0.5)
    o = cone_offsets(n, h)
    assert o.shape == (n, 2)
    assert np.abs(o.mean(axis=0)).max() < 1e-12
    assert np.hypot(*o.T).max() <= h + 1e-15 and np.hypot(*o.T).max() > 0.7 * h
    if n >= 5:  # and spread equally in every direction (a point-symmetric sunflower of 13: 1.6x)
        eig = np.linalg.eigvalsh(o.T @ o)
        assert eig[1] / eig[0] < 1 + 1e-9
        assert np.hypot(*o.T).min() < 0.75 * h  # not only the edge
