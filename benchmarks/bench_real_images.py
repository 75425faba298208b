"""Image detection on real photographs against hand-checked centres (issue 11).

Data: ``../shared/data/kinectnet-dev`` (three Kinect colour cameras, 640x480, a 0.406 m ball
on a stick in a cluttered lab, no background frames) with the reference of
``benchmarks/data/kinectnet_centres.yaml`` (how it was made: ``benchmarks/data/README.md``).
Skips when the data set is absent.

Per camera: recall within 3 px over the images that show the whole ball, false detections
(found but > 3 px off, or found where the ball is cut/absent), misses with their reasons,
and the centre error of the hits. With ``--list`` it prints every image.

With ``--solve`` it also runs the whole session flow (detection with the sonar-guided second
look, then ``calibrate_session``) and reports, per camera, the detections within 3 px after
the flow, the false ones and whether the solve used any of them, and k1's pose against the
identity (the README's rough outside check: within ~1 deg and 150 mm).

Run: .venv/bin/python benchmarks/bench_real_images.py [--session DIR] [--list] [--solve]
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

from calib_core.detect.image.detect import detect_sphere_in_image  # noqa: E402
from calib_core.detect.image.score import reliability_table  # noqa: E402
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


def solve_check(session_dir: Path) -> None:
    from scipy.spatial.transform import Rotation

    from calib_core import pipeline
    from calib_core.solve.calibrate import calibrate_session

    ses = load_session(session_dir)
    ref = yaml.safe_load(REFERENCE.read_text())
    t0 = time.perf_counter()
    dets = pipeline.detect_session(ses, {})
    cal = calibrate_session(ses, dets, {"detect": False})
    print(f"\nWhole session flow (detect + calibrate, {time.perf_counter() - t0:.0f} s)")
    print("| camera | within 3 px after the flow | false detections | false ones used in the solve "
          "| captures used | rotation from identity (deg) | |t| (mm) |")
    print("|---|---|---|---|---|---|---|")
    for cam in sorted(ses.cameras):
        c = cal["cameras"].get(cam)
        hit, false, used_false = 0, [], []
        used = set()
        if c:
            used = {r["capture"] for r in c.get("residuals", []) if r.get("used")}
        whole = sum(ref[cam][k]["flag"] == "whole" for k in ref[cam])
        for cid, d in dets.items():
            e = d.get(cam) or {}
            if e.get("center") is None:
                continue
            r = ref[cam][cid]
            err = float(np.hypot(*(np.asarray(e["center"]) - r["centre_uv_px"])))
            if r["flag"] == "whole" and err <= TOL_PX:
                hit += 1
            else:
                false.append(f"{cid} ({err:.0f} px)")
                if cid in used:
                    used_false.append(cid)
        if c:
            T = np.asarray(c["T_cam_sonar"], float)
            ang = np.degrees(np.linalg.norm(Rotation.from_matrix(T[:3, :3]).as_rotvec()))
            pose = f"{ang:.2f} | {1e3 * np.linalg.norm(T[:3, 3]):.0f}"
        else:
            pose = "not calibrated | -"
        print(f"| {cam} | {hit}/{whole} | {', '.join(false) or '-'} | {', '.join(used_false) or 'none'} "
              f"| {len(used)} | {pose} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--session")
    ap.add_argument("--list", action="store_true")
    ap.add_argument("--solve", action="store_true")
    a = ap.parse_args(argv)
    d = _find_session(a.session)
    if d is None:
        print("kinectnet-dev not found: skipped")
        return 0
    rows = run(d, a.list)
    print_table(rows)
    print(reliability_table([x for st in rows.values() for x in st["scores"]],
                            "Reliability of the detection score on kinectnet (right = whole ball, within 3 px)"))
    print("load average:", Path("/proc/loadavg").read_text().split()[:3])
    if a.solve:
        solve_check(d)
    return 0


if __name__ == "__main__":
    sys.exit(main())
