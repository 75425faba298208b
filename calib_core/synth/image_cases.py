"""Single-image detection cases with ground truth, for the image-detector tests and benchmarks.

Each case is one rendered camera image of a scene kind (no sonar, no session files):
- "clutter": the dry textured room of :mod:`calib_core.synth.room` (brick wall, tiled floor,
  furniture blocks), a matte foam ball of a random colour on a stick or resting on a block;
  no background frame;
- "big": the same room with the ball close (apparent radius up to ~half the frame height);
- "turbid": the canal scene with strong attenuation, veil and blur, sphere 2.2-3.8 m away
  (contrast falls with distance);
- "chair": the room with a ball of any colour (grey often: a gym ball) resting on a chair,
  its dark backrest right behind the ball and the seat's edge along its bottom, so that the
  edges of things touching the sphere run next to its outline (real data set A);
- "glossy", "panels", "motion": photographic effects (highlight and bloom, cast and contact
  shadows, markings, vignetting, exposure and white balance, motion blur) on a gym ball on a
  chair or the floor, a beach ball, a carried foam ball: see :mod:`calib_core.synth.photo.cases`;
- "sports", "outdoor", "underwater": held-out kinds (patterned sports balls; hard sun, sky and
  ground textures; colour attenuation, backscatter, caustics, a dive light and marine snow),
  with camera artefacts (JPEG, high gain, defocus, shake) on a share: see
  :mod:`calib_core.synth.photo.heldout`;
- "mesh", "tank", "dim": held-out kinds of the third round: see-through balls (open lattice,
  cage, knotted net, wiffle holes: :mod:`calib_core.synth.photo.mesh_case`), a pool seen from
  under water with the ball mirrored by the surface and a glass wall
  (:mod:`calib_core.synth.photo.tank`), low light at high gain (:mod:`calib_core.synth.photo.dim`);
- "rov": held-out kind of the fourth round: a field or ROV video camera (wide-angle lens with
  strong barrel distortion, its own frame size: analog PAL / NTSC video interlaced, chroma
  subsampled and compressed, or a digital frame; an on-screen display, the vehicle's parts and
  the dome port's rim in view): see :mod:`calib_core.synth.photo.rov`.

``render_case(kind, seed, scale)`` returns the image, the camera, the sphere radius, the true
projection of the sphere centre (raw px), the visible fraction of the outline and, where the
scene has one, a background image.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_core.camera import CameraModel
from calib_core.geometry import invert_T, transform_points
from calib_core.synth import room, world
from calib_core.synth.photo import cases as photo_cases
from calib_core.synth.range import scenes as range_scenes
from calib_core.synth.photo import heldout as heldout_cases
from calib_core.synth.photo.dim import dim as dim_case
from calib_core.synth.photo.mesh_case import mesh as mesh_case
from calib_core.synth.photo.rov import rov as rov_case
from calib_core.synth.photo.tank import tank as tank_case
from calib_core.synth.camera_render import RenderOptions, Water, finish_image, render_radiance
from calib_core.synth.rig import sample_rig, sample_target_center, silhouette_uv
from calib_core.synth.scene import Scene

KINDS = ("clutter", "big", "turbid", "chair", "glossy", "panels", "motion", "sports", "outdoor", "underwater",
         "mesh", "tank", "dim", "rov")
PHOTO_KINDS = {"glossy": photo_cases.glossy, "panels": photo_cases.panels, "motion": photo_cases.motion}
HELDOUT_KINDS = {**heldout_cases.HELDOUT_KINDS, "mesh": mesh_case, "dim": dim_case}


@dataclass
class ImageCase:
    image: np.ndarray  # (H,W,3) uint8
    cam: CameraModel
    radius_m: float
    true_uv_px: np.ndarray  # (2,)
    radius_px: float
    background: np.ndarray | None
    label: str
    range_m: float | None = None  # camera to sphere centre


def render_case(kind: str, seed: int, scale: float = 0.5, with_ball: bool = True) -> ImageCase:
    """Render one case of ``kind`` for ``seed`` at ``scale`` x 1920x1080 (``with_ball`` False:
    the same scene without the sphere and its holder, for false-detection counts)."""
    if kind not in KINDS:
        raise ValueError(f"unknown case kind {kind!r}; use one of {KINDS}")
    rng = np.random.default_rng([int(seed), 5151, KINDS.index(kind)])
    W, H = max(64, round(1920 * scale)), max(36, round(1080 * scale))
    rig = sample_rig(rng, 1, W, H, scale)
    cam, T_wc = rig.cams["cam1"]
    opts = RenderOptions(aa=3, blur_sigma_px=float(rng.uniform(0.5, 1.1)) * max(scale, 0.35),
                         noise_dn=float(rng.uniform(1.0, 3.0)), shot_gain=float(rng.uniform(0.05, 0.3)))
    if kind == "turbid":
        return _turbid(rng, rig, cam, T_wc, opts, seed, with_ball)
    if kind == "chair":
        return _chair(rng, rig, cam, T_wc, opts, seed, with_ball)
    if kind == "tank":  # its own camera pose (looking up at the water surface)
        L, c, radius, photo, opts, label, T_wc = tank_case(rng, rig, cam, T_wc, scale, with_ball, opts)
        return _finish(L, None, cam, T_wc, c, radius, opts, rng, f"{label}/s{seed}", photo)
    if kind == "rov":  # its own camera, pose and frame finishing
        img, cam, T_wc, c, radius, label = rov_case(rng, rig, T_wc, scale, with_ball, opts)
        return _with_truth(img, None, cam, T_wc, c, radius, f"{label}/s{seed}")
    if kind in HELDOUT_KINDS:
        L, c, radius, photo, opts, label = HELDOUT_KINDS[kind](rng, rig, cam, T_wc, scale, with_ball, opts)
        return _finish(L, None, cam, T_wc, c, radius, opts, rng, f"{label}/s{seed}", photo)
    if kind in PHOTO_KINDS:
        L, c, radius, photo, label = PHOTO_KINDS[kind](rng, rig, cam, T_wc, scale, with_ball)
        return _finish(L, None, cam, T_wc, c, radius, opts, rng, f"{label}/s{seed}", photo)
    radius = float(rng.uniform(0.1, 0.3))
    floor_z = float(min(T_wc[2, 3], 0.0) - rng.uniform(0.6, 1.3))
    if kind == "big":
        c = _close_centre(rng, cam, T_wc, radius, floor_z)
    else:
        c, _ = sample_target_center(rng, rig, radius, "cam1", rng.random() < 0.3,
                                    lambda c: c[2] - radius > floor_z + 0.1)
    static = room.room_scene(rng, floor_z, [c])
    style = room.ball_style(rng)
    parts = room.ball_parts(rng, style, c, radius, floor_z, T_wc[:3, 3])
    L, _ = render_radiance(Scene(tuple(static + (parts if with_ball else []))), cam, T_wc, room.room_air(rng),
                           aa=opts.aa)
    return _finish(L, None, cam, T_wc, c, radius, opts, rng, f"{kind}/s{seed}/{style['holder']}")


def _close_centre(rng, cam, T_wc, radius, floor_z):
    """A centre whose whole outline is in the image with an apparent radius of 20-50 % of the
    frame height."""
    f = 0.5 * (cam.fx + cam.fy)
    for _ in range(400):
        r_px = rng.uniform(0.2, 0.5) * cam.height_px
        d = radius / np.sin(np.arctan(r_px / f))
        m = 1.3 * r_px
        u = rng.uniform(m, cam.width_px - m) if cam.width_px > 2 * m else cam.width_px / 2
        v = rng.uniform(m, cam.height_px - m) if cam.height_px > 2 * m else cam.height_px / 2
        C = cam.normalize(np.array([[u, v]]))[0]
        ray = np.array([C[0], C[1], 1.0]) / np.linalg.norm([C[0], C[1], 1.0])
        c = transform_points(T_wc, (d * ray)[None])[0]
        sil = silhouette_uv(cam, d * ray, radius)
        if (np.isfinite(sil).all() and cam.in_image(sil, margin_px=2.0).all()
                and c[2] - radius > floor_z + 0.05):
            return c
    raise RuntimeError("could not place a close sphere")


def _chair(rng, rig, cam, T_wc, opts, seed, with_ball=True) -> ImageCase:
    radius = float(rng.uniform(0.15, 0.33))
    floor_z = float(min(T_wc[2, 3], 0.0) - rng.uniform(0.9, 1.4))
    c, _ = sample_target_center(rng, rig, radius, "cam1", rng.random() < 0.2,
                                lambda c: c[2] - radius > floor_z + 0.35, dist_range=(1.2, 4.0))
    static = room.room_scene(rng, floor_z, [c])
    style = room.ball_style(rng)
    if rng.random() < 0.5:  # grey, as a gym ball
        style["albedo"] = tuple(np.full(3, float(rng.uniform(0.35, 0.65))))
    ball = room.ball_parts(rng, dict(style, holder="stick"), c, radius, floor_z, T_wc[:3, 3])[0]
    chair = range_scenes.chair(rng, c, radius, floor_z, T_wc[:3, 3])
    L, _ = render_radiance(Scene(tuple(static + ([ball, chair] if with_ball else []))), cam, T_wc,
                           room.room_air(rng), aa=opts.aa)
    return _finish(L, None, cam, T_wc, c, radius, opts, rng, f"chair/s{seed}")


def _turbid(rng, rig, cam, T_wc, opts, seed, with_ball=True) -> ImageCase:
    radius = float(rng.uniform(0.09, 0.15))
    style = world.sample_target_style(rng, radius)
    base = world.sample_water(rng, False)
    water = Water(float(rng.uniform(0.5, 0.8)), base.water_rgb, base.up_gain, base.side_dir, base.side_gain)
    surface_z, static = world.surface_and_pontoons(rng, rig, "canal")
    c, _ = sample_target_center(rng, rig, radius, "cam1", False,
                                lambda c: c[2] < surface_z - 0.5 - radius, dist_range=(2.2, 3.8))
    hold = world.chain(rng, c + [0, 0, radius - 0.5 * style["wire_m"]], surface_z)
    parts = [world.target(style, c, radius, False)] + ([hold] if hold is not None else [])
    opts = RenderOptions(opts.aa, opts.blur_sigma_px * 1.5, opts.noise_dn, opts.shot_gain)
    L, _ = render_radiance(Scene(tuple(static + (parts if with_ball else []))), cam, T_wc, water, aa=opts.aa)
    Lb, _ = render_radiance(Scene(tuple(static)), cam, T_wc, water, aa=1)
    return _finish(L, Lb, cam, T_wc, c, radius, opts, rng, f"turbid/s{seed}")


def _finish(L, L_bg, cam, T_wc, c, radius, opts, rng, label, photo=None) -> ImageCase:
    img = finish_image(L, opts, rng, photo)
    bg = None if L_bg is None else finish_image(L_bg, opts, rng).astype(np.float32)
    return _with_truth(img, bg, cam, T_wc, c, radius, label)


def _with_truth(img, bg, cam, T_wc, c, radius, label) -> ImageCase:
    """The case of a finished image: the centre's projection through the lens, the outline's size."""
    C = transform_points(invert_T(T_wc), c[None])[0]
    sil = silhouette_uv(cam, C, radius)
    r_px = 0.5 * float(np.max(sil.max(axis=0) - sil.min(axis=0)))
    return ImageCase(img, cam, radius, cam.project(C[None])[0], r_px, bg, label, float(np.linalg.norm(C)))
