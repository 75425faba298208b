"""Range-side detection on held-out range sensors (calib_core.synth.range.heldout): a 128-ring
spinning LiDAR (Ouster-like), a solid-state rosette LiDAR (Livox-like) and an active-stereo depth
camera (RealSense-like), none of which the detector was developed against.

Single captures (calib_core.synth.range.capture) of every held-out sensor x holder, seeds
``--first`` .. ``--first + --captures - 1``; the beam width is estimated from 8 other captures
of the pair (seeds 0-7, as a session would, without being told the sensor). Per case: found
within ``--tol-mm`` of the truth ("right"), found farther ("WRONG"), refused (with reasons);
centre error of the right ones (bias = norm of the mean error, along = mean error along the line
of sight, + = too far; mm).

    .venv/bin/python benchmarks/bench_heldout_range.py [--captures 20] [--first 1000] [--tol-mm 20]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.bench_detection_range import _stats, _why  # noqa: E402
from calib_core.detect.sonar.detect import detect_sphere_in_cloud  # noqa: E402
from calib_core.detect.sonar.beam import estimate_beam_width_deg  # noqa: E402
from calib_core.synth.range.capture import HELDOUT, range_capture  # noqa: E402

HOLDERS = ("chair", "table", "stick", "hand")
TARGET_RECALL = 0.98


def one_case(sensor: str, holder: str, seeds, tol_m: float) -> tuple[dict, Counter, list]:
    r_est = 0.2
    est = estimate_beam_width_deg([range_capture(s, sensor, holder, radius_m=r_est)[0] for s in range(8)], r_est, 1.0)
    errs, along, why, wrong = [], [], Counter(), []
    for seed in seeds:
        P, c, r = range_capture(seed, sensor, holder)
        det = detect_sphere_in_cloud(P, r, est.beam_width_deg)
        if not det.found:
            why[_why(det.reason)] += 1
            continue
        e = det.center_sonar_m - c
        if np.linalg.norm(e) > tol_m:
            wrong.append(f"s{seed} {np.linalg.norm(e) * 1000:.0f} mm")
            continue
        errs.append(e)
        along.append(e @ c / np.linalg.norm(c))
    return {"width": est.beam_width_deg, **_stats(errs, len(seeds), along)}, why, wrong


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--captures", type=int, default=20, help="captures per sensor x holder")
    ap.add_argument("--first", type=int, default=1000, help="first seed")
    ap.add_argument("--tol-mm", type=float, default=20.0, help="a found centre farther than this is WRONG")
    ap.add_argument("--sensors", nargs="+", default=list(HELDOUT))
    a = ap.parse_args(argv)
    seeds = list(range(a.first, a.first + a.captures))
    t0 = time.perf_counter()
    print(f"Held-out range sensors, seeds {seeds[0]}-{seeds[-1]} per sensor x holder; width estimated from "
          f"8 other captures; right = within {a.tol_mm:g} mm (mm)")
    print(f"{'case':16} {'width deg':>9} {'right':>7} {'recall':>7} {'wrong':>5} {'refused':>7} "
          f"{'bias':>6} {'along':>6} {'RMS':>6} {'max':>6}")
    notes, n_all, right_all, wrong_all = [], 0, 0, 0
    for sensor in a.sensors:
        for holder in HOLDERS:
            st, why, wrong = one_case(sensor, holder, seeds, a.tol_mm / 1000)
            n_all, right_all, wrong_all = n_all + st["n"], right_all + st["found"], wrong_all + len(wrong)
            print(f"{sensor + ' ' + holder:16} {st['width']:9.3f} {st['found']:3d}/{st['n']:<3d} "
                  f"{st['found'] / st['n']:7.1%} {len(wrong):5d} {sum(why.values()):7d} {st['bias']:6.2f} "
                  f"{st['along']:6.2f} {st['rms']:6.2f} {st['max']:6.2f}")
            notes += [f"  {sensor} {holder}: {k} x {w}" for w, k in why.items()]
            notes += [f"  {sensor} {holder}: WRONG {w}" for w in wrong]
    print("refused or wrong:" if notes else "refused or wrong: none")
    print("\n".join(notes))
    recall = right_all / max(n_all, 1)
    print(f"target recall >= {TARGET_RECALL:.0%}: {recall:.1%} ({right_all}/{n_all}) -> "
          f"{'MET' if recall >= TARGET_RECALL else 'MISSED'}; wrong centres: {wrong_all} (target 0)")
    print(f"\n({time.perf_counter() - t0:.0f} s; load average {os.getloadavg()[0]:.2f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
