"""The sonar-guided second look at images (calib_core.pipeline): the reasons it records.

The detectors are replaced by stand-ins (fast, no files): what is tested is the bookkeeping
around them, the ``resolved_by`` text and the ``first_reason`` of an entry that still failed.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from calib_core import pipeline
from calib_core.disambiguate import image as disambiguate
from calib_core.camera import CameraModel
from calib_core.detect.reasons import count_reasons
from calib_core.detect.types import ImageDetection
from calib_core.disambiguate.image import Resolution

CAM = CameraModel(640, 480, np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]]))
UVR = (320.0, 240.0, 2.0)


def _data():
    cap = SimpleNamespace(image_paths={"cam1": "unused.png"})
    session = SimpleNamespace(sphere_radius_m=0.1, capture=lambda cid: cap)
    return SimpleNamespace(camera=lambda name: CAM, session=session, background=lambda name: None)


def _capture(image_entry: dict) -> dict:
    return {"sonar": {"status": "auto", "center": [0.0, 0.0, 2.0]}, "cam1": {"status": "auto", **image_entry}}


@pytest.fixture
def stand_ins(monkeypatch):
    """A registration that sends every capture back to UVR, and a refit that finds the ball there."""
    def resolve(cam, centers, cands, predict_for=(), rough=(), range_free=()):
        return Resolution(predicted_uvr={c: UVR for c in centers})

    monkeypatch.setattr(disambiguate, "resolve_candidates", resolve)
    monkeypatch.setattr(pipeline, "detect_image_entry", lambda data, cid, cam, hint_uv_px, hint_radius_px:
                        {"status": "auto", "center": [UVR[0], UVR[1]], "range_m": UVR[2], "score": 0.9})
    monkeypatch.setattr(pipeline, "_with_fingerprint", lambda data, cid, sensor, entry, hint=None: entry)


def test_second_look_says_what_the_first_detection_saw(stand_ins):
    dets = {
        "two": _capture({"reason": "two round objects: (100, 100) and (300, 300)",
                         "two_candidates": [[100.0, 100.0, 2.0], [300.0, 300.0, 2.0]]}),
        "none": _capture({"reason": "no round outline"}),
        "half": _capture({"reason": "outline 55 % hidden or too faint at (320, 240)",
                          "partial_center_uv_px": [321.0, 239.0], "partial_range_m": 2.05}),
        "off": _capture({"center": [20.0, 20.0], "range_m": 2.0, "score": 0.9}),
    }
    out = pipeline._resolve_ambiguous_images(_data(), dets, "cam1", only=set(dets))
    why = {cid: e["resolved_by"] for cid, e in out.items()}
    assert set(why) == set(dets)
    assert "two round objects" in why["two"] and "did not fit" not in why["two"]
    assert why["none"].endswith("found nothing")
    assert "partly hidden" in why["half"]
    assert why["off"].endswith("did not fit the rig transform")


def test_a_failed_look_keeps_the_first_detections_own_reason(monkeypatch):
    import calib_core.detect.image.predicted as predicted
    import calib_core.io.images as images

    look = "no round outline near the sonar's prediction"
    monkeypatch.setattr(images, "load_image", lambda path, wh: np.zeros((wh[1], wh[0], 3), np.uint8))
    monkeypatch.setattr(predicted, "detect_at_prediction",
                        lambda *a, **k: ImageDetection(found=False, reason=look, method="ellipse-exact"))
    res = Resolution(T_cam_sonar=np.eye(4), support=5, residual_px=1.0, range_rel_rms=0.01)
    fresh = {"status": "auto", "reason": "outline 45 % hidden or too faint at (3, 4)"}
    first = pipeline._look_at_prediction(_data(), "c1", "cam1", UVR, (res.residual_px, pipeline._registration_phrase(res)), fresh, {})
    assert first["reason"] == look and first["first_reason"] == fresh["reason"]
    # the same failed entry, reused by a later run (its fingerprint still matches) and looked at again
    again = pipeline._look_at_prediction(_data(), "c1", "cam1", UVR, (res.residual_px, pipeline._registration_phrase(res)), first, {})
    assert again["reason"] == look and again["first_reason"] == fresh["reason"]


def test_a_look_at_another_range_is_counted_under_one_plain_kind(monkeypatch):
    import calib_core.detect.image.predicted as predicted
    import calib_core.io.images as images

    monkeypatch.setattr(images, "load_image", lambda path, wh: np.zeros((wh[1], wh[0], 3), np.uint8))
    res = Resolution(T_cam_sonar=np.eye(4), support=5, residual_px=1.0, range_rel_rms=0.01)
    reasons = []
    for rng_m in (3.1, 1.4):  # outlines found at the predicted place, but far off the predicted 2 m
        monkeypatch.setattr(predicted, "detect_at_prediction", lambda *a, r=rng_m, **k: ImageDetection(
            found=True, center_uv_px=np.array(UVR[:2]), range_m=r, method="ellipse-exact"))
        e = pipeline._look_at_prediction(_data(), "c1", "cam1", UVR, (res.residual_px, pipeline._registration_phrase(res)), {"status": "auto", "reason": "no round outline"}, {})
        assert e.get("center") is None and f"{rng_m:.2f} m" in e["reason"]
        reasons.append(e["reason"])
    # the CLI's summary groups reasons by kind: numbers dropped, no stray brackets or units
    assert count_reasons(reasons) == "outline at the predicted place but at another range: 2"
