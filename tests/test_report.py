"""HTML report: content, self-containment, defensive reading of calibration.json, the command."""

from __future__ import annotations

import argparse
import base64
import json
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from calib_core.camera import CameraModel
from calib_core.errors import SessionError
from calib_core.geometry import T_from_rotvec, invert_T, transform_points
from calib_core.io.clouds import Cloud, save_cloud
from calib_core.io.images import save_image
from calib_core.io.intrinsics import save_intrinsics_ros
from calib_core.report import build_report
from calib_core.results import save_calibration
from calib_core.session import load_session
from sonarcal_cli.commands import report as cmd_report

R_SPHERE = 0.11


def make_scene_session(root: Path, n_caps: int = 2, name: str = "report-test", offset_px=(3.0, 4.0)) -> dict:
    """Two cameras, ``n_caps`` captures of a sphere in front of a wall; detections whose image
    centres are the exact projections plus ``offset_px``; returns the truth."""
    rng = np.random.default_rng(0)
    cams = {"cam1": CameraModel(480, 270, [[350, 0, 239.5], [0, 350, 134.5], [0, 0, 1]], [-0.05, 0.01, 0, 0, 0]),
            "cam2": CameraModel(480, 270, [[360, 0, 240.0], [0, 360, 135.0], [0, 0, 1]], [0, 0, 0, 0, 0])}
    T = {"cam1": T_from_rotvec([0.02, -0.03, 0.01], [0.3, -0.1, 0.05]),
         "cam2": T_from_rotvec([0.01, 0.05, 0.0], [-0.4, -0.1, 0.05])}
    caps, dets = [], {}
    for k in range(n_caps):
        cid = f"p{k + 1:02d}"
        centre = np.array([0.3 * k - 0.2, 0.1, 2.5 + 0.3 * k])  # sonar frame == roughly cam frame here
        d = rng.normal(size=(3000, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        wall = np.column_stack([rng.uniform(-2, 2, 4000), rng.uniform(-1, 1, 4000), np.full(4000, 4.0)])
        pts = np.vstack([centre + R_SPHERE * d, wall])
        save_cloud(root / "clouds" / f"{cid}.ply", Cloud(pts))
        images, entry = {}, {"sonar": {"center": centre.tolist(), "status": "accepted", "score": 0.9,
                                       "history": [{"time": "2026-11-22T10:00:00+00:00", "status": "auto",
                                                    "center": centre.tolist(), "who": "detector"},
                                                   {"time": "2026-11-22T10:05:00+00:00", "status": "accepted",
                                                    "center": centre.tolist(), "who": "operator-anna"}]}}
        for cam, m in cams.items():
            uv = m.project(transform_points(T[cam], centre[None]))[0]
            img = np.full((270, 480, 3), (90, 120, 150), np.uint8)
            r_px = float(m.fx * R_SPHERE / transform_points(T[cam], centre[None])[0, 2])
            cv2.circle(img, (int(round(uv[0])), int(round(uv[1]))), int(round(r_px)), (30, 30, 30), -1)
            save_image(root / "images" / cam / f"{cid}.png", img)
            images[cam] = f"images/{cam}/{cid}.png"
            entry[cam] = {"center": [float(uv[0] + offset_px[0]), float(uv[1] + offset_px[1])], "status": "auto",
                          "score": 0.97, "radius_px": float(r_px), "ellipse_px": [float(uv[0]), float(uv[1]), 2 * r_px, 2 * r_px, 0.0]}
        caps.append({"id": cid, "cloud": f"clouds/{cid}.ply", "images": images})
        dets[cid] = entry
    for cam, m in cams.items():
        save_intrinsics_ros(root / "intrinsics" / f"{cam}.yaml", m, cam)
    manifest = {"format": "sonar-camera-session/1", "name": name, "sphere": {"diameter": 2 * R_SPHERE},
                "cameras": {c: {"intrinsics": f"intrinsics/{c}.yaml"} for c in cams}, "captures": caps,
                "measured": {"cam1-sonar": 0.33, "cam2-sonar": 0.42, "cam1-cam2": 0.7}}
    (root / "session.yaml").write_text(yaml.safe_dump(manifest, sort_keys=False))
    (root / "detections.yaml").write_text(yaml.safe_dump({"format": "sonar-camera-detections/1", "captures": dets}))
    return {"T": T, "cams": cams}


def full_calibration(truth) -> dict:
    cov = np.diag([1e-6] * 3 + [1e-6] * 3)
    return {
        "format": "sonar-camera-calibration/1", "session": "report-test", "created": "2026-11-22T12:00:00+00:00",
        "cameras": {c: {"T_cam_sonar": T.tolist(), "rms_reprojection_px": 1.25, "captures_used": ["p01", "p02"],
                        "covariance": cov.tolist(), "solution": "independent"} for c, T in truth["T"].items()},
        "range_scale": {"value": 1.0, "sigma": None, "estimated": False, "note": "not requested"},
        "table_i": {"cameras": ["cam1", "cam2"], "note": "independent per-camera solves", "pairs": {
            "cam1-sonar": {"estimated_m": 0.84479, "measured_m": 0.86557, "error_pct": -2.4, "assoc_m": 0.84827,
                           "assoc_error_pct": 0.41, "error_length_m": 0.04284, "included_angle_rad": np.radians(2.89)},
            "cam2-sonar": {"estimated_m": 0.89603, "measured_m": 0.8625, "error_pct": 3.9},
            "cam1-cam2": {"estimated_m": 0.7075, "measured_m": 0.74374, "error_pct": -4.9}}},
        "warnings": ["a <b>warning</b> to show"],
    }


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    root = tmp_path_factory.mktemp("report_session")
    truth = make_scene_session(root)
    return root, truth


def _images(html: str) -> list[str]:
    return re.findall(r"<img [^>]*src='([^']+)'", html)


def test_report_is_self_contained_and_complete(scene):
    root, truth = scene
    session = load_session(root)
    from calib_core.detections import load_detections

    html = build_report(session, full_calibration(truth), load_detections(session))
    assert "<title>sonarcal report: report-test</title>" in html
    # no network: every reference is inline
    assert not re.search(r"(src|href)\s*=\s*['\"]?(https?:|//)", html)
    assert "<script" not in html and "<link" not in html
    uris = _images(html)
    # 2 captures: sonar + 2 camera thumbnails, 2 overlays each, 1 coloured cloud each
    assert len(uris) == 2 * 3 + 2 * 2 + 2
    for uri in uris:
        head, b64 = uri.split(",", 1)
        assert head in ("data:image/png;base64", "data:image/jpeg;base64")
        img = cv2.imdecode(np.frombuffer(base64.b64decode(b64), np.uint8), cv2.IMREAD_COLOR)
        assert img is not None and img.size > 0 and img.std() > 1  # decodes and is not blank
    # pose with 1/3-sigma, Table I, history, residuals
    assert "1.0 1.0 1.0" in html and "3.0 3.0 3.0" in html  # translation sigma mm
    assert "0.057 0.057 0.057" in html and "0.172 0.172 0.172" in html  # rotation sigma deg
    assert "844.79" in html and "865.57" in html and "+0.41 %" in html and "2.89" in html
    assert "operator-anna" in html and "2026-11-22T10:05:00+00:00" in html
    assert html.count("<svg") >= 2 * 2 + 2 * 2  # residual bars + scatter, sigma charts per camera
    assert "5.00 px" in html  # residual recomputed: offset (3, 4) px
    assert "a &lt;b&gt;warning&lt;/b&gt; to show" in html


def test_report_reads_calibration_defensively(scene):
    root, truth = scene
    session = load_session(root)
    minimal = {"format": "sonar-camera-calibration/1",
               "cameras": {"cam1": {"T_cam_sonar": truth["T"]["cam1"].tolist()}}}
    html = build_report(session, minimal, {})
    assert "No Table I" in html and "uncertainty unknown" in html
    assert len(_images(html)) >= 2  # overlays and coloured clouds for cam1
    odd = dict(minimal, table_i={"pairs": {"cam1-sonar": {"estimated_m": "n/a"}}}, range_scale="weird",
               cameras={"cam1": {"T_cam_sonar": truth["T"]["cam1"].tolist(), "covariance": [[1, 2]],
                                 "residuals": [{"capture": "p01", "residual_px": "bad"}]}})
    html = build_report(session, odd, {})
    assert "sonarcal report" in html
    none = build_report(session, None, None, calibration_note="No calibration yet")
    assert "No calibration yet" in none and "Pose" not in none


def test_report_shows_problems_and_escapes(tmp_path):
    make_scene_session(tmp_path, n_caps=1, name="<script>alert(1)</script>")
    (tmp_path / "images" / "cam2" / "p01.png").unlink()
    session = load_session(tmp_path)
    html = build_report(session, None, {})
    assert "<script>alert" not in html and "&lt;script&gt;" in html
    assert "image file not found" in html


def test_report_says_how_a_look_alike_was_ruled_out(tmp_path):
    """A centre singled out among look-alikes says how, escaped, beside its detection."""
    make_scene_session(tmp_path, n_caps=1)
    dets = yaml.safe_load((tmp_path / "detections.yaml").read_text())["captures"]
    dets["p01"]["sonar"].update(resolved_by="static scenery: the other <candidate> stays put",
                                two_candidates=[[0, 0, 1], [1, 0, 1]])
    html = build_report(load_session(tmp_path), None, dets)
    assert "chosen by static scenery: the other &lt;candidate&gt; stays put" in html
    del dets["p01"]["sonar"]["resolved_by"]
    assert "chosen by" not in build_report(load_session(tmp_path), None, dets)


def test_overlay_segments_the_sphere(scene):
    """The report's overlay comes from the reprojected cloud: the sphere's pixels are tinted."""
    root, truth = scene
    from calib_core.report.captures import ReportOptions, capture_view

    session = load_session(root)
    models = {c: session.camera_model(c) for c in session.cameras}
    view = capture_view(session, session.captures[0], {}, full_calibration(truth), models, ReportOptions())
    assert set(view.overlays) == {"cam1", "cam2"} and view.coloured_cloud
    b64 = view.overlays["cam1"].split(",", 1)[1]
    over = cv2.cvtColor(cv2.imdecode(np.frombuffer(base64.b64decode(b64), np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    m = truth["cams"]["cam1"]
    centre = np.array([-0.2, 0.1, 2.5])
    uv = m.project(transform_points(truth["T"]["cam1"], centre[None]))[0]
    u, v = int(round(uv[0])), int(round(uv[1]))
    patch = over[v - 3:v + 4, u - 3:u + 4].astype(int)
    assert (patch[..., 1] > patch[..., 0] + 15).all()  # green tint over the dark sphere
    assert 0.2 < view.coloured_fraction < 1.0


# ---- the command ---------------------------------------------------------------
def _args(*argv):
    p = argparse.ArgumentParser()
    cmd_report.add_parser(p.add_subparsers())
    return p.parse_args(["report", *map(str, argv)])


def test_cli_writes_default_path_and_handles_missing_or_bad_calibration(tmp_path):
    truth = make_scene_session(tmp_path, n_caps=1)
    args = _args(tmp_path)
    assert args.run(args) == 0  # no calibration yet: a report anyway, with a note
    out = tmp_path / "results" / "report.html"
    assert "No calibration yet" in out.read_text()
    save_calibration(tmp_path / "results" / "calibration.json", full_calibration(truth))
    custom = tmp_path / "elsewhere" / "r.html"
    args = _args(tmp_path, "--out", custom, "--mask-radius", "5")
    assert args.run(args) == 0 and "844.79" in custom.read_text()
    (tmp_path / "results" / "calibration.json").write_text("{not json")
    before = out.read_bytes()
    args = _args(tmp_path)
    with pytest.raises(SessionError, match="invalid JSON"):
        args.run(args)
    assert out.read_bytes() == before
    assert json.loads(json.dumps(full_calibration(truth)))  # the fixture itself is JSON-clean


# ---- rendering helpers ---------------------------------------------------------------
def test_render_points_shows_the_nearest_point_per_pixel():
    from calib_core.report.render import oblique_view, render_points

    xs, ys = np.meshgrid(np.linspace(-0.5, 0.5, 60), np.linspace(-0.5, 0.5, 60))
    near = np.column_stack([xs.ravel() * 0.5, ys.ravel() * 0.5, np.full(xs.size, 2.0)])
    far = np.column_stack([xs.ravel() * 2, ys.ravel() * 2, np.full(xs.size, 3.0)])
    P = np.vstack([far, near])  # far first: order must not matter
    cols = np.vstack([np.tile([0, 0, 255], (len(far), 1)), np.tile([255, 0, 0], (len(near), 1))]).astype(np.uint8)
    cam = CameraModel(200, 200, [[100, 0, 99.5], [0, 100, 99.5], [0, 0, 1]])
    img = render_points(P, cols, cam, np.eye(4), splat_radius_px=2, depth_shading=0.0)
    assert tuple(img[100, 100]) == (255, 0, 0)  # the near square hides the far one
    assert tuple(img[100, 75]) == (0, 0, 255)  # beside it the far plane shows
    assert tuple(img[2, 2]) == (250, 250, 250)  # background
    vcam, T = oblique_view(P, np.eye(4), 320, 200, angle_deg=30)
    view = render_points(P, cols, vcam, T)
    assert (view != 250).any(axis=2).mean() > 0.05  # the cloud fills a fair part of the view
    eye = -T[:3, :3].T @ T[:3, 3]
    assert abs(np.degrees(np.arctan2(eye[0] - np.median(P[:, 0]), -(eye[2] - np.median(P[:, 2]))))) > 10


def test_crop_thumbnail_is_centred_on_the_pixel():
    from calib_core.report.render import crop_thumbnail

    img = np.zeros((300, 400, 3), np.uint8)
    img[150, 250] = 255
    th = crop_thumbnail(img, (250.0, 150.0), half_size_px=20, out_px=41)
    assert th.shape == (41, 41, 3)
    assert np.unravel_index(np.argmax(th[..., 0]), th.shape[:2]) == (20, 20)
    whole = crop_thumbnail(img, None, 20, out_px=100)
    assert whole.shape == (100, 100, 3)


def test_report_falls_back_to_the_detections_calibration_used(scene):
    root, truth = scene
    session = load_session(root)
    cal = full_calibration(truth)
    cal["cameras"]["cam1"]["residuals"] = [{"capture": "p01", "used": True, "uv_px": [100.0, 80.0],
                                            "X_sonar_m": [-0.2, 0.1, 2.5], "residual_px": [0.5, -0.25]}]
    html = build_report(session, cal, {})
    assert "showing the detections calibration.json used" in html
    assert "(100.0, 80.0) px" in html and "(-200, 100, 2500) mm" in html
