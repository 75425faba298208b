"""The HTML report renders in real headless Chromium: title, decoded images, SVG plots, no requests fail."""

from __future__ import annotations

import pytest

from test_report import full_calibration, make_scene_session

from calib_core.detections import load_detections
from calib_core.report import write_report
from calib_core.session import load_session

pytestmark = pytest.mark.browser


def test_report_renders_in_chromium(tmp_path, browser):
    root = tmp_path / "session"
    truth = make_scene_session(root)
    session = load_session(root)
    out = write_report(session, root / "results" / "report.html", full_calibration(truth), load_detections(session))
    failed, requests, errors = [], [], []
    page = browser.new_page()
    try:
        page.set_viewport_size({"width": 1280, "height": 900})
        page.on("requestfailed", lambda r: failed.append(r.url[:80]))
        page.on("request", lambda r: requests.append(r.url[:80]))
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto(out.resolve().as_uri(), wait_until="load", timeout=20_000)
        assert page.title() == "sonarcal report: report-test"
        stats = page.evaluate("""() => {
            const imgs = [...document.images];
            return {n: imgs.length, decoded: imgs.filter(i => i.complete && i.naturalWidth > 0).length,
                    svgs: document.querySelectorAll('svg').length,
                    h2: [...document.querySelectorAll('h2')].map(h => h.textContent),
                    height: document.body.scrollHeight};
        }""")
        shot = tmp_path / "report.png"
        page.screenshot(path=str(shot), full_page=False)
    finally:
        page.close()
    assert not failed and not errors
    assert all(u.startswith(("file:", "data:")) for u in requests)  # nothing leaves the machine
    assert stats["n"] == 12 and stats["decoded"] == stats["n"]
    assert stats["svgs"] >= 8 and stats["height"] > 2000
    assert any("Table I" in h for h in stats["h2"]) and any("Fig. 3" in h for h in stats["h2"])
    assert shot.stat().st_size > 10_000
