"""Held-out image kind "rov": a ball seen by a field or ROV video camera, as sonar calibrations
in the field are shot (built and measured before any detector change: BENCHMARKS.md, session 25).

- The camera (:func:`~calib_core.synth.photo.rov_parts.wide_lens`): 90-120 deg across, strong
  barrel distortion (plumb_bob k1 -0.35 to -0.25, k2 > 0); the renderer casts each pixel's ray
  through the exact inverse of that model, so the ball is squashed towards the corners as the
  lens shows it, and the detector is given these true intrinsics (``ImageCase.cam``). It sits
  at the rig's eye looking ahead and down by -30 to +5 deg.
- The frame: half analog PAL (720x576) or NTSC (720x480) video, half a digital camera's
  1920x1080 (both times ``scale`` / 0.5 and ``scale``: PAL is 720x576 at the benchmarks' 0.5).
  Analog frames are interlaced on most (the ball moves 0.1-1 m/s, so its two fields, a field
  period apart, are rendered with the ball 1-20 mm apart either side of its true centre:
  combed), have their chroma subsampled 4:2:0 or 4:1:1 with bleeding, and are compressed at a
  low bit rate (JPEG quality 15-45); digital frames are compressed at quality 35-80 on most
  (:mod:`calib_core.synth.photo.rov_video`).
- Burned in (:mod:`calib_core.synth.photo.rov_osd`): text with a dark outline, a compass tape, a
  crosshair and / or a circle reticle on most frames; a laser scaler's two red dots on a share.
- The vehicle (:func:`~calib_core.synth.photo.rov_parts.vehicle_parts`): a skid, a manipulator
  arm, the tether, each on a share; the dome port's rim darkening the corners on half (the
  ball is then placed clear of it: the rim's circle, 0.8-0.97 of the half diagonal, cuts
  only the corners).
- Exposure and white balance pump: the frame metered to 0.3-0.55 of white, red and blue gains
  0.7-1.3 each frame; lateral chromatic aberration growing to the corners on most.
- Water: open water (the underwater kind's: green or blue, backscatter; a seabed on most;
  marine snow on 60 %), a test tank, or a dock (:func:`~calib_core.synth.photo.rov_parts.environment`).
- The ball: an orange or yellow trawl float, white or black polystyrene, a grey gym ball
  (glossy), 0.05-0.25 m radius; on a rope to the surface, a pole, tethered to the bed or
  resting on it; its apparent radius 15 px (at PAL) to half the frame height, a third of the
  balls placed in a corner region of the frame (where the distortion is strongest).

The truth is the projection of the ball's centre through the lens (for an interlaced frame,
the centre midway between its two field positions). ``with_ball`` False renders the same scene
(same random draws) without the ball and its holder, one field. No constant here was taken
from a real image.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from calib_core.geometry import invert_T, transform_points
from calib_core.synth.camera_render import RenderOptions, finish_image, render_radiance
from calib_core.synth.photo import heldout as held
from calib_core.synth.photo import heldout_parts as hp
from calib_core.synth.photo import rov_osd, rov_video
from calib_core.synth.photo.cases import draw_photo, metered
from calib_core.synth.photo.effects import BallLook
from calib_core.synth.photo.rov_parts import environment, vehicle_parts, wide_lens
from calib_core.synth.photo.water import marine_snow
from calib_core.synth.rig import silhouette_uv
from calib_core.synth.scene import Cylinder, Material, Scene, Sphere

# (albedo, glossy, share): orange / yellow trawl floats, white and black polystyrene, a grey gym ball
BALLS = (((0.95, 0.40, 0.06), False, 0.3), ((0.92, 0.78, 0.08), False, 0.2), ((0.90, 0.90, 0.88), False, 0.2),
         ((0.06, 0.06, 0.07), False, 0.15), ((0.50, 0.50, 0.50), True, 0.15))
FIELD_S = {"pal": 0.020, "ntsc": 1 / 59.94}


def _frame(rng, scale: float) -> tuple[str, int, int]:
    """("pal" | "ntsc" | "digital", width, height) of this frame at ``scale``."""
    kind = str(rng.choice(["pal", "ntsc", "digital"], p=[0.3, 0.2, 0.5]))
    if kind == "digital":
        return kind, max(64, round(1920 * scale)), max(36, round(1080 * scale))
    s = scale / 0.5
    return kind, max(64, round(720 * s)), max(36, round((576 if kind == "pal" else 480) * s))



def _dome(rng, cam):
    """(radius px, soft px, housing colour) of the dome port's rim, or None."""
    if rng.random() >= 0.5:
        return None
    half_diag = 0.5 * np.hypot(cam.width_px, cam.height_px)
    return (float(rng.uniform(0.8, 0.97)) * half_diag, float(rng.uniform(0.02, 0.08)) * half_diag,
            tuple(np.full(3, rng.uniform(0.0, 0.05))))


def _place(rng, cam, T_wc, radius, scale, holder, dome):
    eye = hp.eye_of(T_wc)
    corner = rng.random() < 0.33
    u_rng = (0.0, 0.3) if rng.random() < 0.5 else (0.7, 1.0)
    v_rng = (0.0, 0.35) if rng.random() < 0.5 else (0.65, 1.0)

    def ok(c):
        C = transform_points(invert_T(T_wc), c[None])[0]
        if np.linalg.norm(C) > 6.0 or (holder == "bed" and c[2] - radius > eye[2] - 0.3):
            return False
        return dome is None or rov_video.inside_dome(silhouette_uv(cam, C, radius), cam.width_px, cam.height_px,
                                                     dome[0], dome[1])
    r_px = (30.0 * scale, 0.5 * cam.height_px)
    if corner:
        try:
            return hp.place_by_size(rng, cam, T_wc, radius, r_px, ok, v_range=v_rng, u_range=u_rng), True
        except RuntimeError:
            pass
    return hp.place_by_size(rng, cam, T_wc, radius, r_px, ok), False


def _ball(rng, c, radius):
    i = int(rng.choice(len(BALLS), p=[b[2] for b in BALLS]))
    alb = np.clip(np.array(BALLS[i][0]) * rng.uniform(0.85, 1.05), 0, 1)
    ball = Sphere(tuple(c), radius, Material(tuple(alb), 0.9, "foam", 0.02, float(rng.uniform(0.0, 0.08)),
                                             int(rng.integers(1 << 30))), tag="target")
    look = BallLook(tuple(c), radius, ks=float(rng.uniform(0.3, 1.0) if BALLS[i][1] else rng.uniform(0.0, 0.3)),
                    shininess=float(rng.uniform(20, 100)))
    return ball, look


def _holder(rng, holder, ball, c, radius, floor_z, surface_z, T_wc) -> list:
    if holder == "pole":
        d = np.array([*rng.normal(0, 0.5, 2), 1.0])
        d /= np.linalg.norm(d)
        top = np.asarray(c) + d * (surface_z - c[2]) / d[2]
        return [Cylinder(tuple(np.asarray(c) + 0.9 * radius * d), tuple(top), float(rng.uniform(0.01, 0.025)),
                         Material(tuple(rng.uniform(0.05, 0.6, 3)), 0.5), tag="stand")]
    if holder == "bed":
        return []
    return held.water_holder(rng, holder, ball, c, radius, floor_z, surface_z, T_wc)


def _scene(rng, cam, T_wc, scale, dome):
    """Ball, holder, environment and vehicle: (static, parts, ball, look, water, c, radius, label bits)."""
    eye = hp.eye_of(T_wc)
    where = str(rng.choice(["open", "bed", "tank", "dock"], p=[0.25, 0.45, 0.15, 0.15]))
    holder = str(rng.choice(["rope", "pole", "tether", "bed"] if where != "open" else ["rope", "pole"]))
    radius = float(rng.uniform(0.05, 0.25))
    try:
        c, corner = _place(rng, cam, T_wc, radius, scale, holder, dome)
    except RuntimeError:  # the bed below the camera is out of view: on a rope instead
        holder = "rope"
        c, corner = _place(rng, cam, T_wc, radius, scale, holder, dome)
    floor_z = float(c[2] - radius if holder == "bed" else min(eye[2], c[2] - radius) - rng.uniform(0.5, 2.5))
    surface_z = float(max(eye[2], c[2] + radius) + rng.uniform(0.5, 4.0))
    static, water, _ = environment(rng, where, T_wc, c, radius, floor_z, surface_z)
    ball, look = _ball(rng, c, radius)
    parts = [ball] + _holder(rng, holder, ball, c, radius, floor_z, surface_z, T_wc)
    vehicle, vnames = vehicle_parts(rng, cam, T_wc, ball)
    bits = [where, holder] + (["corner"] if corner else []) + vnames
    return static + vehicle, parts, ball, look, water, c, radius, bits


def _fields(rng, kind, scene_static, parts, ball, with_ball, cam, T_wc, water, photo):
    """Radiance of the frame: one render, or two fields with the ball moved either way (interlaced)."""
    interlaced = kind != "digital" and rng.random() < 0.8
    speed, d = float(rng.uniform(0.1, 1.0)), rng.normal(0, 1, 3)
    step = speed * FIELD_S.get(kind, 0.02) * d / np.linalg.norm(d)
    if not with_ball:
        photo = replace(photo, occluders=())
        return render_radiance(Scene(tuple(scene_static)), cam, T_wc, water, aa=3, photo=photo)[0], interlaced
    if not interlaced:
        return render_radiance(Scene(tuple(scene_static + parts)), cam, T_wc, water, aa=3, photo=photo)[0], False
    fields = []
    for sign in (-0.5, 0.5):
        moved = replace(ball, center_m=tuple(np.asarray(ball.center_m) + sign * step))
        look = replace(photo.ball, centre_m=moved.center_m)
        fields.append(render_radiance(Scene(tuple(scene_static + [moved] + parts[1:])), cam, T_wc, water, aa=3,
                                      photo=replace(photo, ball=look))[0])
    return rov_video.interlace(fields[0], fields[1]), True


def _camera_light(rng, photo, L, scale, where):
    """Exposure and white balance pumping, snow, laser dots, chromatic aberration (radiance)."""
    photo = replace(metered(rng, photo, L), wb_gains=(float(rng.uniform(0.7, 1.3)), 1.0, float(rng.uniform(0.7, 1.3))))
    tags = []
    if where != "tank" and rng.random() < 0.6:
        s = scale / 0.5
        L = marine_snow(L, rng, int(rng.uniform(20, 300) * s * s), (0.4 * s, 2.5 * s), float(rng.uniform(0.3, 0.9)),
                        float(rng.uniform(1.0, 4.0)) * s)
        tags.append("snow")
    if rng.random() < 0.35:
        L = rov_osd.laser_dots(L, rng, scale)
        tags.append("laser")
    if rng.random() < 0.7:
        L = rov_video.chromatic_aberration(L, float(rng.uniform(0.001, 0.004)))
        tags.append("ca")
    return photo, L, tags


def _video(rng, kind, img, scale):
    """OSD, chroma subsampling and compression of the 8-bit frame."""
    tags = []
    if rng.random() < 0.85:
        img = rov_osd.draw_osd(img, rov_osd.sample_osd(rng, img.shape[0]))
        tags.append("osd")
    if kind != "digital":
        scheme = str(rng.choice(["420", "411"]))
        img = rov_video.chroma_subsample(img, scheme, float(rng.uniform(0.5, 2.0)), float(rng.uniform(-1.0, 1.0)))
        q = int(rng.integers(15, 46))
        tags.append(scheme)
    else:
        q = int(rng.integers(35, 81)) if rng.random() < 0.8 else 0
    if q:
        img = rov_video.compress(img, q)
        tags.append(f"q{q}")
    return img, tags


def rov(rng, rig, T_wc, scale: float, with_ball: bool, opts: RenderOptions):
    """(image uint8, camera, T_world_cam, ball centre (world), radius m, label) of one frame."""
    kind, W, H = _frame(rng, scale)
    cam = wide_lens(rng, W, H)
    T_wc = hp.pose_ahead(rng, T_wc, (-30, 5))
    dome = _dome(rng, cam)
    static, parts, ball, look, water, c, radius, bits = _scene(rng, cam, T_wc, scale, dome)
    photo = replace(draw_photo(rng, c, radius, hp.eye_of(T_wc), look, scale),
                    softness=float(rng.uniform(0.05, 0.2)), vignette=float(rng.uniform(0.1, 0.5)), bloom_px=0.0)
    photo, opts = hp.camera_artefacts(rng, photo, opts, scale)
    photo = replace(photo, jpeg_quality=0)  # the video's own compression comes last
    L, interlaced = _fields(rng, kind, static, parts, ball, with_ball, cam, T_wc, water, photo)
    photo, L, light_tags = _camera_light(rng, photo, L, scale, bits[0])
    if dome is not None:
        L = rov_video.dome_edge(L, *dome)
    img = finish_image(L, opts, rng, photo)
    img, video_tags = _video(rng, kind, img, scale)
    tags = (["interlaced"] if interlaced else []) + (["dome"] if dome else []) + light_tags + video_tags
    label = f"rov/{kind}/{'/'.join(bits)}/{'+'.join(tags) or 'plain'}/{hp.artefact_label(photo, opts)}"
    return img, cam, T_wc, c, radius, label
