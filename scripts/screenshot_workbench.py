"""Regenerate docs/workbench.png from what the workbench shows, in Debian's Chromium.

    .venv/bin/python scripts/screenshot_workbench.py [--session sample_sessions/canal] [--out docs/workbench.png]

Opens a copy of the session (the repo's copy is never written), waits for the automatic
detection and the flags, runs one Solve from the page, frames the selected capture and saves
a 1600x1000 screenshot.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "browser"))

from browser_util import chromium, only_client, wait_for  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--session", default=str(ROOT / "sample_sessions" / "canal"))
    ap.add_argument("--out", default=str(ROOT / "docs" / "workbench.png"))
    args = ap.parse_args()
    from app.server import Workbench

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "session"
        shutil.copytree(args.session, root)
        for stale in ("detections.yaml", "results"):
            p = root / stale
            shutil.rmtree(p) if p.is_dir() else p.unlink(missing_ok=True)
        wb = Workbench(root, port=0)
        try:
            with chromium(1600, 1000) as ctx:
                page = ctx.new_page()
                page.goto(wb.url)
                page.get_by_text("Captures (worst first)").wait_for()
                only_client(wb)
                wb.wait_idle(600)
                page.get_by_role("button", name="Solve", exact=True).click()
                wait_for(lambda: (root / "results" / "calibration.json").exists(), 300, "a calibration")
                wb.wait_idle(300)
                time.sleep(3.0)  # software WebGL: let the frames settle
                page.screenshot(path=args.out)
        finally:
            wb.stop()
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
