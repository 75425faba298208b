"""The review loop in real Chromium (Debian's, headless, Playwright) against live workbenches.

- six actions: a session with one wrong image detection (a look-alike decoy, the true sphere
  half hidden) and one moved target goes to "solved, both handled" with Solve, flag, click,
  flag, Reject, Solve;
- clicks land on the camera whose image was clicked, for each camera of a two-camera session,
  through "View through" and on the boards as the default view shows them;
- undo and redo after a reload of the page;
- the Fused tab puts the fused cloud alone on screen; the drag handle refits on release.
One server per session and one browser context for the module; small images (scale 0.25).
"""

from __future__ import annotations

import json
import re
import time

import numpy as np
import pytest
import yaml

from browser_util import (board_point_world, canvas_box, click_pixel, disk_detections, only_client, screen_of, shot,
                          wait_for)

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def review_wb(tmp_path_factory):
    from app.server import Workbench
    from calib_core.synth.generate import generate_session

    from conftest import review_session_with_decoy_taken

    root = generate_session(tmp_path_factory.mktemp("review") / "review", "review", 11, scale=0.25,
                            pan_step_deg=1.0, sub_rays=7)
    review_session_with_decoy_taken(root)  # the decoy taken by the image detector, as the loop starts
    wb = Workbench(root, host="127.0.0.1", port=0)
    yield wb
    wb.stop()


@pytest.fixture(scope="module")
def stereo_wb(tmp_path_factory):
    from app.server import Workbench
    from calib_core.synth.generate import generate_session

    root = generate_session(tmp_path_factory.mktemp("stereo") / "stereo", "canal", 11, scale=0.25,
                            pan_step_deg=1.0, sub_rays=7, n_captures=6)
    wb = Workbench(root, host="127.0.0.1", port=0)
    yield wb
    wb.stop()


def _open(browser, wb):
    before = set(wb.server.get_clients())
    page = browser.new_page()
    page.goto(wb.url)
    page.get_by_text("Captures (worst first)").wait_for()
    return page, only_client(wb, before)


def test_six_actions_from_two_bad_captures_to_solved(browser, review_wb):
    wb = review_wb
    root = wb.state.session.root
    gt = yaml.safe_load((root / "ground_truth.yaml").read_text())
    moved = next(c for c, v in gt["captures"].items() if v.get("moved_m", 0) > 0.05)
    hidden = next(c for c, v in gt["captures"].items() if v["images"]["cam1"].get("occluded_fraction", 0) > 0.3)
    page, client = _open(browser, wb)
    assert wb.wait_idle(120)
    image_flag = page.get_by_role("button", name=f"⚠ {hidden} cam1: image detection wrong")
    moved_flag = page.get_by_role("button", name=f"⚠ {moved}: target moved")
    image_flag.wait_for()  # flagged before any Solve
    moved_flag.wait_for()
    assert not (root / "results" / "calibration.json").exists()
    actions = []

    def act(what, fn):
        actions.append(what)
        fn()

    solve = page.get_by_role("button", name="Solve", exact=True)
    act("Solve", solve.click)
    cal_path = root / "results" / "calibration.json"
    wait_for(cal_path.exists, 60, "the first calibration")
    assert wb.wait_idle(60)
    first = json.loads(cal_path.read_text())

    fov = client.camera.fov
    act("flag: image", image_flag.click)
    wait_for(lambda: wb.state.selected == hidden and abs(client.camera.fov - fov) > 1e-6, 20, "the flag's view")
    wait_for(lambda: wb.images.viewing.get(client.client_id, ("",))[0] == "cam1", 10, "looking through cam1")
    wait_for(lambda: wb.review.sensor.value == "cam1", 10, "Reject set to act on cam1")
    page.get_by_text("the image detection is wrong").first.wait_for()  # the fix is said
    ring = wb.images.reprojected_centre(hidden, "cam1")  # the predicted position, marked on the board
    true_uv = np.asarray(gt["captures"][hidden]["images"]["cam1"]["center_uv_px"], float)
    r_px = wb.state.camera("cam1").fx * wb.state.session.sphere_radius_m / 1.5
    assert np.linalg.norm(ring - true_uv) < 0.3 * r_px, (ring, true_uv)
    time.sleep(1.0)
    act("click the ring", lambda: click_pixel(page, wb, client, "cam1", ring))
    wait_for(lambda: disk_detections(root)[hidden]["cam1"]["status"] == "corrected", 30, "the image correction")
    e = disk_detections(root)[hidden]["cam1"]
    assert np.linalg.norm(np.asarray(e["center"]) - true_uv) < 0.3 * r_px
    assert disk_detections(root)[hidden]["sonar"]["status"] == "auto"  # only the clicked camera changed
    page.get_by_text(re.compile(f"{hidden} cam1(: refit failed| corrected)")).first.wait_for()
    assert wb.wait_idle(60)
    wait_for(lambda: not page.get_by_role("button", name=f"⚠ {hidden} cam1: image detection wrong").is_visible(),
             20, "the image flag to go once corrected")

    act("flag: moved", moved_flag.click)
    wait_for(lambda: wb.state.selected == moved, 20, "the moved capture selected")
    wait_for(lambda: wb.review.sensor.value == "all sensors", 10, "Reject set to act on the whole capture")
    act("Reject", page.get_by_role("button", name="Reject", exact=True).click)
    wait_for(lambda: disk_detections(root)[moved]["cam1"]["status"] == "rejected", 20, "the moved capture rejected")
    assert disk_detections(root)[moved]["sonar"]["status"] == "rejected"

    act("Solve", solve.click)
    wait_for(lambda: json.loads(cal_path.read_text())["created"] != first["created"] or
             json.loads(cal_path.read_text()) != first, 60, "the second calibration")
    assert wb.wait_idle(60)
    cal = json.loads(cal_path.read_text())["cameras"]["cam1"]
    assert hidden in cal["captures_used"] and moved not in cal["captures_used"]
    assert not cal.get("outliers")
    assert wb.state.flags == []
    gt_T = np.asarray(gt["cameras"]["cam1"]["T_cam_sonar"], float)
    assert np.linalg.norm(np.asarray(cal["T_cam_sonar"])[:3, 3] - gt_T[:3, 3]) < 0.03
    wait_for(lambda: "calibration: results/calibration.json" in wb.session_panel.info.content, 20,
             "the Session tab in step")
    assert len(actions) <= 6, actions
    shot(page, "workbench_review_loop.png")
    page.close()


def test_clicks_land_on_the_clicked_camera(browser, stereo_wb):
    wb = stereo_wb
    root = wb.state.session.root
    gt = yaml.safe_load((root / "ground_truth.yaml").read_text())
    page, client = _open(browser, wb)
    assert wb.wait_idle(120)
    page.get_by_role("checkbox", name="Refit near a click").uncheck()
    wait_for(lambda: not wb.images.refit.value, 10, "refit off")
    cams = list(wb.state.session.cameras)
    for k, cam in enumerate(cams):
        cid = f"p0{k + 2}"
        wb.state.select(cid)
        before = disk_detections(root)[cid]
        uv = np.asarray(gt["captures"][cid]["images"][cam]["center_uv_px"], float) + [3.0, -2.0]
        fov = client.camera.fov
        page.get_by_role("button", name=f"View through {cam}").click()
        wait_for(lambda: abs(client.camera.fov - fov) > 1e-6, 20, f"the view through {cam}")
        time.sleep(1.0)
        click_pixel(page, wb, client, cam, uv)
        wait_for(lambda: disk_detections(root)[cid][cam]["status"] == "corrected", 20, f"{cid} {cam} corrected")
        after = disk_detections(root)[cid]
        assert np.linalg.norm(np.asarray(after[cam]["center"]) - uv) < 1.0, (after[cam]["center"], uv)
        for other in cams:
            if other != cam:  # the other camera's entry is untouched
                assert after[other] == before[other], other
    # from the default view, on each board as it is shown
    page.get_by_role("tab", name="View", exact=True).click()
    pos = np.array(client.camera.position)
    page.get_by_role("button", name="Frame the selected capture").click()
    wait_for(lambda: np.linalg.norm(np.array(client.camera.position) - pos) > 1e-3, 20, "the default view")
    wait_for(lambda: all(b.visible for b in wb.images.boards.values()), 20, "every board shown")
    time.sleep(1.0)
    page.get_by_role("tab", name="Review", exact=True).click()
    cid = wb.state.selected
    for cam in cams:
        model = wb.state.camera(cam)
        uv = np.array([0.5 * model.width_px, 0.5 * model.height_px])
        x, y = screen_of(client, canvas_box(page), board_point_world(wb, cam, uv))
        before = disk_detections(root)[cid]
        n = len((before[cam].get("history") or []))
        page.mouse.click(x, y)
        wait_for(lambda: len(disk_detections(root)[cid][cam].get("history") or []) > n, 20, f"{cam} clicked")
        after = disk_detections(root)[cid]
        assert np.linalg.norm(np.asarray(after[cam]["center"]) - uv) < 3.0
        assert all(after[o] == before[o] for o in cams if o != cam)
    shot(page, "workbench_stereo_clicks.png")

    # undo and redo after a reload (a new connection), from the history in detections.yaml
    last = disk_detections(root)[cid][cams[-1]]["center"]
    page.reload()
    page.get_by_text("Captures (worst first)").wait_for()
    page.get_by_role("button", name="Undo", exact=True).click()
    wait_for(lambda: disk_detections(root)[cid][cams[-1]].get("center") != last, 20, "undo after reload")
    assert disk_detections(root)[cid][cams[-1]]["history"][-1]["kind"] == "undo"
    page.get_by_role("button", name="Redo", exact=True).click()
    wait_for(lambda: disk_detections(root)[cid][cams[-1]].get("center") == last, 20, "redo")
    page.close()


def test_fused_tab_and_drag_handle(browser, stereo_wb):
    wb = stereo_wb
    root = wb.state.session.root
    page, client = _open(browser, wb)
    page.get_by_role("button", name="Solve", exact=True).click()
    wait_for(lambda: (root / "results" / "calibration.json").exists(), 60, "a calibration")
    assert wb.wait_idle(60)
    page.get_by_role("tab", name="Fused", exact=True).click()
    page.get_by_role("button", name="Colour cloud").click()
    page.get_by_text("points coloured from").first.wait_for()
    assert wb.wait_idle(30)
    assert wb.fused.node is not None and wb.fused.node.visible
    assert not any(n.visible for n in wb.scene3d.cloud_nodes.values())  # only the fused cloud on screen
    page.get_by_role("checkbox", name="Show fused cloud").uncheck()
    wait_for(lambda: wb.scene3d.cloud_nodes[wb.state.selected].visible, 20, "the plain cloud back")

    # drag handle: press on its x arrow, move, release -> refit near the new place
    page.get_by_role("tab", name="Review", exact=True).click()
    cid = wb.state.selected
    X = np.asarray(disk_detections(root)[cid]["sonar"]["center"], float)
    page.get_by_text("Correct the sonar centre").click()
    page.get_by_role("checkbox", name="Drag handle at sonar centre").check()
    wait_for(lambda: wb.review.handle is not None, 20, "the handle")
    pos = np.array(client.camera.position)
    page.get_by_role("tab", name="View", exact=True).click()
    page.get_by_role("button", name="Frame the selected capture").click()
    time.sleep(1.5)
    box = canvas_box(page)
    n = len(disk_detections(root)[cid]["sonar"].get("history") or [])
    for axis in np.eye(3):
        a = screen_of(client, box, X + 0.6 * 0.3 * axis)  # along one arrow of the handle
        b = screen_of(client, box, X + 0.6 * 0.3 * axis + 0.05 * axis)
        page.mouse.move(*a)
        page.mouse.down()
        for t in np.linspace(0, 1, 6)[1:]:
            page.mouse.move(a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]))
        page.mouse.up()
        try:
            wait_for(lambda: len(disk_detections(root)[cid]["sonar"].get("history") or []) > n, 5, "a drag")
            break
        except AssertionError:
            continue
    e = disk_detections(root)[cid]["sonar"]
    assert e["history"][-1]["action"] == "drag" and e["status"] == "corrected"
    assert np.linalg.norm(np.asarray(e["center"]) - X) < 0.05  # refit back onto the sphere
    del pos
    page.close()
