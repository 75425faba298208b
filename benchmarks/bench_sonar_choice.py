"""Session-level choice between sonar candidates ("two candidates"), measured on sweep sessions.

Runs :func:`calib_core.pipeline.detect_session` (as ``sonarcal detect`` does) on the sweep
sessions of ``bench_detection_range.py --sweep`` whose per-capture detection refused clouds
as "two candidates" (seabed s49, seabed-slab s51 and s60, clutter s57 at scale 0.5; generated
into ``--cache`` when missing, images blank: the range side never reads them, so the image cue
has nothing to work with here and only the static-scenery cue can decide). Per session: the
captures with the target, those refused per capture (before), those the session-level choice
settled (and whether the centre is within 2 cm of the truth: right / wrong), and those still
refused (after).

    .venv/bin/python benchmarks/bench_sonar_choice.py [--cache /tmp/sonar2/sweep] [--workers 1]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_detection_range import _sweep_session  # noqa: E402

from calib_core.pipeline import detect_session  # noqa: E402
from calib_core.session import load_session  # noqa: E402
from calib_core.synth.ground_truth import load_ground_truth  # noqa: E402

SESSIONS = (("seabed", 49), ("seabed-slab", 60), ("seabed-slab", 51), ("clutter", 57))
RIGHT_M = 0.02


def one(root: Path, workers: int) -> dict:
    """Counts for one session."""
    gt = load_ground_truth(root)
    dets = detect_session(load_session(root), {}, workers=workers)
    out = {"n": 0, "before": 0, "right": 0, "wrong": 0, "after": 0, "why": []}
    for cid, c in gt["captures"].items():
        if not c.get("target"):
            continue
        e = dets.get(cid, {}).get("sonar", {})
        out["n"] += 1
        if e.get("resolved_by"):
            out["before"] += 1
            err = np.linalg.norm(np.asarray(e["center"], float) - np.asarray(c["center_sonar_m"], float))
            out["right" if err <= RIGHT_M else "wrong"] += 1
            out["why"].append(f"  {cid}: {err * 1000:.1f} mm, {e['resolved_by']}")
        elif e.get("center") is None:
            out["before"] += 1
            out["after"] += 1
            out["why"].append(f"  {cid}: still refused: {e.get('reason', '?')[:110]}")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", type=Path, default=Path("/tmp/sonar2/sweep"))
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--workers", type=int, default=1)
    args = ap.parse_args(argv)
    print(f"{'session':18} {'captures':>8} {'refused before':>14} {'settled right':>13} {'wrong':>5} "
          f"{'refused after':>13} {'s':>5}")
    tot = dict.fromkeys(("n", "before", "right", "wrong", "after"), 0)
    notes = []
    for preset, seed in SESSIONS:
        t0 = time.perf_counter()
        r = one(_sweep_session(args.cache, preset, seed, args.scale), args.workers)
        for k in tot:
            tot[k] += r[k]
        notes += [f"{preset} s{seed}:"] + r["why"]
        print(f"{preset + ' s' + str(seed):18} {r['n']:8d} {r['before']:14d} {r['right']:13d} {r['wrong']:5d} "
              f"{r['after']:13d} {time.perf_counter() - t0:5.0f}")
    print(f"{'total':18} {tot['n']:8d} {tot['before']:14d} {tot['right']:13d} {tot['wrong']:5d} {tot['after']:13d}")
    print("\n".join(notes))
    return 0


if __name__ == "__main__":
    sys.exit(main())
