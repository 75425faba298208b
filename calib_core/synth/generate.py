"""Write a complete synthetic session (plus ``ground_truth.yaml``) from a preset and a seed.

Every file goes through the atomic writers of :mod:`calib_core.io`. The seed varies the
intrinsics, the rig, the sphere diameter and lattice, the sphere positions (including
near image corners, 1-4 m away), turbidity, lighting, blur and noise.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from calib_core.geometry import invert_T, make_T, transform_points
from calib_core.io.atomic import atomic_write_yaml
from calib_core.io.clouds import save_cloud
from calib_core.io.images import save_image
from calib_core.io.intrinsics import save_intrinsics_ros
from calib_core.synth import range_scenes, room, world
from calib_core.synth.camera_render import RenderOptions, finish_image, render_radiance
from calib_core.synth.drift import drift_positions, write_drift_frames
from calib_core.synth.ground_truth import GT_FILE, GT_FORMAT, to_list
from calib_core.synth.occlusion import MAX_OCCLUDED_FRACTION, occluded_fraction
from calib_core.synth.presets import for_seed, get_preset
from calib_core.synth.range_capture import in_field, sensor_config, simulate_range
from calib_core.synth.rig import sample_in_sensor_view, sample_rig, sample_target_center, silhouette_uv, sphere_in_image
from calib_core.synth.scene import Scene
from calib_core.synth.sonar_sim import SonarConfig, simulate_scan

SOUND_SPEED = 1481.0
HOLDER_TRIES = 1000  # aimed at a camera pixel; then drawn in the range sensor's view
VIDEO_FPS = 5


def generate_session(out_dir, preset, seed: int, progress=None, **overrides) -> Path:
    """Generate session ``out_dir`` for ``preset`` (name or Preset) and ``seed``.

    ``overrides`` change preset fields (e.g. ``scale=0.25, pan_step_deg=2`` for fast tests).
    ``progress(done, total, label)`` is called after each rendered image / scan.
    Returns the session folder. Raises KeyError for an unknown preset name.
    """
    P = get_preset(preset).with_(**overrides) if overrides else get_preset(preset)
    P = for_seed(P, seed)
    out = Path(out_dir)
    ss = np.random.SeedSequence([int(seed), 7919])
    r_rig, r_scene, r_noise, r_sonar = (np.random.default_rng(s) for s in ss.spawn(4))
    W, H = max(16, round(1920 * P.scale)), max(9, round(1080 * P.scale))
    rig = sample_rig(r_rig, P.n_cameras, W, H, P.scale)
    cams = list(rig.cams)
    diameter = 0.22 if P.name == "canal" else float(r_rig.uniform(*P.diameter_range))
    radius = diameter / 2
    # a wrong stated diameter is too big or too small, by the preset's factor
    d_factor = P.diameter_factor if P.diameter_factor == 1 or r_rig.random() < 0.5 else 2 - P.diameter_factor
    style = world.sample_target_style(r_rig, radius)
    water = world.sample_water(r_scene, P.bright)
    if P.scene == "room":
        water = room.room_air(r_scene)
    elif P.turbidity > 0:  # contrast falls with distance: strong attenuation and veil
        water = replace(water, attenuation_per_m=float(r_scene.uniform(P.turbidity, P.turbidity + 0.3)))
    opts = RenderOptions(aa=4, blur_sigma_px=float(r_scene.uniform(0.5, 1.2)) * max(P.scale, 0.35)
                         * (1.5 if P.turbidity > 0 else 1.0),
                         noise_dn=float(r_scene.uniform(0.8, 3.0)), shot_gain=float(r_scene.uniform(0.05, 0.3)))
    cfg = SonarConfig(pan_step_deg=P.pan_step_deg, pan_span_deg=P.pan_span_deg, sub_rays=P.sub_rays,
                      range_scale=P.range_scale, range_noise_m=float(r_sonar.uniform(0.002, 0.006)),
                      spurious_rate=float(r_sonar.uniform(0.0005, 0.003)))
    if P.range_sensor != "sonar":  # a LiDAR or an RGB-D camera in the sonar's place
        cfg = sensor_config(P.range_sensor, r_sonar)

    if P.scene == "lab":
        surface_z, static = 50.0, []
    else:
        surface_z, static = world.surface_and_pontoons(r_scene, rig, P.scene)
    seabed_z = floor_z = None
    lowest = min(T[2, 3] for _, T in rig.cams.values())
    if P.scene == "room":  # dry: no surface; the floor plays the seabed's part
        surface_z, static = 50.0, []
    if P.scene in ("seabed", "room"):
        seabed_z = float(min(lowest, 0.0) - r_scene.uniform(0.5, 1.2))
    if P.scene == "lab":
        floor_z = float(min(lowest, 0.0) - r_scene.uniform(0.6, 1.0))
    T_sonar_world = invert_T(rig.T_world_sonar)

    def ok_extra(c):
        if c[2] > surface_z - 0.5 - radius:
            return False
        if floor_z is not None and c[2] - radius < floor_z + (0.5 if P.holder == "stick" else 0.3):
            return False
        if P.range_sensor != "sonar" and not in_field(P.range_sensor, transform_points(T_sonar_world, c[None])[0],
                                                      radius, cfg):
            return False
        return seabed_z is None or c[2] - radius > seabed_z + 0.25

    # ---- place the captures ---------------------------------------------------------
    centers = []
    n_corner = int(round(P.corner_fraction * P.n_captures))
    corner_idx = set(r_rig.choice(P.n_captures, n_corner, replace=False).tolist())
    for i in range(P.n_captures):
        ref = cams[i % len(cams)]
        if P.holder:  # the holder (slab, table, chair, person) must not hide the sphere
            base_z = floor_z if floor_z is not None else seabed_z
            seen = _HolderCheck(P, seed, i, rig, radius, base_z, ok_extra)
            zr = _holder_heights(P.holder, rig, radius, base_z)
            try:
                c, _ = sample_target_center(r_rig, rig, radius, ref, i in corner_idx, seen, tries=HOLDER_TRIES,
                                            z_range=zr)
            except RuntimeError:  # a narrow sensor field: draw in the sensor's view instead
                c = sample_in_sensor_view(r_rig, rig, radius, seen, zr)
        else:
            c, _ = sample_target_center(r_rig, rig, radius, ref, i in corner_idx, ok_extra)
        centers.append(c)
    moved_idx = int(r_rig.integers(P.n_captures)) if P.moved else -1
    image_centers = [c.copy() for c in centers]
    if moved_idx >= 0:
        for _ in range(500):
            v = r_rig.normal(0, 1, 3) * [1, 1, 0.4]
            cand = centers[moved_idx] + v / np.linalg.norm(v) * r_rig.uniform(0.10, 0.20)
            cam0, T_wc0 = rig.cams[cams[0]]
            if ok_extra(cand) and sphere_in_image(cam0, invert_T(T_wc0), cand, radius, 2.0):
                image_centers[moved_idx] = cand
                break
    drift_idx = int(r_rig.integers(P.n_captures)) if P.drift_m > 0 else -1
    decoy_idx = -1
    if P.decoy_hidden:
        decoy_idx = (moved_idx + 1 + int(r_rig.integers(P.n_captures - 1))) % P.n_captures
    if P.scene == "room":
        static += room.room_scene(r_scene, seabed_z, centers + image_centers)
        ball = room.ball_style(r_rig)
    elif seabed_z is not None:
        static += world.seabed_scene(r_scene, rig, seabed_z, centers + image_centers)
    if floor_z is not None:
        static += range_scenes.room(r_scene, floor_z)

    total = (P.n_captures + P.n_flange) * (1 + len(cams)) + len(cams)
    done = 0

    def tick(label):
        nonlocal done
        done += 1
        if progress is not None:
            progress(done, total, label)

    def target_parts(c, rng):
        if P.scene == "room":
            return room.ball_parts(rng, ball, c, radius, seabed_z, rig.cams[cams[0]][1][:3, 3])
        ball_part = (range_scenes.solid_ball(c, radius, P.bright) if P.solid_ball
                     else world.target(style, c, radius, P.bright))
        if P.holder:  # resting on a chair, a table or a slab, or on a stick held by a person
            base_z = floor_z if floor_z is not None else seabed_z
            return [ball_part] + range_scenes.holder_parts(rng, P.holder, c, radius, base_z, rig.T_world_sonar[:3, 3])
        parts = [ball_part]
        hold = (world.stand(rng, c - [0, 0, radius], seabed_z) if seabed_z is not None
                else world.chain(rng, c + [0, 0, radius - 0.5 * style["wire_m"]], surface_z))
        return parts + ([hold] if hold is not None else [])

    # ---- captures -------------------------------------------------------------------
    manifest_caps, gt_caps = [], {}
    first_radiance = {}
    ext = P.cloud_format
    ids = [f"p{i + 1:02d}" for i in range(P.n_captures)] + [f"f{i + 1:02d}" for i in range(P.n_flange)]
    for k, cid in enumerate(ids):
        is_target = k < P.n_captures
        # one random stream per capture: changing one capture's content leaves the others alone
        r_cap = np.random.default_rng([int(seed), 7919, 1000 + k])
        extra = (world.decoys(r_cap, rig, centers[k], radius, int(r_cap.integers(2, 5)))
                 if P.decoys and is_target else [])
        if is_target:
            scan_scene = Scene(tuple(static + target_parts(centers[k], r_cap) + extra))
            img_scene = scan_scene if k != moved_idx else Scene(tuple(static + target_parts(image_centers[k], r_cap) + extra))
            if k == decoy_idx:
                trick = world.decoy_and_occluder(r_cap, rig, centers[k], radius, style, P.bright)
                img_scene = Scene(tuple(img_scene.primitives) + tuple(trick))
        else:
            scan_scene = img_scene = Scene(tuple(static + world.flange_assembly(r_cap, rig, surface_z)))
        cloud = simulate_range(P.range_sensor, scan_scene, rig.T_world_sonar, cfg, r_cap)
        save_cloud(out / "clouds" / f"{cid}{ext}", cloud)
        tick(f"{cid} sonar")
        images = {}
        for cam_name in cams:
            cam, T_wc = rig.cams[cam_name]
            L, _ = render_radiance(img_scene, cam, T_wc, water, aa=opts.aa)
            if k == 0:
                first_radiance[cam_name] = L
            rel = f"images/{cam_name}/{cid}.jpg"
            save_image(out / rel, finish_image(L, opts, r_cap), jpeg_quality=P.jpeg_quality)
            images[cam_name] = rel
            tick(f"{cid} {cam_name}")
        manifest_caps.append({"id": cid, "cloud": f"clouds/{cid}{ext}", "images": images})
        gt_caps[cid] = _capture_truth(rig, img_scene, radius, centers[k] if is_target else None,
                                      image_centers[k] if is_target else None)
        if k == drift_idx:  # the drift preset: frames recorded while the sphere drifts
            gt_caps[cid]["drift"] = write_drift_frames(
                out, cid, rig, lambda c: Scene(tuple(static + target_parts(c, np.random.default_rng([seed, 5, k])) + extra)),
                drift_positions(r_cap, centers[k], P.drift_m), water, opts, r_cap, P.jpeg_quality)

    # ---- backgrounds, intrinsics, manifest, truth ------------------------------------
    bg_scene = Scene(tuple(static))
    cam_entries = {}
    for cam_name in cams:
        cam, T_wc = rig.cams[cam_name]
        save_intrinsics_ros(out / "intrinsics" / f"{cam_name}.yaml", cam, cam_name)
        cam_entries[cam_name] = {"intrinsics": f"intrinsics/{cam_name}.yaml"}
        if P.n_backgrounds > 0:
            L, _ = render_radiance(bg_scene, cam, T_wc, water, aa=opts.aa)
            if P.background_video:
                # 1 s with the target still in view, then the sphere-free window
                frames = [finish_image(first_radiance[cam_name], opts, r_noise) for _ in range(VIDEO_FPS)]
                frames += [finish_image(L, opts, r_noise) for _ in range(max(2, P.n_backgrounds) * VIDEO_FPS)]
                _save_video(out / "backgrounds" / f"{cam_name}.avi", frames)
                cam_entries[cam_name]["background"] = f"backgrounds/{cam_name}.avi"
                cam_entries[cam_name]["background_window"] = [1.2, None]
            else:
                for j in range(P.n_backgrounds):
                    save_image(out / "backgrounds" / cam_name / f"bg{j:02d}.jpg", finish_image(L, opts, r_noise),
                               jpeg_quality=P.jpeg_quality)
                cam_entries[cam_name]["background"] = f"backgrounds/{cam_name}/"
        tick(f"{cam_name} background")

    session = {
        "format": "sonar-camera-session/1",
        "name": f"synth-{P.name}-seed{seed}",
        "sphere": {"diameter": round(diameter * d_factor, 4)},
        "sonar": _sonar_block(P.range_sensor, cfg),
        "cameras": cam_entries,
        "captures": manifest_caps,
        "measured": _measured(r_noise, rig),
    }
    T_true = {c: rig.T_cam_sonar(c) for c in cams}
    gt = {"format": GT_FORMAT, "preset": P.name, "seed": int(seed), "range_scale": float(P.range_scale),
          "sphere_diameter_m": float(diameter), "session_diameter_m": session["sphere"]["diameter"],
          "cameras": {c: {"T_cam_sonar": to_list(T_true[c])} for c in cams}}
    if len(cams) == 2:
        T21 = T_true["cam2"] @ invert_T(T_true["cam1"])
        session["stereo"] = {"T_cam2_cam1": to_list(_checkerboard_error(r_noise, T21))}
        gt["stereo"] = {"T_cam2_cam1": to_list(T21)}
    if P.range_sensor == "sonar":
        gt["sonar"] = {"frame": "x forward, y left, z up (origin at the acoustic centre)",
                       "model": "first strong return in a cone of sub-rays, placed on the beam centre line",
                       "beam_width_deg": cfg.beam_width_deg, "n_beams": cfg.n_beams, "fan_deg": cfg.fan_deg,
                       "pan_step_deg": cfg.pan_step_deg, "pan_span_deg": cfg.pan_span_deg, "sub_rays": cfg.sub_rays,
                       "range_noise_m": cfg.range_noise_m, "range_quantum_m": cfg.range_quantum_m,
                       "true_sound_speed_m_s": SOUND_SPEED * P.range_scale}
    else:
        gt["sonar"] = {"frame": "x forward, y left, z up (origin at the optical centre)",
                       "sensor": P.range_sensor, "model": "one ray per return, no footprint (beam width 0)",
                       "beam_width_deg": 0.0, **{k: v for k, v in vars(cfg).items()}}
    gt["world"] = {"T_world_sonar": to_list(rig.T_world_sonar), "surface_z_m": surface_z,
                   "seabed_z_m": seabed_z, "attenuation_per_m": water.attenuation_per_m}
    gt["backgrounds"] = {c: ({"video": True, "fps": VIDEO_FPS, "target_until_s": 1.0} if P.background_video
                             else {"video": False, "frames": P.n_backgrounds}) for c in cams}
    gt["captures"] = gt_caps
    atomic_write_yaml(out / GT_FILE, gt)
    atomic_write_yaml(out / "session.yaml", session)
    return out


def _holder_heights(holder: str, rig, radius: float, base_z: float) -> tuple:
    """World heights (m) for the centre of a sphere on a holder: clear of the floor or seabed
    and, on a table or slab, with the sphere's bottom below every camera (a camera under
    the top of what the sphere rests on sees the top hide it; a chair's seat is narrower
    than the ball, so the occlusion test alone decides there)."""
    lo = base_z + (0.5 if holder == "stick" else 0.3) + radius
    if holder == "hand":  # held out at arm's length by a person standing on the floor
        return base_z + 0.6, base_z + 1.5
    if holder in ("stick", "chair"):
        return lo, np.inf
    return lo, min(T[2, 3] for _, T in rig.cams.values()) - 0.05 + radius


class _HolderCheck:
    """Placement test for presets whose sphere rests on (or is held by) something: the
    preset's own checks, then the sphere, with the very holder capture ``k`` will get (same
    random stream), hidden by at most MAX_OCCLUDED_FRACTION from every camera."""

    def __init__(self, P, seed, k, rig, radius, base_z, ok_extra):
        self.P, self.seed, self.k, self.rig = P, seed, k, rig
        self.radius, self.base_z, self.ok_extra = radius, base_z, ok_extra

    def __call__(self, c) -> bool:
        if not self.ok_extra(c):
            return False
        r_cap = np.random.default_rng([int(self.seed), 7919, 1000 + self.k])  # as in the capture loop
        ball = range_scenes.solid_ball(c, self.radius, self.P.bright)
        parts = range_scenes.holder_parts(r_cap, self.P.holder, c, self.radius, self.base_z,
                                          self.rig.T_world_sonar[:3, 3])
        scene = Scene((ball, *parts))
        limit = range_scenes.MAX_OCCLUDED.get(self.P.holder, MAX_OCCLUDED_FRACTION)
        return all(occluded_fraction(scene, 0, T_wc, c, self.radius) < limit
                   for _, T_wc in self.rig.cams.values())


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
