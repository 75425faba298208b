"""Write a complete synthetic session (plus ``ground_truth.yaml``) from a preset and a seed.

Every file goes through the atomic writers of :mod:`calib_core.io`. The seed varies the
intrinsics, the rig, the sphere diameter and lattice, the sphere positions (including
near image corners, 1-4 m away), turbidity, lighting, blur and noise.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from calib_core.geometry import invert_T, make_T, transform_points
from calib_core.io.atomic import atomic_write_yaml
from calib_core.io.clouds import save_cloud
from calib_core.io.images import save_image
from calib_core.io.intrinsics import save_intrinsics_ros
from calib_core.synth import world
from calib_core.synth.camera_render import finish_image, render_radiance
from calib_core.synth.drift import drift_positions, write_drift_frames
from calib_core.synth.ground_truth import GT_FILE, GT_FORMAT, to_list
from calib_core.synth.layout import Layout, Placement, add_surroundings, place_targets, sample_layout
from calib_core.synth.occlusion import occluded_fraction
from calib_core.synth.photo.session import background_photo, capture_light, dress, render_capture, session_look
from calib_core.synth.presets import for_seed, get_preset
from calib_core.synth.range.capture import simulate_range
from calib_core.synth.rig import silhouette_uv
from calib_core.synth.scene import Scene

SOUND_SPEED = 1481.0
VIDEO_FPS = 5


def generate_session(out_dir, preset, seed: int, progress=None, **overrides) -> Path:
    """Generate session ``out_dir`` for ``preset`` (name or Preset) and ``seed``.

    ``overrides`` change preset fields (e.g. ``scale=0.25, pan_step_deg=2`` for fast tests).
    ``progress(done, total, label)`` is called after each rendered image / scan.
    Returns the session folder. Raises KeyError for an unknown preset name.
    """
    P = get_preset(preset).with_(**overrides) if overrides else get_preset(preset)
    P = for_seed(P, seed)  # a preset's alternatives by seed (the carried ball's sensor)
    out = Path(out_dir)
    ss = np.random.SeedSequence([int(seed), 7919])
    r_rig, r_scene, r_noise, r_sonar = (np.random.default_rng(s) for s in ss.spawn(4))
    L = sample_layout(P, seed, r_rig, r_scene, r_sonar)
    pl = place_targets(L, r_rig)
    add_surroundings(L, pl, r_scene, r_rig)
    tick = _Ticker((P.n_captures + P.n_flange) * (1 + len(L.cams)) + len(L.cams), progress)
    look = session_look(P.photo, seed, L.radius) if P.photo else None
    if look is not None:  # indoors: air instead of the lab's water veil (the range sensor does not see it)
        L.water = look.air
    manifest_caps, gt_caps, first_radiance = _write_captures(out, L, pl, tick, look)
    cam_entries = _write_backgrounds(out, L, first_radiance, r_noise, tick, look)
    session, gt = _manifest_and_truth(L, cam_entries, manifest_caps, gt_caps, r_noise)
    atomic_write_yaml(out / GT_FILE, gt)
    atomic_write_yaml(out / "session.yaml", session)
    return out


class _Ticker:
    """Counts finished scans and images and reports them to ``progress(done, total, label)``."""

    def __init__(self, total: int, progress=None):
        self.total, self.progress, self.done = total, progress, 0

    def __call__(self, label: str) -> None:
        self.done += 1
        if self.progress is not None:
            self.progress(self.done, self.total, label)


def _capture_ids(P) -> list[str]:
    return [f"p{i + 1:02d}" for i in range(P.n_captures)] + [f"f{i + 1:02d}" for i in range(P.n_flange)]


def _write_captures(out: Path, L: Layout, pl: Placement, tick, look=None) -> tuple[list, dict, dict]:
    """Every capture's cloud and images: (manifest entries, truth per capture, first radiance per camera;
    with ``look``, a photographic preset's, also ``(cam, "photo")`` -> that image's Photo)."""
    P, rig = L.P, L.rig
    manifest_caps, gt_caps, first_radiance = [], {}, {}
    for k, cid in enumerate(_capture_ids(P)):
        is_target = k < P.n_captures
        # one random stream per capture: changing one capture's content leaves the others alone
        r_cap = np.random.default_rng([int(L.seed), 7919, 1000 + k])
        scan_scene, img_scene, extra = _capture_scenes(L, pl, k, r_cap)
        cloud = simulate_range(P.range_sensor, scan_scene, rig.T_world_sonar, L.cfg, r_cap)
        save_cloud(out / "clouds" / f"{cid}{P.cloud_format}", cloud)
        tick(f"{cid} sonar")
        light = _capture_light(L, pl, look, k)
        images = _write_images(out, L, cid, img_scene, r_cap, first_radiance if k == 0 else None, tick, light)
        manifest_caps.append({"id": cid, "cloud": f"clouds/{cid}{P.cloud_format}", "images": images})
        gt_caps[cid] = _capture_truth(rig, img_scene, L.radius, pl.centers[k] if is_target else None,
                                      pl.image_centers[k] if is_target else None)
        if light is not None:  # a photographic preset: the ball's blur during the exposure (px), if any
            gt_caps[cid]["motion_px"] = None if light[1].motion_px is None else to_list(light[1].motion_px)
        if k == pl.drift_idx:  # the drift preset: frames recorded while the sphere drifts
            gt_caps[cid]["drift"] = write_drift_frames(
                out, cid, rig, partial(_drift_scene, L, k, extra),
                _drift_line(L, pl, k), L.water, L.opts, r_cap, P.jpeg_quality, stills=images)
    return manifest_caps, gt_caps, first_radiance


def _capture_scenes(L: Layout, pl: Placement, k: int, r_cap) -> tuple:
    """(scene scanned, scene photographed, extra parts) of capture ``k`` (a flange capture past
    the target captures)."""
    P = L.P
    is_target = k < P.n_captures
    extra = (world.decoys(r_cap, L.rig, pl.centers[k], L.radius, int(r_cap.integers(2, 5)))
             if P.decoys and is_target else [])
    if not is_target:
        scene = Scene(tuple(L.static + world.flange_assembly(r_cap, L.rig, L.surface_z)))
        return scene, scene, extra
    # the drifting capture's scene is its drift frames' (the same holder through the scan)
    scan_scene = (L.scene(pl.centers[k], r_cap, extra) if k != pl.drift_idx
                  else _drift_scene(L, k, extra, pl.centers[k]))
    img_scene = scan_scene if k != pl.moved_idx else L.scene(pl.image_centers[k], r_cap, extra)
    if k == pl.decoy_idx:
        trick = world.decoy_and_occluder(r_cap, L.rig, pl.centers[k], L.radius, L.style, P.bright)
        img_scene = Scene(tuple(img_scene.primitives) + tuple(trick))
    return scan_scene, img_scene, extra


def _drift_line(L: Layout, pl: Placement, k: int) -> np.ndarray:
    """The drifting sphere's centres: across the first camera's line of sight, the sense from a
    stream of the capture's own (not ``r_cap``, whose draws depend on the clouds simulated)."""
    eye = L.rig.cams[L.cams[0]][1][:3, 3]
    return drift_positions(np.random.default_rng([int(L.seed), 7, k]), pl.centers[k], L.P.drift_m, eye)


def _drift_scene(L: Layout, k: int, extra: list, c) -> Scene:
    """Capture ``k``'s scene with the drifting sphere at ``c`` (its holder from a stream of its own)."""
    return L.scene(c, np.random.default_rng([L.seed, 5, k]), extra)


def _capture_light(L: Layout, pl: Placement, look, k: int):
    """(look, light) of target capture ``k`` of a photographic preset, else None."""
    if look is None or k >= L.P.n_captures:
        return None
    eye = L.rig.cams[L.cams[0]][1][:3, 3]
    return look, capture_light(look, L.seed, k, pl.image_centers[k], L.radius, eye, L.P.scale)


def _write_images(out: Path, L: Layout, cid: str, img_scene, r_cap, first_radiance: dict | None, tick,
                  light=None) -> dict:
    """Render and save every camera's image of one capture; keep the radiance in ``first_radiance``.
    ``light``: (SessionLook, CaptureLight) of a photographic preset (the scene is dressed)."""
    images = {}
    for cam_name in L.cams:
        cam, T_wc = L.rig.cams[cam_name]
        photo = None
        if light is None:
            radiance, _ = render_radiance(img_scene, cam, T_wc, L.water, aa=L.opts.aa)
        else:
            radiance, photo = render_capture(dress(img_scene, light[0]), cam, T_wc, L.water, L.opts.aa, light[1],
                                             r_cap, L.P.scale)
        if first_radiance is not None:
            first_radiance[cam_name] = radiance
            if photo is not None:
                first_radiance[(cam_name, "photo")] = photo
        rel = f"images/{cam_name}/{cid}.jpg"
        save_image(out / rel, finish_image(radiance, L.opts, r_cap, photo), jpeg_quality=L.P.jpeg_quality)
        images[cam_name] = rel
        tick(f"{cid} {cam_name}")
    return images


def _write_backgrounds(out: Path, L: Layout, first_radiance: dict, r_noise, tick, look=None) -> dict:
    """Intrinsics and background frames (or video) of every camera: session.yaml's ``cameras``
    (a photographic preset's: the dressed room with the first capture's camera effects)."""
    P = L.P
    bg_scene = Scene(tuple(L.static)) if look is None else dress(Scene(tuple(L.static)), look)
    cam_entries = {}
    for cam_name in L.cams:
        cam, T_wc = L.rig.cams[cam_name]
        save_intrinsics_ros(out / "intrinsics" / f"{cam_name}.yaml", cam, cam_name)
        cam_entries[cam_name] = {"intrinsics": f"intrinsics/{cam_name}.yaml"}
        if P.n_backgrounds > 0:
            photo = first_radiance.get((cam_name, "photo"))
            photo = None if photo is None else background_photo(photo)
            radiance, _ = render_radiance(bg_scene, cam, T_wc, L.water, aa=L.opts.aa, photo=photo)
            cam_entries[cam_name].update(_write_background(out, L, cam_name, radiance, first_radiance[cam_name]
                                                           if P.background_video else None, r_noise, photo))
        tick(f"{cam_name} background")
    return cam_entries


def _write_background(out: Path, L: Layout, cam_name: str, radiance, first, r_noise, photo=None) -> dict:
    """One camera's background: a video (whose first second still shows the target, ``first``)
    when the preset asks for one, else still frames. Returns its session.yaml keys."""
    P, opts = L.P, L.opts
    if P.background_video:
        # 1 s with the target still in view, then the sphere-free window
        frames = [finish_image(first, opts, r_noise, photo) for _ in range(VIDEO_FPS)]
        frames += [finish_image(radiance, opts, r_noise, photo) for _ in range(max(2, P.n_backgrounds) * VIDEO_FPS)]
        _save_video(out / "backgrounds" / f"{cam_name}.avi", frames)
        return {"background": f"backgrounds/{cam_name}.avi", "background_window": [1.2, None]}
    for j in range(P.n_backgrounds):
        save_image(out / "backgrounds" / cam_name / f"bg{j:02d}.jpg", finish_image(radiance, opts, r_noise, photo),
                   jpeg_quality=P.jpeg_quality)
    return {"background": f"backgrounds/{cam_name}/"}


def _manifest_and_truth(L: Layout, cam_entries: dict, manifest_caps: list, gt_caps: dict, r_noise) -> tuple[dict, dict]:
    """(session.yaml, ground_truth.yaml) contents."""
    P, rig, cams = L.P, L.rig, L.cams
    session = {
        "format": "sonar-camera-session/1",
        "name": f"synth-{P.name}-seed{L.seed}",
        "sphere": {"diameter": round(L.diameter * L.d_factor, 4)},
        "sonar": _sonar_block(P.range_sensor, L.cfg),
        "cameras": cam_entries,
        "captures": manifest_caps,
        "measured": _measured(r_noise, rig),
    }
    T_true = {c: rig.T_cam_sonar(c) for c in cams}
    gt = {"format": GT_FORMAT, "preset": P.name, "seed": int(L.seed), "range_scale": float(P.range_scale),
          "sphere_diameter_m": float(L.diameter), "session_diameter_m": session["sphere"]["diameter"],
          "cameras": {c: {"T_cam_sonar": to_list(T_true[c])} for c in cams}}
    if len(cams) >= 2:  # every other camera tied to cam1 (T_<cam>_cam1), as checkerboards give them
        session["stereo"], gt["stereo"] = {}, {}
        for c in cams[1:]:
            T_c1 = T_true[c] @ invert_T(T_true["cam1"])
            session["stereo"][f"T_{c}_cam1"] = to_list(_checkerboard_error(r_noise, T_c1))
            gt["stereo"][f"T_{c}_cam1"] = to_list(T_c1)
    gt["sonar"] = _sensor_truth(P, L.cfg)
    gt["world"] = {"T_world_sonar": to_list(rig.T_world_sonar), "surface_z_m": L.surface_z,
                   "seabed_z_m": L.seabed_z, "attenuation_per_m": L.water.attenuation_per_m}
    gt["backgrounds"] = {c: ({"video": True, "fps": VIDEO_FPS, "target_until_s": 1.0} if P.background_video
                             else {"video": False, "frames": P.n_backgrounds}) for c in cams}
    gt["captures"] = gt_caps
    return session, gt


def _sensor_truth(P, cfg) -> dict:
    """ground_truth.yaml's range-sensor block: the simulation's model and parameters."""
    if P.range_sensor == "sonar":
        return {"frame": "x forward, y left, z up (origin at the acoustic centre)",
                "model": "first strong return in a cone of sub-rays, placed on the beam centre line",
                "beam_width_deg": cfg.beam_width_deg, "n_beams": cfg.n_beams, "fan_deg": cfg.fan_deg,
                "pan_step_deg": cfg.pan_step_deg, "pan_span_deg": cfg.pan_span_deg, "sub_rays": cfg.sub_rays,
                "range_noise_m": cfg.range_noise_m, "range_quantum_m": cfg.range_quantum_m,
                "true_sound_speed_m_s": SOUND_SPEED * P.range_scale}
    return {"frame": "x forward, y left, z up (origin at the optical centre)",
            "sensor": P.range_sensor, "model": "one ray per return, no footprint (beam width 0)",
            "beam_width_deg": 0.0, **{k: v for k, v in vars(cfg).items()}}


def _sonar_block(sensor: str, cfg) -> dict:
    """session.yaml's range-sensor block. Only the sonar states a beam width: for the others
    the detector has to find out that there is (almost) none."""
    if sensor == "sonar":
        return {"model": "BlueView BV5000-2250 (simulated)", "sound_speed": SOUND_SPEED,
                "beam_width_deg": cfg.beam_width_deg}
    name = {"lidar16": "16-ring spinning LiDAR (simulated)", "rgbd": "RGB-D depth camera (simulated)"}[sensor]
    return {"model": name}


def _capture_truth(rig, img_scene, radius, c_scan_world, c_img_world) -> dict:
    T_sw = invert_T(rig.T_world_sonar)
    if c_scan_world is None:
        return {"target": False, "center_sonar_m": None, "center_sonar_at_image_m": None, "moved_m": 0.0,
                "images": {c: {"center_uv_px": None, "visible": False} for c in rig.cams}}
    ent = {"target": True,
           "center_sonar_m": to_list(transform_points(T_sw, c_scan_world[None])[0]),
           "center_sonar_at_image_m": to_list(transform_points(T_sw, c_img_world[None])[0]),
           "moved_m": float(np.linalg.norm(c_img_world - c_scan_world)), "images": {}}
    tid = img_scene.ids_with_tag("target")[0]
    for name, (cam, T_wc) in rig.cams.items():
        C = transform_points(invert_T(T_wc), c_img_world[None])[0]
        uv = cam.project(C[None])[0] if C[2] > 0 else None
        sil = silhouette_uv(cam, C, radius)
        in_img = bool(np.isfinite(sil).all() and cam.in_image(sil).all())
        occl = occluded_fraction(img_scene, tid, T_wc, c_img_world, radius)
        ent["images"][name] = {"center_uv_px": to_list(uv), "visible": bool(in_img and occl <= 0.25),
                               "in_image": in_img, "occluded_fraction": round(occl, 4),
                               "distance_m": float(np.linalg.norm(C))}
    return ent


def _save_video(path: Path, frames_rgb: list) -> None:
    """MJPG .avi written to a temporary folder, then moved into place atomically."""
    import tempfile

    import cv2

    from calib_core.io.atomic import atomic_write_bytes

    h, w = frames_rgb[0].shape[:2]
    with tempfile.TemporaryDirectory() as tmp:
        tmp_path = Path(tmp) / path.name
        vw = cv2.VideoWriter(str(tmp_path), cv2.VideoWriter_fourcc(*"MJPG"), float(VIDEO_FPS), (w, h))
        if not vw.isOpened():
            raise RuntimeError("OpenCV cannot write MJPG video here")
        for f in frames_rgb:
            vw.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
        vw.release()
        atomic_write_bytes(path, tmp_path.read_bytes())


def _measured(rng, rig) -> dict:
    """Tape-measured baselines: true origin distances + a few mm (origins are not physical points)."""
    names = list(rig.cams)
    m = {f"{c}-sonar": round(float(np.linalg.norm(rig.T_cam_sonar(c)[:3, 3]) + rng.normal(0, 0.004)), 4) for c in names}
    if len(names) == 2:
        T = rig.T_cam_world(names[1]) @ rig.cams[names[0]][1]
        m[f"{names[0]}-{names[1]}"] = round(float(np.linalg.norm(T[:3, 3]) + rng.normal(0, 0.003)), 4)
    return m


def _checkerboard_error(rng, T21) -> np.ndarray:
    """A stereo transform as a checkerboard calibration would give it (~0.1 deg, ~2 mm off)."""
    dR = Rotation.from_rotvec(rng.normal(0, np.deg2rad(0.08), 3)).as_matrix()
    return make_T(dR @ T21[:3, :3], T21[:3, 3] + rng.normal(0, 0.002, 3))
