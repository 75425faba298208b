"""The HTML report renders in real headless Chromium: title, decoded images, SVG plots, no requests fail."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

from test_report import full_calibration, make_scene_session  # noqa: E402

from calib_core.detections import load_detections  # noqa: E402
from calib_core.report import write_report  # noqa: E402
from calib_core.session import load_session  # noqa: E402

pytestmark = pytest.mark.browser

ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
        "--disable-component-update", "--disable-sync"]


@pytest.mark.skipif(shutil.which("chromium") is None, reason="Debian chromium is not installed")
def test_report_renders_in_chromium(tmp_path):
    playwright = pytest.importorskip("playwright.sync_api")
    root = tmp_path / "session"
    truth = make_scene_session(root)
    session = load_session(root)
    out = write_report(session, root / "results" / "report.html", full_calibration(truth), load_detections(session))
    failed, requests, errors = [], [], []
    with playwright.sync_playwright() as p:
        ctx = p.chromium.launch_persistent_context(str(tmp_path / "profile"), executable_path=shutil.which("chromium"),
                                                   headless=True, args=ARGS, viewport={"width": 1280, "height": 900})
        try:
            page = ctx.new_page()
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
            ctx.close()
    assert not failed and not errors
    assert all(u.startswith(("file:", "data:")) for u in requests)  # nothing leaves the machine
    assert stats["n"] == 12 and stats["decoded"] == stats["n"]
    assert stats["svgs"] >= 8 and stats["height"] > 2000
    assert any("Table I" in h for h in stats["h2"]) and any("Fig. 3" in h for h in stats["h2"])
    assert shot.stat().st_size > 10_000
