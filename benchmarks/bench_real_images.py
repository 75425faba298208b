"""Image detection on real photographs against hand-checked centres (issue 11).

Data: ``../shared/data/kinectnet-dev`` (three Kinect colour cameras, 640x480, a 0.406 m ball
on a stick in a cluttered lab, no background frames) with the reference of
``benchmarks/data/kinectnet_centres.yaml`` (how it was made: ``benchmarks/data/README.md``).
Skips when the data set is absent.

Per camera: recall within 3 px over the images that show the whole ball, false detections
(found but > 3 px off, or found where the ball is cut/absent), misses with their reasons,
and the centre error of the hits. With ``--list`` it prints every image.

Run: .venv/bin/python benchmarks/bench_real_images.py [--session DIR] [--list]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from calib_core.detect.image import detect_sphere_in_image  # noqa: E402
from calib_core.io.images import load_image  # noqa: E402
from calib_core.session import load_session  # noqa: E402

DEFAULT_SESSION = ROOT.parent.parent / "shared" / "data" / "kinectnet-dev"
REFERENCE = ROOT / "benchmarks" / "data" / "kinectnet_centres.yaml"
TOL_PX = 3.0


def reason_class(reason: str) -> str:
    """A refusal's kind without its numbers and places (for counting)."""
    r = reason.split(" at (")[0].split(":")[0]
    return "".join(ch if not ch.isdigit() and ch != "." else "" for ch in r).replace("  ", " ").strip()


def _find_session(arg: str | None) -> Path | None:
    for p in ([Path(arg)] if arg else [DEFAULT_SESSION, Path("/work/shared/data/kinectnet-dev")]):
        if (p / "session.yaml").is_file():
            return p
    return None


def run(session_dir: Path, listing: bool = False) -> dict:
    ses = load_session(session_dir)
    ref = yaml.safe_load(REFERENCE.read_text())
    rows = {}
    for cam in sorted(ses.cameras):
        model = ses.camera_model(cam)
        st = {"whole": 0, "hit": 0, "false": 0, "errs": [], "miss": Counter(), "ms": [], "scores": []}
        for cap in ses.captures:
            r = ref[cam][cap.id]
            img = load_image(cap.image_paths[cam])
            t0 = time.perf_counter()
            det = detect_sphere_in_image(img, model, ses.sphere_radius_m)
            st["ms"].append(1e3 * (time.perf_counter() - t0))
            err = (float(np.hypot(*(np.asarray(det.center_uv_px) - r["centre_uv_px"])))
                   if det.found and r.get("centre_uv_px") else None)
            whole = r["flag"] == "whole"
            st["whole"] += whole
            if det.found:
                st["scores"].append((det.score, err is not None and err <= TOL_PX and whole))
            if whole and det.found and err <= TOL_PX:
                st["hit"] += 1
                st["errs"].append(err)
            elif det.found:
                st["false"] += 1
            elif whole:
                st["miss"][reason_class(det.reason)] += 1
            if listing:
                e = f"{err:7.2f}" if err is not None else "      -"
                print(f"{cam} {cap.id} {r['flag']:6s} found={det.found!s:5s} err={e} "
                      f"score={det.score:.2f} {det.reason}")
        rows[cam] = st
    return rows


def print_table(rows: dict) -> None:
    print(f"| camera | whole-ball images | within {TOL_PX:.0f} px | recall | false detections "
          "| median / max err (px) | ms/image (median) | misses (reason: count) |")
    print("|---|---|---|---|---|---|---|---|")
    tot = Counter()
    for cam, st in rows.items():
        errs = np.array(st["errs"]) if st["errs"] else np.array([np.nan])
        miss = ", ".join(f"{k}: {v}" for k, v in st["miss"].most_common()) or "-"
        print(f"| {cam} | {st['whole']} | {st['hit']} | {100 * st['hit'] / max(st['whole'], 1):.0f} % "
              f"| {st['false']} | {np.nanmedian(errs):.2f} / {np.nanmax(errs):.2f} "
              f"| {np.median(st['ms']):.1f} | {miss} |")
        tot.update({"whole": st["whole"], "hit": st["hit"], "false": st["false"]})
    print(f"| all | {tot['whole']} | {tot['hit']} | {100 * tot['hit'] / max(tot['whole'], 1):.0f} % "
          f"| {tot['false']} | | | |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--session")
    ap.add_argument("--list", action="store_true")
    a = ap.parse_args(argv)
    d = _find_session(a.session)
    if d is None:
        print("kinectnet-dev not found: skipped")
        return 0
    rows = run(d, a.list)
    print_table(rows)
    print("load average:", Path("/proc/loadavg").read_text().split()[:3])
    return 0


if __name__ == "__main__":
    sys.exit(main())
