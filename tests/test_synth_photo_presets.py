"""The photographic session presets "gym" and "carried-photo" (calib_core.synth.photo.session):
generation is deterministic, the effects are present where the model puts them, and the plain
presets do not use them. Small resolutions throughout."""

from __future__ import annotations

import hashlib
from dataclasses import replace

import numpy as np
import pytest

from calib_core.camera import CameraModel
from calib_core.session import load_session, validate_session
from calib_core.synth.photo import session as ps
from calib_core.synth.camera_render import render_radiance
from calib_core.synth.generate import generate_session
from calib_core.synth.ground_truth import load_ground_truth
from calib_core.synth.presets import PRESETS, for_seed
from calib_core.synth.range.scenes import room, solid_ball
from calib_core.synth.scene import Scene

SMALL = dict(scale=0.15, n_captures=2, pan_step_deg=3.0)
W, H = 200, 150


def _digest(root) -> str:
    h = hashlib.sha256()
    for p in sorted(q for q in root.rglob("*") if q.is_file()):
        h.update(p.relative_to(root).as_posix().encode() + b"\0" + p.read_bytes())
    return h.hexdigest()


@pytest.mark.parametrize("name", ["gym", "carried-photo"])
def test_photo_presets_are_deterministic_valid_sessions(tmp_path, name):
    a = generate_session(tmp_path / "a", name, 5, **SMALL)
    b = generate_session(tmp_path / "b", name, 5, **SMALL)
    assert _digest(a) == _digest(b)
    assert validate_session(a).problems == []
    c = generate_session(tmp_path / "c", name, 6, **SMALL)
    assert _digest(c) != _digest(a)
    gt = load_ground_truth(a)
    assert gt["preset"] == name
    assert all("motion_px" in c for c in gt["captures"].values())  # None when still
    if name == "gym":
        assert all(c["motion_px"] is None for c in gt["captures"].values())
    sess = load_session(a)
    assert all(spec.background_path is None for spec in sess.cameras.values())
    assert len(sess.cameras) == (2 if name == "gym" else 1)


def test_presets_fields():
    gym, carried = PRESETS["gym"], PRESETS["carried-photo"]
    assert gym.photo == "gym" and gym.holder == "chair" and gym.n_cameras == 2 and gym.range_sensor == "lidar16"
    assert carried.photo == "carried" and carried.holder == "hand" and carried.n_backgrounds == 0
    assert {for_seed(carried, s).range_sensor for s in (4, 5)} == {"rgbd", "lidar16"}
    assert all(p.photo == "" for n, p in PRESETS.items() if n not in ("gym", "carried-photo", "carried-3cam", "underwater"))
    assert PRESETS["carried-3cam"].photo == "carried" and PRESETS["carried-3cam"].n_cameras == 3
    names = list(PRESETS)  # added after every older preset (their seeds' sessions unchanged)
    assert names[names.index("gym"):names.index("gym") + 2] == ["gym", "carried-photo"]
    assert names.index("gym") > names.index("carried")


def _ball_scene():
    """A 0.3 m ball resting on a floor 3 m ahead, a wall behind; the camera looks along +x."""
    c = np.array([3.0, 0.0, 0.0])
    static = room(np.random.default_rng(0), -0.3)
    cam = CameraModel(W, H, np.array([[180.0, 0, 99.5], [0, 180.0, 74.5], [0, 0, 1]]), np.zeros(5))
    T_wc = np.eye(4)
    T_wc[:3, :3] = np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], float)
    T_wc[:3, 3] = [0.0, 0.0, 0.4]
    return Scene(tuple(static) + (solid_ball(c, 0.3, False),)), c, cam, T_wc


def test_dress_replaces_ball_floor_and_wall_materials_only():
    scene, c, _, _ = _ball_scene()
    look = ps.session_look("gym", 3, 0.3)
    dressed = ps.dress(scene, look)
    by_tag = {p.tag: p.material for p in dressed.primitives}
    assert by_tag["target"] == look.ball_material and by_tag["floor"].texture == "tiles"
    assert by_tag["wall"].texture == "brick"
    assert [type(p) for p in dressed.primitives] == [type(p) for p in scene.primitives]


def test_gym_looks_vary_by_seed_and_are_glossy():
    looks = [ps.session_look("gym", s, 0.3) for s in range(40)]
    shades = np.array([np.mean(lk.ball_material.albedo) for lk in looks])
    assert shades.min() < 0.2 and shades.max() > 0.6  # dark to white balls
    assert all(lk.ball.ks >= 0.3 for lk in looks)
    assert sum(lk.ball.seam_dir is not None or lk.ball.logo_dir is not None for lk in looks) > 20
    foam = [ps.session_look("carried", s, 0.2) for s in range(20)]
    assert all(lk.ball.ks <= 0.15 and lk.ball_material.texture == "foam" for lk in foam)
    assert sum(lk.ball.seam_dir is not None or lk.ball.logo_dir is not None for lk in foam) >= 15


def test_motion_blur_only_on_some_carried_captures():
    gym = ps.session_look("gym", 1, 0.3)
    carried = ps.session_look("carried", 1, 0.2)
    eye = np.zeros(3)
    assert all(ps.capture_light(gym, 1, k, (3, 0, 0), 0.3, eye, 1.0).motion_px is None for k in range(30))
    lengths = [ps.capture_light(carried, 1, k, (3, 0, 0), 0.2, eye, 0.5).motion_px for k in range(60)]
    blurred = [np.hypot(*m) for m in lengths if m is not None]
    assert 10 <= len(blurred) <= 40
    assert min(blurred) >= 0.5 * ps.MOTION_PX_1080P[0] - 1e-9 and max(blurred) <= 0.5 * ps.MOTION_PX_1080P[1]


def test_shadow_highlight_vignette_and_exposure_are_present():
    scene, c, cam, T_wc = _ball_scene()
    look = ps.session_look("gym", 2, 0.3)
    dressed = ps.dress(scene, look)
    light = ps.capture_light(look, 2, 0, c, 0.3, T_wc[:3, 3], 0.1)
    L, photo = ps.render_capture(dressed, cam, T_wc, look.air, 2, light, np.random.default_rng(0), 0.1)
    assert photo.vignette > 0 and photo.exposure != 1.0 and photo.bloom_px > 0
    # without the ball's shadow and gloss: the floor right under the ball is brighter, the ball duller
    plain = replace(photo, occluders=(), ball=replace(photo.ball, ks=0.0))
    L0, hit = render_radiance(dressed, cam, T_wc, look.air, aa=2, photo=plain)
    ball_id = dressed.ids_with_tag("target")[0]
    floor_id = dressed.ids_with_tag("floor")[0]
    v_ball = np.nonzero((hit == ball_id).any(axis=1))[0].max()
    under = (hit == floor_id) & (np.arange(H)[:, None] <= v_ball + 6) & (np.abs(np.arange(W) - 99.5)[None, :] < 12)
    assert under.any()
    assert L[under].mean() < 0.7 * L0[under].mean()
    on_ball = hit == ball_id
    assert (L[on_ball].max(axis=1) - L0[on_ball].max(axis=1)).max() > 0.2  # the highlight


def test_motion_blur_streaks_the_ball_along_its_motion():
    scene, c, cam, T_wc = _ball_scene()
    look = ps.session_look("carried", 2, 0.3)
    dressed = ps.dress(scene, look)
    still = ps.capture_light(look, 2, 0, c, 0.3, T_wc[:3, 3], 1.0)
    moving = replace(still, motion_px=(16.0, 0.0))
    Ls, _ = ps.render_capture(dressed, cam, T_wc, look.air, 1, still, np.random.default_rng(0), 1.0)
    Lm, _ = ps.render_capture(dressed, cam, T_wc, look.air, 1, moving, np.random.default_rng(0), 1.0)
    _, hit = render_radiance(dressed, cam, T_wc, look.air, aa=1)
    row = int(np.median(np.nonzero(hit == dressed.ids_with_tag("target")[0])[0]))
    cols = np.nonzero(hit[row] == dressed.ids_with_tag("target")[0])[0]
    right = cols.max() + 5  # beyond the still ball's right edge: the streak reaches it
    assert not np.allclose(Lm[row, right], Ls[row, right], atol=1e-3)
    assert np.allclose(Lm[row, cols.min() + 10: cols.max() - 10], Ls[row, cols.min() + 10: cols.max() - 10], atol=0.2)

