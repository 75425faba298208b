"""Sonar detection on the project's simulator (calib_core.synth): BV5000-like panned fan,
first return among sub-rays of each 1 deg cone, range noise and quantisation, spurious
returns, chain or stand, seabed, walls, docks and clutter. Small sessions (coarse pan,
tiny images) keep this file fast; the benchmark runs the full presets."""

from __future__ import annotations

import numpy as np
import pytest

from calib_core.detect.sonar.detect import detect_sphere_in_cloud
from calib_core.io.clouds import load_cloud
from calib_core.session import load_session

synth = pytest.importorskip("calib_core.synth.generate")
from calib_core.synth.ground_truth import load_ground_truth  # noqa: E402

FAST = dict(scale=0.05, pan_step_deg=1.0, n_backgrounds=0)


def _captures(root):
    s = load_session(root)
    gt = load_ground_truth(root)
    out = []
    for cap in s.captures:
        g = gt["captures"][cap.id]
        if not g.get("target", True):
            continue
        c = np.asarray(g["center_sonar_m"], float) * gt["range_scale"]
        out.append((cap.id, load_cloud(cap.cloud_path).points_m, c))
    return s, gt, out


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    base = tmp_path_factory.mktemp("sonar_synth")
    made = {}
    for preset, seed, n, step in [("canal", 11, 3, 1.0), ("seabed", 12, 3, 1.0),
                                  ("wrongdiam", 14, 2, 0.75)]:
        made[preset] = synth.generate_session(base / preset, preset, seed, n_captures=n,
                                              **dict(FAST, pan_step_deg=step))
    return made


@pytest.mark.parametrize("preset", ["canal", "seabed"])
def test_cone_model_finds_every_sphere_and_beats_the_naive_fit(sessions, preset):
    s, gt, caps = _captures(sessions[preset])
    cone_err, naive_err = [], []
    for cid, P, c in caps:
        det = detect_sphere_in_cloud(P, s.sphere_radius_m, s.beam_width_deg or 1.0)
        assert det.found, (preset, cid, det.reason)
        naive = detect_sphere_in_cloud(P, s.sphere_radius_m, s.beam_width_deg or 1.0,
                                       method="known-radius")
        assert naive.found
        cone_err.append(np.linalg.norm(det.center_sonar_m - c))
        naive_err.append(np.linalg.norm(naive.center_sonar_m - c))
        # the sonar's diameter agrees with the truth within a few percent
        assert abs(det.diameter_m - gt["sphere_diameter_m"]) < 0.06 * gt["sphere_diameter_m"]
        assert det.apparent_diameter_m > gt["sphere_diameter_m"]  # blooming
        # the stated uncertainty is not absurd: error within a few sigma plus model error
        sd = np.sqrt(np.trace(det.cov_sonar_m2))
        assert 1e-4 < sd < 0.01
    cone_err, naive_err = np.array(cone_err), np.array(naive_err)
    assert cone_err.max() < 0.010, cone_err
    assert cone_err.mean() < 0.5 * naive_err.mean(), (cone_err, naive_err)


def test_wrong_diameter_in_session_is_refused_with_the_seen_diameter(sessions):
    s, gt, caps = _captures(sessions["wrongdiam"])
    assert abs(s.sphere_diameter_m - gt["sphere_diameter_m"]) > 0.2 * gt["sphere_diameter_m"]
    seen = []
    for cid, P, c in caps:
        det = detect_sphere_in_cloud(P, s.sphere_radius_m, s.beam_width_deg or 1.0)
        assert not det.found and det.reason, cid  # never a centre fitted with the wrong size
        if "another size" in det.reason:
            seen.append(det.extras["candidate_diameter_m"])
            assert np.linalg.norm(np.asarray(det.extras["candidate_center"]) - c) < 0.03
    assert seen, "the diameter the sonar sees is reported"
    assert np.all(np.abs(np.array(seen) - gt["sphere_diameter_m"]) < 0.08 * gt["sphere_diameter_m"])
