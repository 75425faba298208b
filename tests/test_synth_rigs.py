"""Synthetic rigs beyond the paper's: a fisheye camera (equidistant intrinsics) and three
cameras tied to cam1 by stereo transforms. Small sizes (a few seconds each)."""

from __future__ import annotations

import numpy as np
import pytest

from calib_core.geometry import invert_T
from calib_core.io.intrinsics import load_intrinsics
from calib_core.session import load_session
from calib_core.synth.generate import generate_session
from calib_core.synth.ground_truth import load_ground_truth

FAST = dict(scale=0.15, n_captures=3, pan_step_deg=2.0, sub_rays=7)


def test_fisheye_preset_writes_equidistant_intrinsics_and_spheres_in_view(tmp_path):
    root = generate_session(tmp_path / "fe", "fisheye", 5, **FAST)
    s = load_session(root)
    cam = s.camera_model("cam1")
    assert cam.fisheye and cam.dist.size == 4
    assert (root / "intrinsics" / "cam1.yaml").read_text().count("equidistant") == 1
    gt = load_ground_truth(root)
    T = np.asarray(gt["cameras"]["cam1"]["T_cam_sonar"])
    n = 0
    for c in gt["captures"].values():
        img = c["images"]["cam1"]
        if img["center_uv_px"] is None:
            continue
        X = np.asarray(c["center_sonar_at_image_m"])  # its pixel is the fisheye projection
        uv = cam.project((T[:3, :3] @ X + T[:3, 3])[None])[0]
        assert np.allclose(uv, img["center_uv_px"], atol=1e-6)
        n += img["visible"]
    assert n >= 2


def test_three_cameras_each_tied_to_cam1(tmp_path):
    root = generate_session(tmp_path / "c3", "carried-3cam", 4, **FAST)
    s = load_session(root)
    assert list(s.cameras) == ["cam1", "cam2", "cam3"]
    assert set(s.stereo) == {"T_cam2_cam1", "T_cam3_cam1"}
    gt = load_ground_truth(root)
    T = {c: np.asarray(gt["cameras"][c]["T_cam_sonar"]) for c in s.cameras}
    for c in ("cam2", "cam3"):
        exact = T[c] @ invert_T(T["cam1"])
        assert np.allclose(np.asarray(gt["stereo"][f"T_{c}_cam1"]), exact, atol=1e-9)
        given = s.stereo[f"T_{c}_cam1"]  # checkerboard-like: close to the truth, not equal
        assert 0 < np.linalg.norm(given[:3, 3] - exact[:3, 3]) < 0.02
    # the third camera sits above the stereo pair
    up = [invert_T(T[c])[:3, 3] for c in ("cam1", "cam2", "cam3")]
    assert np.linalg.norm(up[2] - 0.5 * (up[0] + up[1])) > 0.2
    assert load_intrinsics(root / "intrinsics" / "cam3.yaml").width_px == round(1920 * FAST["scale"])
