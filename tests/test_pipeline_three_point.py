"""A registration on exactly three plain detections: its looks are its checks (calib_core.pipeline
``_looks_on_three``, calib_core.disambiguate.three).

The look at a predicted place is replaced by a stand-in that finds the sphere only where it truly
is (within the look's window), so what is tested is the bookkeeping: looks kept only when enough
of them confirm the registration, and nothing kept from a registration on a wrong detection.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from calib_core import pipeline
from calib_core.camera import CameraModel
from calib_core.detect.types import ImageDetection

CAM = CameraModel(640, 480, np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]]))
R_M = 0.1
T_CAM_SONAR = np.eye(4)
T_CAM_SONAR[:3, :3] = Rotation.from_euler("xyz", [2.0, -3.0, 1.0], degrees=True).as_matrix()
T_CAM_SONAR[:3, 3] = [0.12, -0.05, 0.2]
CENTERS_CAM_M = np.array([[-0.6, -0.3, 2.0], [0.5, 0.2, 2.6], [0.0, 0.4, 3.2], [-0.3, 0.1, 1.6],
                          [0.6, -0.4, 3.0], [0.2, -0.1, 2.2], [-0.7, 0.3, 2.9], [0.3, 0.5, 1.9]])
IDS = [f"p{k:02d}" for k in range(len(CENTERS_CAM_M))]
PLAIN = IDS[:3]


def _truth():
    uv = CAM.project(CENTERS_CAM_M)
    rng = np.linalg.norm(CENTERS_CAM_M, axis=1)
    return {c: (uv[k], rng[k]) for k, c in enumerate(IDS)}


def _data():
    cap = SimpleNamespace(image_paths={"cam1": "unused.png"})
    session = SimpleNamespace(sphere_radius_m=R_M, capture=lambda cid: cap, cameras=["cam1"], stereo={})
    return SimpleNamespace(camera=lambda name: CAM, session=session, background=lambda name: None)


def _detections(plain_offset_px=(0.0, 0.0)):
    R, t = T_CAM_SONAR[:3, :3], T_CAM_SONAR[:3, 3]
    out = {}
    for k, c in enumerate(IDS):
        uv, rng = _truth()[c]
        son = {"status": "auto", "center": (R.T @ (CENTERS_CAM_M[k] - t)).tolist()}
        if c in PLAIN:
            shift = np.asarray(plain_offset_px) if c == PLAIN[0] else 0.0
            img = {"status": "auto", "center": (uv + shift).tolist(), "range_m": float(rng), "score": 0.99}
        else:
            img = {"status": "auto", "reason": "no round outline"}
        out[c] = {"sonar": son, "cam1": img}
    return out


@pytest.fixture
def looks(monkeypatch):
    """A look that finds the sphere where it truly is, when that lies within its window; the
    captures it may find are in ``findable`` (all by default)."""
    import calib_core.detect.image.predicted as predicted
    import calib_core.io.images as images

    findable = set(IDS)

    def look(image, cam, r, uv_px, radius_px, background=None, shift_frac=0.3, seed=0):
        for c, (uv, rng) in _truth().items():
            if c in findable and np.hypot(*(uv - np.asarray(uv_px))) <= shift_frac * radius_px:
                return ImageDetection(found=True, center_uv_px=uv.copy(), cov_uv_px2=np.eye(2) * 0.01, score=None,
                                      radius_px=float(cam.fx * r / rng), range_m=float(rng), method="ellipse-exact")
        return ImageDetection(found=False, reason="no round outline near the prediction", method="ellipse-exact")

    monkeypatch.setattr(images, "load_image", lambda path, wh: np.zeros((wh[1], wh[0], 3), np.uint8))
    monkeypatch.setattr(predicted, "detect_at_prediction", look)
    monkeypatch.setattr(pipeline, "detect_image_entry", lambda *a, **k: {"status": "auto", "reason": "no round outline"})
    monkeypatch.setattr(pipeline, "_with_fingerprint", lambda data, cid, sensor, entry, hint=None: entry)
    return findable


def _centres(out):
    return {c: e["center"] for c, e in out.items() if e.get("center") is not None}


def test_three_plain_detections_and_looks_that_confirm_them_find_the_rest(looks):
    dets = _detections()
    out = pipeline._resolve_ambiguous_images(_data(), dets, "cam1", only=set(IDS))
    found = _centres(out)
    assert set(found) == set(IDS) - set(PLAIN)
    for c, uv in found.items():
        assert np.hypot(*(np.asarray(uv) - _truth()[c][0])) < 1e-2  # entries keep 3 decimals
    assert any("registration on 3 captures" in out[c]["resolved_by"] and "confirmed by" in out[c]["resolved_by"] for c in found)


def test_one_confirming_look_is_not_enough(looks):
    looks.intersection_update({"p05"})  # every other look finds nothing
    out = pipeline._resolve_ambiguous_images(_data(), _detections(), "cam1", only=set(IDS))
    assert _centres(out) == {}


def test_a_wrong_plain_detection_gives_no_look_kept(looks):
    out = pipeline._resolve_ambiguous_images(_data(), _detections(plain_offset_px=(35.0, -20.0)), "cam1", only=set(IDS))
    assert _centres(out) == {}
