"""Workbench speed as an operator sees it, in real Chromium (headless, software WebGL).

    .venv/bin/python benchmarks/bench_workbench_browser.py [--session canal] [--clicks 8]

- load -> interactive: from starting ``sonarcal serve`` (a new process) until the page shows
  the review table with its buttons (detection still running behind the progress bar); the
  median of ``--loads`` starts, each on a fresh copy; then until the image panel has the
  selected capture's image (images and clouds follow the panel);
- Solve: from the click on Solve until results/calibration.json is rewritten and the page
  shows the new pose;
- click -> overlay: from the release of a click on an image board (refit off) until the page
  has received the updated board image (websocket frame seen by Playwright), and until the
  page's next animation frame after it.

Runs on a copy of the sample session (the repo's copy is never written). Needs Debian's
chromium; prints a table. Timing depends on the machine's load: see /proc/loadavg.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "browser"))

from browser_util import FrameLog, board_point_world, canvas_box, chromium, only_client, screen_of, wait_for  # noqa: E402

TARGETS = {"load -> interactive (s)": 3.0, "Solve (s)": 1.5, "click -> overlay (ms)": 150.0}


def fresh_copy(tmp: Path, name: str) -> Path:
    src = ROOT / "sample_sessions" / name
    dst = tmp / name
    shutil.copytree(src, dst)
    for stale in ("detections.yaml", "results"):
        p = dst / stale
        shutil.rmtree(p) if p.is_dir() else p.unlink(missing_ok=True)
    return dst


def serve_url(root: Path, t0: float):
    """Start `sonarcal serve` on ``root`` in a new process; (process, URL) once the URL is printed."""
    proc = subprocess.Popen([str(ROOT / ".venv" / "bin" / "python"), "-m", "sonarcal_cli.main", "serve", str(root),
                             "--port", "0"], cwd=str(ROOT), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin", "COLUMNS": "200"})
    for line in proc.stdout:
        m = re.search(r"(http://[^\s]+)", line)
        if m and "open" in line:
            return proc, m.group(1)
    proc.wait(20)
    raise RuntimeError(f"sonarcal serve exited ({proc.returncode}) without printing a URL")


def load_once(ctx, root: Path) -> dict:
    """One start: times from starting `sonarcal serve` (s)."""
    t0 = time.perf_counter()
    proc, url = serve_url(root, t0)
    try:
        t_url = time.perf_counter() - t0
        page = ctx.new_page()
        opened = []
        page.on("websocket", lambda ws: opened.append(time.perf_counter() - t0))
        page.goto(url)
        page.get_by_text("Captures (worst first)").wait_for(timeout=60_000)
        page.get_by_role("button", name="Reject", exact=True).wait_for()
        t_ready = time.perf_counter() - t0
        page.get_by_text(re.compile(r"cam1: \S+")).first.wait_for(timeout=60_000)  # the image panel's label
        t_images = time.perf_counter() - t0
        try:  # detection starts 1 s after the page connects, behind the progress bar
            page.get_by_text(re.compile(r"detection:")).first.wait_for(timeout=30_000)
            progress = True
        except Exception:
            progress = False
        page.close()
        return {"url": t_url, "ws": opened[0] if opened else float("nan"), "ready": t_ready, "images": t_images,
                "progress": progress}
    finally:
        stop(proc)


def stop(proc) -> None:
    """Stop a `sonarcal serve` (it finishes a running detection first; killed after 60 s)."""
    proc.terminate()
    try:
        proc.wait(60)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(10)


def bench_load(ctx, tmp: Path, name: str, n: int) -> dict:
    """``n`` starts of `sonarcal serve` on fresh copies; the page opened as soon as the URL is printed."""
    runs = [load_once(ctx, fresh_copy(tmp / f"load{k}", name)) for k in range(n)]
    med = {k: statistics.median(r[k] for r in runs) for k in ("url", "ws", "ready", "images")}
    return {"url printed (s)": med["url"], "page websocket open (s)": med["ws"],
            "load -> interactive (s)": med["ready"],
            "load -> interactive, each (s)": ", ".join(f"{r['ready']:.2f}" for r in runs),
            "detection behind a progress bar": all(r["progress"] for r in runs),
            "load -> images shown (s)": med["images"]}


def bench_solve(ctx, wb, repeats: int = 2) -> dict:
    before = set(wb.server.get_clients())
    page = ctx.new_page()
    page.goto(wb.url)
    page.get_by_text("Captures (worst first)").wait_for()
    only_client(wb, before)
    wb.wait_idle(600)
    cal_path = wb.state.session.root / "results" / "calibration.json"
    times, saved = [], []
    page.get_by_role("tab", name="Solve", exact=True).click()  # where the result shows
    for k in range(repeats):
        old = cal_path.read_text() if cal_path.exists() else None
        t0 = time.perf_counter()
        page.get_by_role("button", name="Solve", exact=True).click()
        wait_for(lambda: cal_path.exists() and cal_path.read_text() != old, 120, "calibration", poll=0.01)
        saved.append(time.perf_counter() - t0)
        cal = json.loads(cal_path.read_text())
        t_mm = " ".join(f"{v:.1f}" for v in 1000 * np.asarray(cal["cameras"]["cam1"]["T_cam_sonar"])[:3, 3])
        wait_for(lambda: t_mm in page.locator("body").inner_text(), 60, "the pose in the page", poll=0.02)
        times.append(time.perf_counter() - t0)
        wb.wait_idle(60)
        if k == 0:  # the second Solve follows a correction, as in the review loop
            cid = wb.state.session.captures[1].id
            wb.state.set_status(cid, "rejected", "bench")
            wb.wait_idle(60)
    page.close()
    return {"Solve (s)": statistics.median(times), "Solve, each: saved / shown (s)":
            ", ".join(f"{a:.2f} / {b:.2f}" for a, b in zip(saved, times))}


def bench_click(ctx, wb, n: int) -> dict:
    before = set(wb.server.get_clients())
    page = ctx.new_page()
    log = FrameLog(page)
    page.goto(wb.url)
    page.get_by_text("Captures (worst first)").wait_for()
    client = only_client(wb, before)
    wb.wait_idle(600)
    page.get_by_role("checkbox", name="Refit near a click").uncheck()
    wait_for(lambda: not wb.images.refit.value, 10, "refit off")
    fov = client.camera.fov
    page.get_by_role("button", name="View through cam1").click()
    wait_for(lambda: abs(client.camera.fov - fov) > 1e-6, 20, "view through cam1")
    time.sleep(2.0)
    cid = wb.state.selected
    uv0 = np.asarray((wb.state.entry(cid, "cam1") or {}).get("center") or (960.0, 540.0), float)
    recv, drawn = [], []
    for k in range(n):
        x, y = screen_of(client, canvas_box(page), board_point_world(wb, "cam1", uv0 + [3.0 * (k % 3), 2.0 * k]))
        page.mouse.move(x, y)
        time.sleep(0.3)
        page.mouse.down()
        page.mouse.up()
        t0 = time.perf_counter()  # the click is complete (the board reports clicks on release)
        t1 = None
        while t1 is None and time.perf_counter() - t0 < 20:
            page.wait_for_timeout(2)  # lets Playwright deliver the frame events (sync API)
            t1 = log.first_big_after(t0)
        if t1 is None:
            raise AssertionError("no overlay arrived within 20 s of the click")
        page.evaluate("new Promise(r => requestAnimationFrame(() => r()))")  # the next frame drawn
        t2 = time.perf_counter()
        recv.append(1000 * (t1 - t0))
        drawn.append(1000 * (t2 - t0))
        wb.wait_idle(30)
        time.sleep(0.5)
    page.close()
    return {"click -> overlay (ms)": statistics.median(recv), "click -> overlay max (ms)": max(recv),
            "click -> overlay + frame (ms)": statistics.median(drawn)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--session", default="canal")
    ap.add_argument("--clicks", type=int, default=8)
    ap.add_argument("--loads", type=int, default=5, help="starts of `sonarcal serve` (the median is reported)")
    ap.add_argument("--load-only", action="store_true", help="measure only load -> interactive")
    args = ap.parse_args()
    from app.server import Workbench

    load = open("/proc/loadavg").read().split()[:3]
    rows = {}
    with tempfile.TemporaryDirectory() as tmp, chromium(1600, 1000) as ctx:
        tmp = Path(tmp)
        rows.update(bench_load(ctx, tmp, args.session, args.loads))
        if not args.load_only:
            wb = Workbench(fresh_copy(tmp / "solve", args.session), port=0)
            try:
                rows.update(bench_solve(ctx, wb))
                rows.update(bench_click(ctx, wb, args.clicks))
            finally:
                wb.stop()
    print(f"Workbench in Chromium, session {args.session} (1920x1080 images), viewport 1600x1000; "
          f"load average before: {' '.join(load)}, after: {' '.join(open('/proc/loadavg').read().split()[:3])}")
    for k, v in rows.items():
        val = f"{v:.2f}" if isinstance(v, float) and "(ms)" not in k else (f"{v:.0f}" if isinstance(v, float) else str(v))
        t = TARGETS.get(k)
        mark = "" if t is None else f"   target <= {t:g}   {'met' if v <= t else 'MISSED'}"
        print(f"  {k:32s} {val:>24s}{mark}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
