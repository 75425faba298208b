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
    from sonarcal_cli.commands import serve as cmd_serve

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
    import app.panels.review as review

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
    assert wb.fused.node is not None
    assert wb.scene3d.hidden == {c.id for c in wb.state.session.captures}  # the fused cloud alone on screen
    assert not any(n.visible for n in wb.scene3d.cloud_nodes.values())
    wb.fused.show.value = False
    assert wb.wait_idle(30)
    assert wb.scene3d.hidden == set() and wb.scene3d.cloud_nodes[wb.state.selected].visible


def test_drag_handle_refits_the_sonar_centre_on_release(wb, monkeypatch):
    from types import SimpleNamespace

    import app.panels.review as review

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


def test_click_messages_say_a_failed_refit_plainly():
    from app.panels.images import click_message

    ok = click_message("p01", "cam2", {"center": [10.0, 20.0], "refit": True}, True)
    failed = click_message("p01", "cam2", {"center": [10.0, 20.0], "refit": False, "refit_reason": "no sphere"}, True)
    plain = click_message("p01", "cam2", {"center": [10.0, 20.0], "refit": False}, False)
    assert ok[2] == "green" and "cam2 corrected" in ok[0]
    assert failed[2] != "green" and "refit failed" in failed[0] and "no sphere" in failed[1]
    assert plain[2] == "green" and "clicked centre" in plain[1]


def test_a_click_corrects_the_camera_looked_through_and_refit_uses_the_sphere_size(wb, monkeypatch):
    import app.panels.images as images

    seen = {}

    def fake_refit(data, cid, cam, uv, radius):
        seen.update(cid=cid, cam=cam, radius=radius)
        return {"status": "corrected", "center": [float(v) for v in uv], "refit": True}

    monkeypatch.setattr(images, "refit_image", fake_refit)
    wb.images.viewing[7] = ("cam1", np.zeros(3))
    assert wb.images.clicked_camera(7, "cam9") == "cam1"  # a board behind another: the viewed camera wins
    assert wb.images.clicked_camera(8, "cam9") == "cam9"
    calibrate_fake(wb, T_from_rotvec(np.zeros(3), np.array([0.0, 0.0, 0.0])))
    e = wb.images.correct_click("p02", "cam1", (20.0, 21.0), "b")
    assert e["refit"] is True and e["refit_asked"] is True and seen["cam"] == "cam1"
    son = wb.state.entry("p02", "sonar")["center"]
    fx = wb.state.camera("cam1").fx
    assert abs(seen["radius"] - fx * wb.state.session.sphere_radius_m / son[2]) < 1e-9  # not the click radius


def test_session_tab_follows_a_solve_and_events_are_named(wb):
    from app.panels.session import calibration_line

    assert "none yet" in wb.session_panel.info.content
    calibrate_fake(wb, np.eye(4))
    assert "results/calibration.json" in wb.session_panel.info.content
    assert calibration_line({"cameras": {"cam1": {"rms_reprojection_px": 0.512}}}).endswith("(cam1 RMS 0.51 px)")
    got = []
    wb.state.bus.subscribe("corrected", lambda **kw: got.append(kw))
    wb.images.refit.value = False
    wb.images.correct_click("p01", "cam1", (5.0, 6.0), "b")
    assert got == [{"cid": "p01", "sensor": "cam1"}]
    with pytest.raises(KeyError):
        wb.state.bus.publish("no-such-event")


def test_review_table_colours_and_states_thresholds(wb):
    from app.panels.review import DOTS, cell, dot
    from calib_core.diagnose.wording import THRESHOLDS_NOTE

    calibrate_fake(wb, np.eye(4))
    text = wb.review.table.content
    assert THRESHOLDS_NOTE in text and f"{DOTS['good']} good" in text
    c = cell({"status": "auto", "score": 0.95, "residual_px": 7.25, "found": True, "flag": None})
    assert c.startswith(DOTS["bad"]) and "7.25\u00a0px" in c  # bad
    assert " " not in c.split("</span>", 1)[1]  # and never wrapped mid-value
    assert cell({"status": "rejected", "score": None, "residual_px": None, "found": False}).startswith(dot("none"))


def test_a_flag_is_a_link_to_its_capture_and_fix(wb):
    from types import SimpleNamespace

    from calib_core.diagnose import Flag

    st = wb.state
    wb.diagnoser.wait_idle(30)
    st.flags = [Flag("p03", "sonar", "sonar", "cam1", 40.0, None, [0.1, 0.2, 2.9], 0.3),
                Flag("p02", "cam1", "image", "cam1", 55.0, [30.0, 20.0], None, 12.0)]
    st.bus.publish("flags")
    assert wb.wait_idle(30)
    b0, b1 = wb.flags.buttons[:2]
    assert b0.visible and b0.label == "⚠ p03 sonar: sonar detection wrong" and "drag the handle" in b0.hint
    assert b1.label == "⚠ p02 cam1: image detection wrong" and not wb.flags.buttons[2].visible
    first_two = wb.review.table.content.split("\n")[4:6]  # flagged captures come first, marked
    assert {ln.split("|")[2].strip() for ln in first_two} == {"p02", "p03"} and all("⚠" in ln for ln in first_two)
    wb.flags.go(SimpleNamespace(client=None, client_id=None), 0)
    assert wb.wait_idle(30)
    assert st.selected == "p03" and wb.review.sensor.value == "sonar" and wb.review.handle_on.value
    assert "sonar detection is wrong" in wb.review.details.content
    wb.flags.go(SimpleNamespace(client=None, client_id=None), 1)
    assert wb.wait_idle(30)
    assert st.selected == "p02" and wb.review.sensor.value == "cam1"
    # uncalibrated: the board marks where the consensus pose puts the sphere
    assert np.allclose(wb.images.reprojected_centre("p02", "cam1"), [30.0, 20.0])


def test_default_view_faces_the_image_boards(wb):
    import contextlib
    from types import SimpleNamespace

    from app.panels.scene3d import camera_pose

    calibrate_fake(wb, T_from_rotvec(np.array([0.4, -0.3, 0.2]), np.array([0.1, 0.0, 0.2])))
    client = SimpleNamespace(camera=SimpleNamespace(), atomic=contextlib.nullcontext)
    wb.scene3d.home_view(client)
    view = np.asarray(client.camera.look_at, float) - np.asarray(client.camera.position, float)
    axis = camera_pose(wb.state, "cam1")[:3, 2]  # the board's normal (the camera's optical axis)
    angle = np.degrees(np.arccos(view @ axis / np.linalg.norm(view)))
    assert angle < 50, angle  # seen from behind the camera, not edge-on (90 deg)
