"""The workbench's Origin and token checks in real Chromium (Debian's, via Playwright).

The full URL the server prints opens the workbench (the token cookie carries over to the
page's websocket); the bare URL is refused; a page of another origin, open in the same
browser after the workbench's cookie was set, can neither connect a websocket nor read
the page.
"""

from __future__ import annotations

import http.server
import threading

import pytest

from test_app_state import make_session

pytestmark = pytest.mark.browser

EVIL_JS = """async (target) => {
    const result = {opened: false, messages: 0, fetched: null};
    await new Promise((done) => {
        let ws;
        try { ws = new WebSocket(target.ws, [target.proto]); } catch (e) { return done(); }
        ws.onopen = () => { result.opened = true; };
        ws.onmessage = () => { result.messages += 1; };
        ws.onerror = () => done();
        ws.onclose = () => done();
        setTimeout(done, 4000);
    });
    try {
        const r = await fetch(target.page, {credentials: "include"});
        result.fetched = await r.text();
    } catch (e) { result.fetched = "blocked"; }
    return result;
}"""


class _Evil(http.server.BaseHTTPRequestHandler):
    def do_GET(self):  # noqa: N802
        body = b"<html><body>evil page</body></html>"
        self.send_response(200)
        self.send_header("Content-Type", "text/html")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, *a):
        pass


def test_token_and_origin_in_chromium(tmp_path, browser):
    import viser

    from app.server import Workbench

    wb = Workbench(make_session(tmp_path / "s"), port=0, uploads_dir=tmp_path / "uploads")
    evil = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Evil)
    threading.Thread(target=evil.serve_forever, daemon=True).start()
    connected = []
    wb.server.on_client_connect(lambda c: connected.append(c.client_id))
    page = browser.new_page()
    other = browser.new_page()
    try:
        bare = page.goto(f"http://127.0.0.1:{wb.port}/")
        assert bare.status == 403 and "token" in page.content()
        assert not connected
        page.goto(wb.url)  # the printed URL: the page loads and its websocket connects
        page.get_by_text("sonarcal workbench", exact=False).first.wait_for()
        assert len(connected) == 1
        cookies = [c for c in browser.cookies() if c["name"].startswith(f"sonarcal_token_{wb.port}")]
        assert cookies and cookies[0]["httpOnly"] and cookies[0]["sameSite"] == "Strict"
        refused_before = wb.guard.refused
        # another site, open in the same browser that holds the workbench's cookie
        other.goto(f"http://localhost:{evil.server_address[1]}/")
        got = other.evaluate(EVIL_JS, {"ws": f"ws://127.0.0.1:{wb.port}/", "proto": f"viser-v{viser.__version__}",
                                       "page": f"http://127.0.0.1:{wb.port}/"})
        assert got["opened"] is False and got["messages"] == 0
        assert got["fetched"] == "blocked" or "sonarcal" not in (got["fetched"] or "").lower() or \
            "token" in got["fetched"]
        assert len(connected) == 1 and wb.guard.refused > refused_before
    finally:
        page.close()
        other.close()
        evil.shutdown()
        wb.stop()


def test_script_in_session_fields_stays_text_in_chromium(tmp_path, browser):
    import yaml

    from app.server import Workbench

    xss = '<iframe srcdoc="<script>parent.document.title=1</script>"></iframe>'
    root = make_session(tmp_path / "s")
    manifest = yaml.safe_load((root / "session.yaml").read_text())
    manifest["name"] = "Sitzung über Wasser " + xss
    manifest["captures"][0]["id"] = "<img src=x onerror=alert(1)>"
    (root / "session.yaml").write_text(yaml.safe_dump(manifest, allow_unicode=True))
    (root / "detections.yaml").unlink(missing_ok=True)
    wb = Workbench(root, port=0, uploads_dir=tmp_path / "uploads")
    page = browser.new_page()
    try:
        dialogs = []
        page.on("dialog", lambda d: (dialogs.append(d.message), d.dismiss()))
        page.goto(wb.url)
        page.get_by_text("Sitzung über Wasser", exact=False).first.wait_for()
        page.get_by_text("<iframe srcdoc=", exact=False).first.wait_for()  # shown as text
        assert page.evaluate("document.querySelectorAll('iframe').length") == 0
        assert page.evaluate("document.querySelectorAll('img[src=\"x\"]').length") == 0
        assert not dialogs and page.title() != "1"
    finally:
        page.close()
        wb.stop()
