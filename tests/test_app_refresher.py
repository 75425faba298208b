"""The workbench's refresh thread: light handlers before heavy ones; heavy ones held while the
first page loads, then run once on release; wait_idle covers what is owed."""

from __future__ import annotations

import threading

from app.common import Refresher


def _refresher(log):
    errors = []
    r = Refresher(on_error=lambda kind, e: errors.append((kind, e)))
    return r, errors


def test_heavy_handlers_run_after_light_ones_in_a_batch():
    log = []
    r, errors = _refresher(log)
    try:
        gate = threading.Event()
        r.on("first", lambda: gate.wait(10))  # keeps the thread busy while the batch is marked
        r.on("detections", lambda: log.append("image"), heavy=True)
        r.on("detections", lambda: log.append("table"))
        r.on("selection", lambda: log.append("cloud"), heavy=True)
        r.on("selection", lambda: log.append("markers"))
        r.mark("first")
        r.mark("detections", "selection")
        gate.set()
        assert r.wait_idle(10)
        assert log == ["table", "markers", "image", "cloud"] and not errors
    finally:
        r.stop()


def test_held_heavy_handlers_are_owed_once_and_run_on_release():
    log = []
    r, errors = _refresher(log)
    try:
        image = lambda: log.append("image")  # noqa: E731
        r.on("detections", image, heavy=True)
        r.on("selection", image, heavy=True)
        r.on("detections", lambda: log.append("table"))
        r.hold()
        r.mark("detections")
        r.mark("selection")
        assert not r.wait_idle(0.5)  # the image is owed: not idle until released
        assert r.wait_idle(5, owed=False)  # (what stop() waits for: the owed work is dropped)
        assert log == ["table"]
        r.release()
        assert r.wait_idle(10)
        assert log == ["table", "image"] and not r.holding and not errors
        r.mark("selection")  # after the release heavy handlers run as asked
        assert r.wait_idle(10) and log == ["table", "image", "image"]
    finally:
        r.stop()


def test_a_failing_handler_is_reported_and_the_others_still_run():
    log = []
    r, errors = _refresher(log)
    try:
        r.on("detections", lambda: 1 / 0, heavy=True)
        r.on("detections", lambda: log.append("table"))
        r.on("detections", lambda: log.append("image"), heavy=True)
        r.mark("detections")
        assert r.wait_idle(10)
        assert log == ["table", "image"]
        assert len(errors) == 1 and errors[0][0] == "detections" and isinstance(errors[0][1], ZeroDivisionError)
    finally:
        r.stop()
