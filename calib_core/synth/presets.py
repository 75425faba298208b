"""Synthetic session presets: what kind of scene, rig and sensor set-up each one makes.

A :class:`Preset` is declarative; :func:`calib_core.synth.generate.generate_session` turns
it plus a seed into a session. Everything random (intrinsics, rig, sphere positions,
turbidity, noise) comes from the seed; the preset fixes the kind of scene.
"""

from __future__ import annotations

from dataclasses import dataclass, replace


@dataclass(frozen=True)
class Preset:
    """Scene kind and sensor settings of a synthetic session.

    n_cameras: 1, 2 (the paper's stereo rig, cameras cam1 and cam2) or 3 (a third, cam3, above them).
    n_captures: target captures (the sphere held still during a scan).
    n_flange: extra non-target captures (steel pipe with a square flange, sphere absent).
    pan_step_deg, sub_rays: sonar pan step and sub-rays per 1 deg beam cone.
    range_scale: reported range = true range * range_scale (sound-speed error).
    moved: one capture's target moves 10-20 cm between the scan and the images.
    scene: "canal" (open water, chain, pontoons), "seabed" (seabed, wall/dock, stand, clutter),
        "lab" (a room: floor and wall, in air),
        "room" (dry, textured: brick wall, tiled floor, furniture blocks; a matte foam ball of
        any colour on a stick or resting on a block; :mod:`calib_core.synth.room`).
    turbidity: > 0 = turbid water, attenuation drawn from [turbidity, turbidity + 0.3] 1/m,
        optical blur x1.5 (contrast falls with distance).
    bright: bright sphere on dark water (instead of a dark mesh on bright backlit water).
    n_backgrounds: sphere-free frames per camera (0 = no background in session.yaml).
    background_video: write the background as an MJPG .avi whose first second still shows the
        target (session.yaml then gives ``background_window`` to skip it).
    decoys: other round things (spheres and discs of other sizes) in image and cloud.
    diameter_factor: session.yaml states the diameter times this or times (2 - this), by seed
        (wrong-diameter test: ~30 % too big or too small).
    cloud_format: suffix of the cloud files (".ply", ".pcd", ".npy", ".xyz").
    scale: image resolution factor (1.0 = 1920x1080); K scales with it.
    drift_m: one capture's sphere drifts this far (m) during its scan; the session then holds
        ``frames/<cam>/<id>_<j>.jpg`` recorded during that scan (a bag written from it shows the drift).
    corner_fraction: share of captures aimed near an image corner.
    photo: "" (plain renders) or a photographic look, "gym", "carried" or "underwater" (see the field's comment).
    decoy_hidden: one capture (not the moved one) shows cam1 a decoy that looks exactly like the
        target beside it while a panel hides half of the true target (image only): a wrong image
        detection (calib_core.synth.world.decoy_and_occluder).
    """

    name: str
    description: str
    n_cameras: int = 1
    n_captures: int = 9
    n_flange: int = 0
    pan_step_deg: float = 0.5
    pan_span_deg: float = 90.0
    sub_rays: int = 19
    range_scale: float = 1.0
    moved: bool = False
    scene: str = "canal"
    bright: bool = False
    n_backgrounds: int = 3
    background_video: bool = False
    decoys: bool = False
    diameter_factor: float = 1.0
    cloud_format: str = ".ply"
    scale: float = 1.0
    corner_fraction: float = 0.3
    jpeg_quality: int = 90
    # range side (issue 11): the range sensor ("sonar", or "lidar16" / "rgbd" from
    # calib_core.synth.range.sim, no beam footprint), what holds the ball ("" = the scene's
    # chain or stand; "chair", "table", "stick" with a person, or "hand": a person carrying it,
    # calib_core.synth.range.scenes),
    # a solid ball instead of the open mesh, and the range of true diameters (m)
    range_sensor: str = "sonar"  # or alternatives by seed, "rgbd|lidar16" (see for_seed)
    holder: str = ""
    solid_ball: bool = False
    diameter_range: tuple = (0.18, 0.30)
    drift_m: float = 0.0
    turbidity: float = 0.0
    decoy_hidden: bool = False
    # photographic look (calib_core.synth.photo.session): "" = the plain renderer; "gym" (glossy gym
    # ball of a shade drawn by seed, key light, cast and contact shadows, vignetting, exposure,
    # textured room) or "carried" (foam ball with a seam / logo, some captures motion-blurred) or
    # "underwater" (a float in the held-out underwater kind's water: calib_core.synth.photo.session)
    photo: str = ""
    # the cameras' lens model: "" = pinhole + plumb_bob, "fisheye" = OpenCV's equidistant model
    # (a wide dome-port camera, 110-160 deg across; intrinsics written as ROS "equidistant")
    lens: str = ""
    # round boulders (half-buried spheres of about the target's size) on the seabed around the work
    # area, seen by every sensor (calib_core.synth.boulders); 0 = none
    boulders: int = 0

    def with_(self, **changes) -> "Preset":
        """A copy with some fields changed (e.g. ``scale=0.25`` for fast tests)."""
        return replace(self, **changes)


_LIST = [
    Preset("canal", "the paper's rig: two cameras 0.74 m apart, sonar ~0.86 m from each, 9 captures in a "
           "~3 m work area, chain and pontoons, measured baselines and a checkerboard stereo transform",
           n_cameras=2, n_captures=9, pan_step_deg=0.5),
    Preset("quick", "one camera, 6 captures, coarse pan steps: fast", n_captures=6, pan_step_deg=1.0,
           sub_rays=19, cloud_format=".pcd", n_backgrounds=2),
    Preset("moved", "one capture's target moved 10-20 cm between the scan and the image", n_captures=8,
           pan_step_deg=0.75, moved=True),
    Preset("soundspeed", "sound-speed error: cloud ranges scaled by 1.02; two cameras with a stereo "
           "transform, which is what makes the scale observable", n_cameras=2, n_captures=8, pan_step_deg=0.75,
           range_scale=1.02),
    Preset("flange", "target captures plus non-target captures of a steel pipe with a square flange "
           "(paper Fig. 5)", n_captures=7, n_flange=2, pan_step_deg=0.5),
    Preset("seabed", "seabed, a wall or dock, the sphere on a stand instead of a chain, clutter",
           n_captures=8, pan_step_deg=0.75, scene="seabed", cloud_format=".npy", background_video=True),
    Preset("bright", "bright sphere on dark water", n_captures=8, pan_step_deg=0.75, bright=True),
    Preset("nobg", "no background frames", n_captures=8, pan_step_deg=0.75, n_backgrounds=0),
    Preset("decoys", "other round things (spheres, discs of other sizes) in image and cloud", n_captures=8,
           pan_step_deg=0.75, decoys=True, cloud_format=".xyz"),
    Preset("wrongdiam", "session.yaml states a sphere diameter ~30 % off the true one", n_captures=8,
           pan_step_deg=0.75, diameter_factor=1.3),
    # range side (issue 11): sensors with no beam footprint, balls resting on or held by things
    Preset("lidar-chair", "16-ring spinning LiDAR (no footprint, 2 deg between rings, 1-2 cm noise); a grey "
           "0.5-0.7 m gym ball resting on a chair in a room", n_captures=8, scene="lab", range_sensor="lidar16",
           holder="chair", solid_ball=True, diameter_range=(0.5, 0.7), n_backgrounds=0),
    Preset("rgbd-stick", "RGB-D depth camera (depth noise growing with range, holes, flying pixels); a yellow "
           "ball on a black stick held by a person close behind it", n_captures=8, scene="lab", range_sensor="rgbd",
           holder="stick", solid_ball=True, diameter_range=(0.3, 0.5), bright=True, n_backgrounds=0),
    Preset("rgbd-table", "RGB-D depth camera; the ball resting on a table wider than itself", n_captures=8,
           scene="lab", range_sensor="rgbd", holder="table", solid_ball=True, diameter_range=(0.3, 0.5)),
    Preset("seabed-slab", "sonar; the mesh sphere resting on a flat slab on the seabed (the slab reaches well "
           "past the sphere on every side)", n_captures=8, pan_step_deg=0.75, scene="seabed", holder="table",
           cloud_format=".npy"),
    Preset("drift", "one capture's sphere drifts 8 cm during its scan (frames recorded during the scan; "
           "for bag round trips and the target-motion check)", n_captures=6, pan_step_deg=1.0, drift_m=0.08),
]

_LIST += [
    Preset("clutter", "dry textured room (brick wall, tiled floor, furniture), a matte foam ball of any "
           "colour on a stick that hides part of its outline or resting on a block; no background frames",
           n_captures=8, pan_step_deg=0.75, scene="room", n_backgrounds=0, cloud_format=".npy"),
    Preset("turbid", "turbid water: strong attenuation and veil, blur; contrast falls with distance",
           n_captures=9, pan_step_deg=0.75, turbidity=0.5),
]

_LIST.append(Preset(
    "review", "the workbench's review loop: one capture whose image shows a look-alike decoy beside the "
    "half-hidden target (a wrong image detection) and one whose target moved between scan and image",
    n_captures=8, pan_step_deg=0.75, moved=True, decoy_hidden=True))

_LIST.append(Preset(
    "carried", "a yellow foam ball held out at arm's length by a person standing behind it (one hand under it or "
    "two on its sides, hiding part of its outline), in front of a wall; RGB-D (even seeds) or 16-ring LiDAR (odd "
    "seeds); no background frames", n_captures=8, scene="lab", range_sensor="rgbd|lidar16", holder="hand",
    solid_ball=True, diameter_range=(0.3, 0.5), bright=True, n_backgrounds=0))

# photographic sessions (issue 11, real sets A and B): the effects of calib_core.synth.photo.effects
_LIST += [
    Preset("gym", "real set A: a glossy gym ball (0.5-0.7 m, grey most often, also dark, white or coloured; a "
           "seam, logo or valve) resting on a chair, brick wall, tiled floor, a key light with cast and contact "
           "shadows, highlight and bloom, vignetting, metered exposure; 2 cameras, 16-ring LiDAR, no background "
           "frames", n_cameras=2, n_captures=8, scene="lab", range_sensor="lidar16", holder="chair",
           solid_ball=True, diameter_range=(0.5, 0.7), n_backgrounds=0, photo="gym"),
    Preset("carried-photo", "real set B: a yellow foam ball with a seam and/or logo carried by a person in front "
           "of a brick wall, shadows, vignetting, exposure, motion blur on some captures (2-24 px at 1080p); RGB-D "
           "(even seeds) or 16-ring LiDAR (odd seeds); no background frames", n_captures=8, scene="lab",
           range_sensor="rgbd|lidar16", holder="hand", solid_ball=True, diameter_range=(0.3, 0.5), bright=True,
           n_backgrounds=0, photo="carried"),
]

# a wide-angle camera (issue 11: other rigs)
_LIST.append(Preset(
    "fisheye", "one wide dome-port camera in OpenCV's fisheye (equidistant) model, 110-160 deg across, beside "
    "the sonar in the canal; half the captures aimed near the image's edges, where the sphere is squashed",
    n_captures=9, pan_step_deg=0.75, lens="fisheye", corner_fraction=0.5))

# three cameras (issue 11: real set B's rig), tied to cam1 by checkerboard-like stereo transforms
_LIST.append(Preset(
    "carried-3cam", "real set B's rig: carried-photo's yellow foam ball carried by a person, seen by three cameras "
    "(the stereo pair and a third above them, each tied to cam1 by a stereo transform); RGB-D (even seeds) or "
    "16-ring LiDAR (odd seeds); no background frames", n_cameras=3, n_captures=8, scene="lab",
    range_sensor="rgbd|lidar16", holder="hand", solid_ball=True, diameter_range=(0.3, 0.5), bright=True,
    n_backgrounds=0, photo="carried"))

# the product's own domain, photographed (issue 11): the underwater image kind's water in a session
_LIST.append(Preset(
    "underwater", "a float (orange, white, yellow or dark) on a stand over a sand or gravel seabed with round "
    "boulders of about its size around it; the photographs in the underwater image kind's water (per-channel "
    "attenuation and backscatter, sunlight from above with caustics, a dive light, marine snow); two cameras with "
    "a stereo transform, sonar; no background frames", n_cameras=2, n_captures=8, pan_step_deg=0.75,
    scene="seabed", solid_ball=True, n_backgrounds=0, photo="underwater", boulders=6, cloud_format=".npy"))

PRESETS: dict[str, Preset] = {p.name: p for p in _LIST}


# a 16-ring LiDAR's rings are 2 deg apart: its balls are gym balls at least this big (m)
MIN_DIAMETER_M = {"lidar16": 0.45}


def for_seed(preset: Preset, seed: int) -> Preset:
    """The preset as a seed makes it: a ``range_sensor`` of alternatives ("rgbd|lidar16") is
    the first for even seeds, the second for odd ones (the ball then at least as big as that
    sensor needs, MIN_DIAMETER_M). Other presets are returned unchanged."""
    if "|" not in preset.range_sensor:
        return preset
    options = preset.range_sensor.split("|")
    sensor = options[int(seed) % len(options)]
    lo, hi = preset.diameter_range
    lo2 = max(lo, MIN_DIAMETER_M.get(sensor, 0.0))
    return preset.with_(range_sensor=sensor, diameter_range=(lo2, max(hi, lo2 + 0.2)))


def get_preset(name_or_preset) -> Preset:
    """Look a preset up by name (KeyError listing the names if unknown), or pass one through."""
    if isinstance(name_or_preset, Preset):
        return name_or_preset
    try:
        return PRESETS[str(name_or_preset)]
    except KeyError:
        raise KeyError(f"unknown preset '{name_or_preset}' (presets: {', '.join(PRESETS)})") from None
