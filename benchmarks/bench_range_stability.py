"""Stability of the range-side search on far, sparse captures (issue 11, range5 task 1).

A far ball in a sparse scan (a sonar fan or a 16-ring LiDAR at 3 m or more: 30-100 returns on
it) sits near the edge of what the RANSAC search finds. When one random stream serves the
whole cloud, any unrelated change (one more look in another cluster, another object far away)
changes the draws in its cluster and flips the outcome. This script measures, on the sweep's
sessions (``bench_detection_range.py --sweep``; generated here if missing) for every capture
with the ball at ``--min-range`` m or more:

- found: the share found with ``rng_seed`` 0 (what ``sonarcal detect`` does), and the mean
  share over ``--rng-seeds`` seeds (the search's own luck);
- varies: captures whose found / refused outcome differs between those seeds;
- reorder: captures whose outcome (found, or the centre by more than 1 mm) changes when the
  cloud's points are shuffled;
- +far: the same when an unrelated object (the three visible faces of a box 1.5 ball diameters
  wide, 400 returns, 2.5 m to the side of the ball) is added to the cloud.

The beam width is fixed per sensor (sonar: 0.9 x the manifest's, what the session estimator
finds on these presets; LiDAR: 0.001 deg) so that before and after compare the search alone.

    .venv/bin/python benchmarks/bench_range_stability.py [--first 61 --last 80] [--cache DIR]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_detection_range import _sweep_session  # noqa: E402
from calib_core.detect.sonar.detect import detect_sphere_in_cloud  # noqa: E402
from calib_core.io.clouds import load_cloud  # noqa: E402
from calib_core.session import load_session  # noqa: E402
from calib_core.synth.ground_truth import load_ground_truth  # noqa: E402

PRESETS = ("seabed", "seabed-slab", "clutter", "canal", "lidar-chair", "carried")
SHIFT_TOL_M = 0.001


def far_box(center_m: np.ndarray, radius_m: float, rng: np.random.Generator, n: int = 400) -> np.ndarray:
    """Returns of the three sensor-facing faces of a box 3 radii wide, 2.5 m to the side of the
    ball (perpendicular to its line of sight, horizontal): an object unrelated to the ball."""
    los = center_m / np.linalg.norm(center_m)
    side = np.cross(los, [0.0, 0.0, 1.0])
    side = side / np.linalg.norm(side) if np.linalg.norm(side) > 1e-6 else np.array([0.0, 1.0, 0.0])
    c = center_m + 2.5 * side
    a = 1.5 * radius_m
    pts = rng.uniform(-a, a, (n, 3))
    face = rng.integers(0, 3, n)
    pts[np.arange(n), face] = -a * np.sign(c[face])  # the face towards the sensor on each axis
    return c + pts


def _outcome(det) -> tuple[bool, np.ndarray | None]:
    return (True, np.asarray(det.center_sonar_m)) if det.found else (False, None)


def _differs(a, b) -> bool:
    if a[0] != b[0]:
        return True
    return bool(a[0] and np.linalg.norm(a[1] - b[1]) > SHIFT_TOL_M)


def one_capture(P: np.ndarray, r: float, width: float, truth: np.ndarray, n_seeds: int) -> dict:
    """Outcomes of one capture under the rng seeds and the two unrelated changes."""
    rng = np.random.default_rng(12345)
    base = _outcome(detect_sphere_in_cloud(P, r, width, rng_seed=0))
    found = [base[0]] + [detect_sphere_in_cloud(P, r, width, rng_seed=s).found for s in range(1, n_seeds)]
    shuffled = _outcome(detect_sphere_in_cloud(P[rng.permutation(len(P))], r, width, rng_seed=0))
    extra = _outcome(detect_sphere_in_cloud(np.vstack([P, far_box(truth, r, rng)]), r, width, rng_seed=0))
    return {"found0": base[0], "rate": float(np.mean(found)), "varies": len(set(found)) > 1,
            "reorder": _differs(base, shuffled), "far": _differs(base, extra)}


def _captures(root: Path, min_range: float):
    gt = load_ground_truth(root)
    s = load_session(root)
    sensor = str(gt["sonar"].get("sensor", "sonar"))
    width = 0.9 * float(s.beam_width_deg or 1.0) if sensor == "sonar" else 0.001
    for cid, c in gt["captures"].items():
        if c.get("target") and np.linalg.norm(c["center_sonar_m"]) >= min_range and sensor in ("sonar", "lidar16"):
            yield sensor, cid, load_cloud(s.capture(cid).cloud_path).points_m, s.sphere_radius_m, width, \
                np.asarray(c["center_sonar_m"], float)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--first", type=int, default=61)
    ap.add_argument("--last", type=int, default=80)
    ap.add_argument("--cache", type=Path, default=Path("/tmp/range4/sweep"), help="the sweep's sessions")
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--rng-seeds", type=int, default=6)
    ap.add_argument("--min-range", type=float, default=3.0)
    ap.add_argument("--presets", nargs="+", default=list(PRESETS))
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    print(f"Far sparse captures (ball >= {args.min_range:g} m; sonar fans and 16-ring LiDAR), seeds "
          f"{args.first}-{args.last}: outcome stability ({args.rng_seeds} rng seeds; reorder / +far: "
          f"captures whose outcome changes)")
    print(f"{'preset':12} {'sensor':8} {'n':>4} {'found':>9} {'mean found':>10} {'varies':>6} {'reorder':>7} {'+far':>5}")
    tot = np.zeros(4, int)
    for preset in args.presets:
        rows: dict[str, list] = {}
        for seed in range(args.first, args.last + 1):
            root = _sweep_session(args.cache, preset, seed, args.scale)
            for sensor, cid, P, r, width, truth in _captures(root, args.min_range):
                rows.setdefault(sensor, []).append(one_capture(P, r, width, truth, args.rng_seeds))
        for sensor, res in rows.items():
            n = len(res)
            f0 = sum(x["found0"] for x in res)
            v, ro, fa = (sum(x[k] for x in res) for k in ("varies", "reorder", "far"))
            tot += [n, v, ro, fa]
            print(f"{preset:12} {sensor:8} {n:4d} {f0:4d}/{n:<4d} {np.mean([x['rate'] for x in res]):10.1%} "
                  f"{v:6d} {ro:7d} {fa:5d}")
    print(f"{'total':21} {tot[0]:4d} {'':9} {'':10} {tot[1]:6d} {tot[2]:7d} {tot[3]:5d}")
    print(f"target: 0 outcomes changed by reordering or an unrelated far object: {tot[2] + tot[3]} -> "
          f"{'MET' if tot[2] + tot[3] == 0 else 'MISSED'}")
    print(f"\n({time.perf_counter() - t0:.0f} s; load average {os.getloadavg()[0]:.2f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
