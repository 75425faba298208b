"""The layout of one synthetic session, drawn from a preset and a seed before any file is written.

:func:`sample_layout` draws the rig, the sphere, the water and render options, the range
sensor and the static scene's levels (surface, seabed, floor); :func:`place_targets` puts the
sphere of every capture (and picks the moved, drifting and decoy captures);
:func:`add_surroundings` adds the seabed, room or floor around them. Each draws from the
random streams it is given, in a fixed order, so a preset and a seed give one session.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from calib_core.geometry import invert_T, transform_points
from calib_core.synth import room, world
from calib_core.synth.boulders import round_boulders
from calib_core.synth.range import scenes as range_scenes
from calib_core.synth.camera_render import RenderOptions
from calib_core.synth.occlusion import MAX_OCCLUDED_FRACTION, occluded_fraction
from calib_core.synth.range.capture import in_field, sensor_config
from calib_core.synth.rig import sample_in_sensor_view, sample_rig, sample_target_center, sphere_in_image
from calib_core.synth.scene import Scene
from calib_core.synth.sonar_sim import SonarConfig

HOLDER_TRIES = 1000  # aimed at a camera pixel; then drawn in the range sensor's view


@dataclass
class Layout:
    """Everything drawn once per session; ``static`` grows by :func:`add_surroundings`."""

    P: object  # the Preset
    seed: int
    rig: object
    diameter: float  # true diameter (m)
    d_factor: float  # session.yaml states diameter * d_factor
    style: dict  # the target's look (world.sample_target_style)
    water: object
    opts: RenderOptions
    cfg: object  # SonarConfig, or the LiDAR / RGB-D configuration
    surface_z: float
    seabed_z: float | None
    floor_z: float | None
    static: list = field(default_factory=list)
    ball: object = None  # the room's foam ball (room scenes)

    @property
    def cams(self) -> list[str]:
        return list(self.rig.cams)

    @property
    def radius(self) -> float:
        return self.diameter / 2

    @property
    def base_z(self) -> float | None:
        """What a holder stands on: the floor, else the seabed."""
        return self.floor_z if self.floor_z is not None else self.seabed_z

    def ok_extra(self, c) -> bool:
        """The preset's own checks on a sphere centre (world): under the surface, above the
        floor or seabed, in a LiDAR's or RGB-D camera's field."""
        P, radius = self.P, self.radius
        if c[2] > self.surface_z - 0.5 - radius:
            return False
        if self.floor_z is not None and c[2] - radius < self.floor_z + (0.5 if P.holder == "stick" else 0.3):
            return False
        T_sonar_world = invert_T(self.rig.T_world_sonar)
        if P.range_sensor != "sonar" and not in_field(P.range_sensor, transform_points(T_sonar_world, c[None])[0],
                                                      radius, self.cfg):
            return False
        return self.seabed_z is None or c[2] - radius > self.seabed_z + 0.25

    def target_parts(self, c, rng) -> list:
        """The sphere at ``c`` and what holds it (chain, stand, holder, or the room's ball)."""
        P, radius = self.P, self.radius
        if P.scene == "room":
            return room.ball_parts(rng, self.ball, c, radius, self.seabed_z, self.rig.cams[self.cams[0]][1][:3, 3])
        ball_part = (range_scenes.solid_ball(c, radius, P.bright) if P.solid_ball
                     else world.target(self.style, c, radius, P.bright))
        if P.holder:  # resting on a chair, a table or a slab, or on a stick held by a person
            return [ball_part] + range_scenes.holder_parts(rng, P.holder, c, radius, self.base_z,
                                                           self.rig.T_world_sonar[:3, 3])
        hold = (world.stand(rng, c - [0, 0, radius], self.seabed_z) if self.seabed_z is not None
                else world.chain(rng, c + [0, 0, radius - 0.5 * self.style["wire_m"]], self.surface_z))
        return [ball_part] + ([hold] if hold is not None else [])

    def scene(self, c, rng, extra: list) -> Scene:
        """The static scene with the sphere at ``c`` (holder drawn from ``rng``) and ``extra`` parts."""
        return Scene(tuple(self.static + self.target_parts(c, rng) + extra))


@dataclass
class Placement:
    """Where the sphere is in each target capture (world, m), and the special captures (-1: none)."""

    centers: list  # during the scan
    image_centers: list  # when the images were taken (differs for the moved capture)
    moved_idx: int
    drift_idx: int
    decoy_idx: int


def sample_layout(P, seed, r_rig, r_scene, r_sonar) -> Layout:
    """Draw a session's layout for preset ``P`` (rig, sphere, water, sensor, levels)."""
    W, H = max(16, round(1920 * P.scale)), max(9, round(1080 * P.scale))
    rig = sample_rig(r_rig, P.n_cameras, W, H, P.scale, P.lens)
    diameter = 0.22 if P.name == "canal" else float(r_rig.uniform(*P.diameter_range))
    # a wrong stated diameter is too big or too small, by the preset's factor
    d_factor = P.diameter_factor if P.diameter_factor == 1 or r_rig.random() < 0.5 else 2 - P.diameter_factor
    style = world.sample_target_style(r_rig, diameter / 2)
    water, opts = _water_and_render(P, r_scene)
    cfg = _range_config(P, r_sonar)
    surface_z, static, seabed_z, floor_z = _levels(P, r_scene, rig)
    return Layout(P, seed, rig, diameter, d_factor, style, water, opts, cfg, surface_z, seabed_z, floor_z, static)


def _water_and_render(P, r_scene) -> tuple:
    water = world.sample_water(r_scene, P.bright)
    if P.scene == "room":
        water = room.room_air(r_scene)
    elif P.turbidity > 0:  # contrast falls with distance: strong attenuation and veil
        water = replace(water, attenuation_per_m=float(r_scene.uniform(P.turbidity, P.turbidity + 0.3)))
    opts = RenderOptions(aa=4, blur_sigma_px=float(r_scene.uniform(0.5, 1.2)) * max(P.scale, 0.35)
                         * (1.5 if P.turbidity > 0 else 1.0),
                         noise_dn=float(r_scene.uniform(0.8, 3.0)), shot_gain=float(r_scene.uniform(0.05, 0.3)))
    return water, opts


def _range_config(P, r_sonar):
    cfg = SonarConfig(pan_step_deg=P.pan_step_deg, pan_span_deg=P.pan_span_deg, sub_rays=P.sub_rays,
                      range_scale=P.range_scale, range_noise_m=float(r_sonar.uniform(0.002, 0.006)),
                      spurious_rate=float(r_sonar.uniform(0.0005, 0.003)))
    if P.range_sensor != "sonar":  # a LiDAR or an RGB-D camera in the sonar's place
        cfg = sensor_config(P.range_sensor, r_sonar)
    return cfg


def _levels(P, r_scene, rig) -> tuple:
    """(surface_z, static parts, seabed_z or None, floor_z or None) for the preset's scene."""
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
    return surface_z, static, seabed_z, floor_z


def place_targets(L: Layout, r_rig) -> Placement:
    """The sphere's centre in every target capture, then the moved, drifting and decoy captures."""
    P = L.P
    centers = _centers(L, r_rig)
    moved_idx = int(r_rig.integers(P.n_captures)) if P.moved else -1
    image_centers = [c.copy() for c in centers]
    if moved_idx >= 0:
        image_centers[moved_idx] = _moved_center(L, r_rig, centers[moved_idx], image_centers[moved_idx])
    drift_idx = int(r_rig.integers(P.n_captures)) if P.drift_m > 0 else -1
    decoy_idx = -1
    if P.decoy_hidden:
        decoy_idx = (moved_idx + 1 + int(r_rig.integers(P.n_captures - 1))) % P.n_captures
    return Placement(centers, image_centers, moved_idx, drift_idx, decoy_idx)


def _centers(L: Layout, r_rig) -> list:
    P = L.P
    n_corner = int(round(P.corner_fraction * P.n_captures))
    corner_idx = set(r_rig.choice(P.n_captures, n_corner, replace=False).tolist())
    centers = []
    for i in range(P.n_captures):
        ref = L.cams[i % len(L.cams)]
        if P.holder:  # the holder (slab, table, chair, person) must not hide the sphere
            c = _holder_center(L, r_rig, i, ref, i in corner_idx)
        else:
            try:
                c, _ = sample_target_center(r_rig, L.rig, L.radius, ref, i in corner_idx, L.ok_extra)
            except RuntimeError:  # a fisheye's corners can lie wholly outside the sonar's field
                if i not in corner_idx:
                    raise
                c, _ = sample_target_center(r_rig, L.rig, L.radius, ref, False, L.ok_extra)
        centers.append(c)
    return centers


def _holder_center(L: Layout, r_rig, i: int, ref: str, corner: bool):
    seen = _HolderCheck(L.P, L.seed, i, L.rig, L.radius, L.base_z, L.ok_extra)
    zr = _holder_heights(L.P.holder, L.rig, L.radius, L.base_z, L.P.photo)
    try:
        c, _ = sample_target_center(r_rig, L.rig, L.radius, ref, corner, seen, tries=HOLDER_TRIES, z_range=zr)
    except RuntimeError:  # a narrow sensor field: draw in the sensor's view instead
        c = sample_in_sensor_view(r_rig, L.rig, L.radius, seen, zr)
    return c


def _moved_center(L: Layout, r_rig, center, fallback):
    """Where the moved capture's sphere is in its images: 10-20 cm from ``center``, still in
    the first camera's image (``fallback`` when 500 draws find no such place)."""
    for _ in range(500):
        v = r_rig.normal(0, 1, 3) * [1, 1, 0.4]
        cand = center + v / np.linalg.norm(v) * r_rig.uniform(0.10, 0.20)
        cam0, T_wc0 = L.rig.cams[L.cams[0]]
        if L.ok_extra(cand) and sphere_in_image(cam0, invert_T(T_wc0), cand, L.radius, 2.0):
            return cand
    return fallback


def add_surroundings(L: Layout, pl: Placement, r_scene, r_rig) -> None:
    """The seabed, the room or the floor around the placed spheres (into ``L.static``)."""
    P = L.P
    if P.scene == "room":
        L.static += room.room_scene(r_scene, L.seabed_z, pl.centers + pl.image_centers)
        L.ball = room.ball_style(r_rig)
    elif L.seabed_z is not None:
        L.static += world.seabed_scene(r_scene, L.rig, L.seabed_z, pl.centers + pl.image_centers)
        if P.boulders:  # a stream of their own: the other presets' scenes stay as they were
            L.static += round_boulders(np.random.default_rng([int(L.seed), 7919, 4343]), L.rig, L.seabed_z,
                                       P.boulders, L.radius, pl.centers + pl.image_centers)
    if L.floor_z is not None:
        L.static += range_scenes.room(r_scene, L.floor_z)


def _holder_heights(holder: str, rig, radius: float, base_z: float, photo: str = "") -> tuple:
    """World heights (m) for the centre of a sphere on a holder: clear of the floor or seabed
    and, on a table or slab, with the sphere's bottom below every camera (a camera under
    the top of what the sphere rests on sees the top hide it; a chair's seat is narrower
    than the ball, so the occlusion test alone decides there)."""
    lo = base_z + (0.5 if holder == "stick" else 0.3) + radius
    if holder == "chair" and photo:  # the photographic presets: a seat 0.4-1.1 m high (not a stool of any height)
        return base_z + 0.40 + radius, base_z + 1.10 + radius
    if holder == "hand":  # held out at arm's length by a person standing on the floor
        return base_z + 0.6, base_z + 1.5
    if holder in ("stick", "chair"):
        return lo, np.inf
    return lo, min(T[2, 3] for _, T in rig.cams.values()) - 0.05 + radius


class _HolderCheck:
    """Placement test for presets whose sphere rests on (or is held by) something: the
    preset's own checks, then the sphere, with the very holder capture ``k`` will get (same
    random stream), hidden by at most MAX_OCCLUDED_FRACTION from every camera (a carrying
    hand may hide more: range_scenes.MAX_OCCLUDED)."""

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
