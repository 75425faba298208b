"""The "underwater" session preset: a float on a stand over a seabed with round boulders of about
its size, photographed in the underwater image kind's water (calib_core.synth.photo.water_session,
calib_core.synth.boulders). Small resolutions and few captures throughout."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from calib_core.io.images import load_image
from calib_core.session import load_session, validate_session
from calib_core.synth.generate import generate_session
from calib_core.synth.ground_truth import load_ground_truth
from calib_core.synth.layout import add_surroundings, place_targets, sample_layout
from calib_core.synth.photo import session as ps
from calib_core.synth.presets import PRESETS, for_seed
from calib_core.synth.scene import Sphere

SMALL = dict(scale=0.15, n_captures=2, pan_step_deg=3.0)


def _digest(root) -> str:
    h = hashlib.sha256()
    for p in sorted(q for q in root.rglob("*") if q.is_file()):
        h.update(p.relative_to(root).as_posix().encode() + b"\0" + p.read_bytes())
    return h.hexdigest()


def _layout(seed: int, **kw):
    P = for_seed(PRESETS["underwater"].with_(**kw), seed)
    ss = np.random.SeedSequence([seed, 7919])
    r_rig, r_scene, _, r_sonar = (np.random.default_rng(s) for s in ss.spawn(4))
    L = sample_layout(P, seed, r_rig, r_scene, r_sonar)
    pl = place_targets(L, r_rig)
    add_surroundings(L, pl, r_scene, r_rig)
    return L, pl


def test_preset_fields():
    P = PRESETS["underwater"]
    assert P.photo == "underwater" and P.scene == "seabed" and P.boulders > 0 and P.n_cameras == 2
    assert P.n_backgrounds == 0 and P.range_sensor == "sonar"
    names = list(PRESETS)  # added after every older preset (their seeds' sessions unchanged)
    assert names.index("underwater") > names.index("carried-3cam")


def test_session_is_deterministic_and_valid(tmp_path):
    a = generate_session(tmp_path / "a", "underwater", 5, **SMALL)
    b = generate_session(tmp_path / "b", "underwater", 5, **SMALL)
    assert _digest(a) == _digest(b)
    assert validate_session(a).problems == []
    gt = load_ground_truth(a)
    assert gt["preset"] == "underwater"
    sess = load_session(a)
    assert len(sess.cameras) == 2 and all(spec.background_path is None for spec in sess.cameras.values())
    assert all(not im["occluded_fraction"] for c in gt["captures"].values() for im in c["images"].values())
    # water: red is absorbed first (the image is blue or green), the veil lifts the shadows
    img = load_image(a / sess.captures[0].image_paths["cam1"]).astype(float)
    mean = img.reshape(-1, 3).mean(axis=0)
    assert mean[0] < 0.8 * max(mean[1], mean[2])


@pytest.mark.parametrize("seed", [41, 42])
def test_round_boulders_lie_on_the_seabed_clear_of_the_target(seed):
    L, pl = _layout(seed, n_captures=4)
    boulders = [p for p in L.static if isinstance(p, Sphere) and p.tag == "clutter"
                and abs(p.center_m[2] - L.seabed_z) <= 0.45 * p.radius_m and 0.55 * L.radius <= p.radius_m <= 1.65 * L.radius]
    assert len(boulders) >= 3  # about the target's size, half-buried
    for b in boulders:
        gap = min(np.hypot(*(np.asarray(b.center_m) - c)[:2]) for c in pl.centers)
        assert gap >= 0.3 + b.radius_m + L.radius


def test_other_presets_have_no_boulders():
    assert all(p.boulders == 0 for n, p in PRESETS.items() if n != "underwater")


def test_underwater_look_varies_by_seed_and_uses_the_water_model():
    looks = [ps.session_look("underwater", s, 0.12) for s in range(12)]
    assert all(lk.air.attenuation_rgb is not None and lk.air.attenuation_rgb[0] > lk.air.attenuation_rgb[1] for lk in looks)
    assert all(np.log(4.0) / lk.air.attenuation_rgb[1] >= 4.0 - 1e-9 for lk in looks)  # the ball stays visible
    assert len({lk.ball_material.albedo for lk in looks}) > 3
    assert any(lk.dive.caustic > 0 for lk in looks) and any(lk.dive.caustic == 0 for lk in looks)
    assert any(lk.dive.spot_gain > 0 for lk in looks) and any(lk.dive.snow > 0 for lk in looks)
    light = ps.capture_light(looks[0], 0, 0, (3.0, 0.0, -0.5), 0.12, np.zeros(3), 0.5)
    assert light.motion_px is None and light.photo.key_dir[2] == 1.0  # the sun from above
