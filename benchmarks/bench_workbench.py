"""Workbench benchmark: session load, correction -> overlays (1M points at 1080p), memory,
and a load test (10 websocket clients clicking for ~1 minute while one of them solves).

    .venv/bin/python benchmarks/bench_workbench.py [--load-seconds 60] [--clients 10]

Everything runs in-process on 127.0.0.1 (loopback only) on copies in a temp folder; the
sample session in the repo is never written. Times are server-side wall clock: from the
action (a correction, a click message arriving) until every display refresh it caused has
been applied to the shared scene/GUI (queued to the clients).
"""

from __future__ import annotations

import argparse
import json
import random
import shutil
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import psutil

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.server import Workbench  # noqa: E402
from calib_core.results import CALIBRATION_FORMAT  # noqa: E402

PROC = psutil.Process()
TARGETS = {"session load, cold start: review table ready (s)": 3.0, "session load in a running server (s)": 3.0,
           "correction -> overlays (ms)": 150.0}


def rss_mb() -> float:
    return PROC.memory_info().rss / 2**20


def sample_session(tmp: Path, name: str) -> Path:
    src = ROOT / "sample_sessions" / name
    dst = tmp / name
    if src.is_dir():
        shutil.copytree(src, dst)
        for stale in ("detections.yaml", "results"):
            p = dst / stale
            shutil.rmtree(p) if p.is_dir() else p.unlink(missing_ok=True)
        return dst
    from calib_core.synth.generate import generate_session

    return generate_session(dst, name, 1)


def gt_calibration(wb) -> dict:
    """A calibration dict with the ground-truth poses (display benchmark; the solver is benchmarked elsewhere)."""
    gt = wb.state.ground_truth
    return {"format": CALIBRATION_FORMAT, "cameras": {c: {"T_cam_sonar": v["T_cam_sonar"].tolist()
                                                          if hasattr(v["T_cam_sonar"], "tolist") else v["T_cam_sonar"]}
                                                      for c, v in gt["cameras"].items()},
            "range_scale": {"value": float(gt.get("range_scale", 1.0))}}


def _wait(cond, timeout: float) -> None:
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise TimeoutError("benchmark condition not reached")
        time.sleep(0.002)


def bench_load(tmp: Path) -> dict:
    """Open the sample in a new Workbench with a page (a websocket client) connecting at once, as
    `sonarcal serve` and a browser do; times from the start of Workbench():

    - review table ready: the review table filled in the shared GUI (what the page needs to be
      usable; the browser's own drawing comes on top, see bench_workbench_browser.py);
    - images and clouds: every display refresh done (they follow the page's panel);
    - detections done: the automatic detection (started 1 s after the page connects) finished."""
    root = sample_session(tmp, "canal")
    r0 = rss_mb()
    t0 = time.perf_counter()
    wb = Workbench(root, port=0)
    page = WsClient(wb.url)
    page.start()
    _wait(lambda: "Captures (worst first)" in wb.review.table.content, 120)
    t_table = time.perf_counter() - t0
    wb.refresher.wait_idle(120)
    t_display = time.perf_counter() - t0
    wb.wait_idle(600)
    t_detect = time.perf_counter() - t0
    page.close()
    again = sample_session(tmp / "again", "canal")
    t0 = time.perf_counter()
    wb.open_session(again)  # what the browser's "Open folder" does
    wb.refresher.wait_idle(120)
    t_reopen = time.perf_counter() - t0
    wb.wait_idle(600)
    wb.open_session(root)
    wb.wait_idle(600)
    return {"session load, cold start: review table ready (s)": t_table,
            "session load, cold start: images and clouds shown (s)": t_display,
            "session load, cold start: automatic detection done (s)": t_detect,
            "session load in a running server (s)": t_reopen,
            "RSS after load (MB)": rss_mb(), "RSS before (MB)": r0, "root": root, "wb": wb}


def bench_overlay(wb, n_points: int = 1_000_000, repeats: int = 10) -> dict:
    """Replace p01's cloud by a 1M-point one (the session's points, jittered), then time corrections."""
    from calib_core.io.clouds import Cloud, save_cloud

    st = wb.state
    pts = np.concatenate([st.cloud(c.id).points_m for c in st.session.captures])
    rng = np.random.default_rng(0)
    big = pts[rng.integers(0, len(pts), n_points)] + rng.normal(0, 0.01, (n_points, 3))
    save_cloud(st.session.capture("p01").cloud_path, Cloud(big, None))
    with st.lock:
        st._clouds.clear()
    st.set_calibration(gt_calibration(wb))
    wb.images.refit.value = False
    wb.images.mask_radius.value = 3
    st.select("p02")
    wb.wait_idle(120)
    t0 = time.perf_counter()
    st.select("p01")
    wb.wait_idle(120)
    t_switch = time.perf_counter() - t0  # loads 1M points, projects them, builds masks, sends the cloud
    e = st.entry("p01", "cam1") or {}
    uv0 = np.asarray(e.get("center") or (960.0, 540.0), float)
    times, render = [], []
    for k in range(repeats):
        uv = uv0 + [k % 3, -(k % 2)]
        t0 = time.perf_counter()
        wb.images.correct_click("p01", "cam1", uv, "bench")
        wb.wait_idle(60)
        times.append(time.perf_counter() - t0)
        t1 = time.perf_counter()
        wb.images.render("p01", "cam1")
        render.append(time.perf_counter() - t1)
    wb.images.refit.value = True
    t0 = time.perf_counter()
    wb.images.correct_click("p01", "cam1", uv0, "bench")
    wb.wait_idle(60)
    t_refit = time.perf_counter() - t0
    t0 = time.perf_counter()
    wb.images.mask_radius.value = 5
    wb.wait_idle(60)
    t_radius = time.perf_counter() - t0
    return {"correction -> overlays (ms)": 1000 * statistics.median(times),
            "correction -> overlays, max (ms)": 1000 * max(times),
            "full-res overlay image, one camera (ms, not on the update path)": 1000 * statistics.median(render),
            "correction with refit -> overlays (ms)": 1000 * t_refit,
            "mask radius change, 1M points reprojected (ms)": 1000 * t_radius,
            "select 1M-point capture (ms)": 1000 * t_switch,
            "RSS with 1M-point cloud (MB)": rss_mb()}


class WsClient(threading.Thread):
    """A websocket client speaking viser's protocol: drains updates, clicks buttons."""

    def __init__(self, url: str):
        super().__init__(daemon=True)
        import viser
        from websockets.sync.client import connect

        self.ws = connect(url.replace("http", "ws"), subprotocols=[f"viser-v{viser.__version__}"], max_size=None,
                          open_timeout=30)
        self.bytes = 0
        self.stop = False
        import msgspec

        # viser counts a connection as a client once it reports its viewpoint
        self.ws.send(msgspec.msgpack.encode({
            "type": "ViewerCameraMessage", "wxyz": [1.0, 0.0, 0.0, 0.0], "position": [-3.0, 0.0, 1.0], "fov": 1.0,
            "near": 0.01, "far": 100.0, "image_height": 720, "image_width": 1280, "look_at": [0.0, 0.0, 0.0],
            "up_direction": [0.0, 0.0, 1.0]}))

    def run(self):
        while not self.stop:
            try:
                self.bytes += len(self.ws.recv(timeout=0.5))
            except TimeoutError:
                continue
            except Exception:
                return

    def click(self, handle) -> None:
        import msgspec

        self.ws.send(msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": handle._impl.uuid,
                                             "updates": {"value": True}}))

    def set(self, handle, value) -> None:
        import msgspec

        self.ws.send(msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": handle._impl.uuid,
                                             "updates": {"value": value}}))

    def close(self):
        self.stop = True
        try:
            self.ws.close()
        except Exception:
            pass


def bench_load_test(tmp: Path, n_clients: int, seconds: float) -> dict:
    root = sample_session(tmp, "quick")
    wb = Workbench(root, port=0)
    wb.wait_idle(600)
    clients = [WsClient(wb.url) for _ in range(n_clients)]
    for c in clients:
        c.start()
    rev = wb.review
    rss = [rss_mb()]
    lat = []
    rng = random.Random(0)
    solved_at = None
    t_end = time.monotonic() + seconds
    t_start = time.monotonic()
    solve_started = False
    while time.monotonic() < t_end:
        if not solve_started and time.monotonic() - t_start > 3:
            clients[0].click(wb.solve.button)  # one client solves (worker thread) while the others work
            solve_started = True
        for c in clients[:-1]:  # edits and view changes; only the probe navigates
            if rng.random() < 0.7:
                c.click(rng.choice([rev.accept, rev.undo, rev.reject, rev.undo]))
            else:
                c.set(wb.images.mask_opacity, round(rng.uniform(0.2, 0.8), 2))
        # probe: a click from the last client on "Next"; time until the server has selected
        # the next capture and refreshed every display
        before = wb.state.selected
        t0 = time.perf_counter()
        clients[-1].click(rev.next)
        while wb.state.selected == before and time.perf_counter() - t0 < 10:
            time.sleep(0.002)
        wb.refresher.wait_idle(10)
        lat.append(time.perf_counter() - t0)
        if solve_started and solved_at is None and wb.state.calibration is not None:
            solved_at = time.monotonic() - t_start
        rss.append(rss_mb())
        time.sleep(0.5)
    wb.wait_idle(120)
    from calib_core.detections import load_detections
    from calib_core.session import load_session

    consistent = load_detections(load_session(root)) == wb.state.detections
    received = sum(c.bytes for c in clients)
    for c in clients:
        c.close()
    wb.stop()
    lat.sort()
    return {"load: clients": n_clients, "load: duration (s)": seconds,
            "load: probe clicks": len(lat),
            "load: click -> refreshed, median (ms)": 1000 * statistics.median(lat),
            "load: click -> refreshed, p95 (ms)": 1000 * lat[int(0.95 * (len(lat) - 1))],
            "load: click -> refreshed, max (ms)": 1000 * lat[-1],
            "load: solve finished at (s)": solved_at if solved_at is not None else float("nan"),
            "load: RSS start / peak / end (MB)": f"{rss[0]:.0f} / {max(rss):.0f} / {rss[-1]:.0f}",
            "load: MB sent to clients": received / 2**20,
            "load: detections.yaml == server state": consistent}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--load-seconds", type=float, default=60.0)
    ap.add_argument("--clients", type=int, default=10)
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--json", help="also write the results here")
    ap.add_argument("--no-load-test", action="store_true", help="skip the 10-client load test")
    a = ap.parse_args()
    rows = {}
    with tempfile.TemporaryDirectory(prefix="bench-wb-") as tmp:
        tmp = Path(tmp)
        load = bench_load(tmp)
        wb = load.pop("wb")
        load.pop("root")
        rows.update(load)
        rows.update(bench_overlay(wb, a.points))
        wb.stop()
        if not a.no_load_test:
            rows.update(bench_load_test(tmp, a.clients, a.load_seconds))
    from rich.console import Console
    from rich.table import Table

    load_avg = " ".join(open("/proc/loadavg").read().split()[:3])
    t = Table(title=f"bench_workbench (server side, 127.0.0.1); load average at the end {load_avg}")
    for col in ("measure", "value", "target", "met"):
        t.add_column(col)
    for k, v in rows.items():
        target = TARGETS.get(k)
        val = f"{v:.1f}" if isinstance(v, float) else str(v)
        met = "" if target is None else ("yes" if v < target else "NO")
        t.add_row(k, val, "" if target is None else f"< {target:g}", met)
    Console().print(t)
    if a.json:
        Path(a.json).write_text(json.dumps({k: (v if isinstance(v, (int, float, str, bool)) else str(v))
                                            for k, v in rows.items()}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
