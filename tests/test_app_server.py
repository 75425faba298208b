"""The workbench server without a browser: binding, click geometry, overlays, errors, uploads."""

from __future__ import annotations

import argparse
import io
import zipfile

import numpy as np
import pytest

from calib_core.detections import load_detections
from calib_core.geometry import T_from_rotvec
from calib_core.results import CALIBRATION_FORMAT
from calib_core.session import load_session
from test_app_state import make_session


@pytest.fixture()
def wb(tmp_path):
    from app.server import Workbench

    w = Workbench(make_session(tmp_path / "s"), port=0, uploads_dir=tmp_path / "uploads")
    assert w.wait_idle(30)
    yield w
    w.stop()


def calibrate_fake(wb, T):
    """Install a calibration dict (as the solver would return) for the display code."""
    wb.state.set_calibration({"format": CALIBRATION_FORMAT, "cameras": {"cam1": {"T_cam_sonar": T.tolist()}},
                              "range_scale": {"value": 1.0}})
    assert wb.wait_idle(30)


def test_binds_loopback_by_default(wb):
    assert wb.host == "127.0.0.1" and wb.port > 0
    assert wb.url == f"http://127.0.0.1:{wb.port}/?token={wb.token}" and len(wb.token) >= 24
    from sonarcal_cli import cmd_serve

    p = argparse.ArgumentParser()
    cmd_serve.add_parser(p.add_subparsers())
    args = p.parse_args(["serve", "somewhere"])
    assert args.host == "127.0.0.1" and args.port == 8080


@pytest.mark.parametrize("rot", [(0.0, 0.0, 0.0), (0.3, -0.5, 0.2)])
def test_board_click_maps_a_ray_back_to_its_pixel(wb, rot):
    T = T_from_rotvec(np.array(rot), np.array([0.1, -0.2, 0.4]))
    calibrate_fake(wb, T)
    T_cam_board, rw, rh = wb.images.board_geometry("cam1")
    T_world_board = wb.scene3d.camera_pose("cam1") @ T_cam_board
    model = wb.state.camera("cam1")
    eye = T_world_board[:3, :3] @ np.array([0.01, -0.02, -0.3]) + T_world_board[:3, 3]
    for uv in [(0.0, 0.0), (12.3, 40.7), (63.0, 47.0), (31.5, 23.5)]:
        local = np.array([((uv[0] + 0.5) / model.width_px - 0.5) * rw, ((uv[1] + 0.5) / model.height_px - 0.5) * rh, 0])
        hit = T_world_board[:3, :3] @ local + T_world_board[:3, 3]
        got = wb.images.pixel_from_ray("cam1", eye, (hit - eye) / np.linalg.norm(hit - eye))
        assert np.allclose(got, uv, atol=1e-9)
    assert wb.images.pixel_from_ray("cam1", eye, T_world_board[:3, 0]) is None  # parallel to the board


def test_click_correction_without_refit_is_saved_exactly(wb):
    wb.images.refit.value = False
    entry = wb.images.correct_click("p02", "cam1", (10.25, 11.5), "browser-3")
    disk = load_detections(load_session(wb.state.session.root))
    assert disk["p02"]["cam1"]["center"] == [10.25, 11.5] == entry["center"]
    assert disk["p02"]["cam1"]["status"] == "corrected" and disk["p02"]["cam1"]["history"][-1]["client"] == "browser-3"


def test_overlay_shows_the_reprojected_cloud_mask(wb):
    img_plain = wb.images.render("p01", "cam1")
    assert wb.images.mask("p01", "cam1", 3) is None  # not calibrated yet: no mask
    calibrate_fake(wb, np.eye(4))  # clouds sit ~3 m in front of the camera
    m = wb.images.mask("p01", "cam1", 3.0)
    assert m.shape == (48, 64) and m.any()
    out = wb.images.render("p01", "cam1")
    green = (out[..., 1].astype(int) - out[..., 0]) > 60
    assert green[m].mean() > 0.5 and not np.array_equal(out, img_plain)
    assert wb.images.reprojected_centre("p01", "cam1") is not None
    rows = wb.review.rows()
    assert all(r["residual"] is not None for r in rows)
    assert [r["residual"] for r in rows] == sorted((r["residual"] for r in rows), reverse=True)  # worst first


def test_pick_in_sonar_picks_the_first_point_along_the_ray(wb, monkeypatch):
    import app.review as review

    seen = {}

    def fake_refit(data, cid, seed):  # record the seed, return a plain correction
        seen["seed"] = np.asarray(seed)
        return {"status": "corrected", "center": [float(v) for v in seed], "refit": False}

    monkeypatch.setattr(review, "refit_sonar", fake_refit)
    P = wb.state.cloud("p01").points_m
    target = P[np.argmin(P[:, 2])]  # the nearest point to an eye far behind along -z
    eye = target - np.array([0, 0, 10.0])
    wb.review.pick_sonar(eye, (0, 0, 1), "browser-1")
    assert np.allclose(seen["seed"], target)
    assert load_detections(load_session(wb.state.session.root))["p01"]["sonar"]["center"] == [float(v) for v in target]


def test_guarded_callbacks_never_raise(wb):
    from app.common import guarded

    @guarded(wb.server)
    def boom(event):
        raise RuntimeError("bad")

    assert boom(None) is None
    wb.session_panel.path.value = "/definitely/not/here"
    assert wb.session_panel.open_btn  # the handler below is the one the button runs
    from app.common import guarded as g

    g(wb.server)(wb.session_panel._open_path)(None)
    assert wb.state.session is not None and wb.state.session.name == "tiny"
    wb.state.select("p02")
    with pytest.raises(Exception):
        wb.state.select("nope")
    assert wb.state.selected == "p02"


def test_upload_of_a_zipped_session_opens_it(wb, tmp_path):
    src = make_session(tmp_path / "other")
    (src / "session.yaml").write_text((src / "session.yaml").read_text().replace("name: tiny", "name: uploaded"))
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for p in src.rglob("*"):
            if p.is_file():
                zf.write(p, "other/" + str(p.relative_to(src)))
    streamed = wb.uploads.incoming_file()
    streamed.write_bytes(buf.getvalue())
    wb.session_panel._on_upload(None, "other.zip", streamed)
    assert wb.wait_idle(30)
    assert not streamed.exists()  # the streamed zip is deleted once unpacked
    assert wb.state.session.name == "uploaded"
    assert (tmp_path / "uploads").resolve() in wb.state.session.root.parents


def test_fused_view_colours_the_cloud_from_the_image(wb):
    from types import SimpleNamespace

    from calib_core.errors import SessionError

    with pytest.raises(SessionError, match="no calibrated camera"):
        wb.fused.colour("p02")
    calibrate_fake(wb, np.eye(4))
    P, colours, coloured, cams = wb.fused.colour("p02")
    assert cams == ["cam1"] and coloured.any()
    assert (colours[coloured] == 30).all()  # p02's image is uniformly 30
    assert (colours[~coloured] == 90).all()  # the rest stays grey
    wb.fused.capture.value = "p02"
    wb.fused._run(SimpleNamespace(client=None, client_id=None))
    assert wb.wait_idle(30)
    assert wb.fused.node is not None and wb.scene3d.hidden == {"p02"}


def test_drag_handle_refits_the_sonar_centre_on_release(wb, monkeypatch):
    from types import SimpleNamespace

    import app.review as review

    monkeypatch.setattr(review, "refit_sonar", lambda data, cid, seed: {
        "status": "corrected", "center": [float(v) for v in seed], "refit": False})
    wb.review.handle_on.value = True
    assert wb.wait_idle(30)
    assert wb.review.handle is not None
    target = SimpleNamespace(position=np.array([0.5, 0.25, 3.0]))
    ev = lambda phase: SimpleNamespace(phase=phase, target=target, client=None, client_id=4)  # noqa: E731
    wb.review._on_drag(ev("start"))
    wb.review._on_drag(ev("update"))
    assert load_detections(load_session(wb.state.session.root))["p01"]["sonar"]["status"] == "auto"
    wb.review._on_drag(ev("end"))
    e = load_detections(load_session(wb.state.session.root))["p01"]["sonar"]
    assert e["status"] == "corrected" and e["center"] == [0.5, 0.25, 3.0] and e["history"][-1]["action"] == "drag"
