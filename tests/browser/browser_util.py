"""Helpers shared by the Chromium tests and the browser benchmark (the fixtures are in
chromium_fixtures.py, a pytest plugin loaded by tests/conftest.py)."""

from __future__ import annotations

import contextlib
import math
import shutil
import time
from pathlib import Path

import numpy as np

ARTIFACTS = Path(__file__).resolve().parents[2] / "test-artifacts"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]

def wait_for(cond, timeout=60.0, what="condition", poll=0.05):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        v = cond()
        if v:
            return v
        time.sleep(poll)
    raise AssertionError(f"timed out waiting for {what}")


@contextlib.contextmanager
def chromium_browser():
    """Debian's Chromium, headless, driven by Playwright (FileNotFoundError when not installed)."""
    from playwright.sync_api import sync_playwright

    exe = shutil.which("chromium")
    if exe is None:
        raise FileNotFoundError("Debian chromium is not installed")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=exe, headless=True, args=CHROMIUM_ARGS)
        try:
            yield browser
        finally:
            browser.close()


def new_context(browser, width=1500, height=860):
    """A fresh browser context (its own cookies and cache) with the tests' viewport and timeout."""
    ctx = browser.new_context(viewport={"width": width, "height": height})
    ctx.set_default_timeout(30_000)
    return ctx


@contextlib.contextmanager
def chromium(width=1500, height=860):
    """One Chromium and one context, outside pytest (the benchmark)."""
    with chromium_browser() as browser:
        ctx = new_context(browser, width, height)
        try:
            yield ctx
        finally:
            ctx.close()


def shot(page, name: str):
    import cv2

    ARTIFACTS.mkdir(exist_ok=True)
    png = page.screenshot(path=str(ARTIFACTS / name))
    return cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)


def canvas_box(page):
    boxes = [b for b in (c.bounding_box() for c in page.locator("canvas").all()) if b]
    return max(boxes, key=lambda b: b["width"] * b["height"])


def page_text(page) -> str:
    return page.locator("body").inner_text()


def choose(page, combobox: str, option: str) -> None:
    page.get_by_role("combobox", name=combobox).click()
    page.get_by_role("option", name=option, exact=True).click()


def only_client(wb, before=()):
    """The one viser client connected after ``before`` (ids) were."""
    return wait_for(lambda: next((c for i, c in wb.server.get_clients().items() if i not in before), None), 30,
                    "the page's websocket client")


def screen_of(client, box, X_world):
    """Canvas position (CSS px) of a world point seen by ``client``'s camera (OpenCV convention)."""
    import viser.transforms as vtf

    R = vtf.SO3(np.asarray(client.camera.wxyz)).as_matrix()
    pc = R.T @ (np.asarray(X_world, float) - np.asarray(client.camera.position))
    f = box["height"] / 2 / math.tan(client.camera.fov / 2)
    return box["x"] + box["width"] / 2 + f * pc[0] / pc[2], box["y"] + box["height"] / 2 + f * pc[1] / pc[2]


def board_point_world(wb, cam: str, uv) -> np.ndarray:
    """World position of raw pixel ``uv`` on camera ``cam``'s image board."""
    from app.panels.scene3d import camera_pose

    model = wb.state.camera(cam)
    T, rw, rh = wb.images.board_geometry(cam)
    local = np.array([((uv[0] + 0.5) / model.width_px - 0.5) * rw, ((uv[1] + 0.5) / model.height_px - 0.5) * rh, 0.0, 1.0])
    return (camera_pose(wb.state, cam) @ T @ local)[:3]


def click_pixel(page, wb, client, cam: str, uv) -> None:
    """Click where raw pixel ``uv`` of camera ``cam``'s board appears in ``client``'s view."""
    page.mouse.click(*screen_of(client, canvas_box(page), board_point_world(wb, cam, uv)))


def disk_detections(root):
    from calib_core.detections import load_detections
    from calib_core.session import load_session

    return load_detections(load_session(root))


class FrameLog:
    """Websocket frames the page receives (viser's socket lives in a web worker, which page
    scripts cannot see; Playwright can): (perf_counter seconds, bytes) per frame."""

    def __init__(self, page):
        self.frames: list = []
        page.on("websocket", lambda ws: ws.on("framereceived", self._add))

    def _add(self, payload) -> None:
        self.frames.append((time.perf_counter(), len(payload)))

    def first_big_after(self, t0: float, min_bytes: int = 4000):
        return next((t for t, n in list(self.frames) if t > t0 and n >= min_bytes), None)
