"""Are the image centre errors of one kind noise or bias? (issue 11, twenty-fourth round)

For every hit (within 3 px) on cached synthetic cases (``bench_image_presets.py --cache``):
the centre error, the stated standard deviation (from the detection's covariance) and the
squared Mahalanobis distance of the error. Noise that the covariance describes gives a mean
Mahalanobis^2 of ~2 (two image axes) and ~1 % beyond 9.21; a bias the covariance does not know
shows as errors larger than stated. Prints a table per kind (and per look, the part of the
label after the kind).

Run: .venv/bin/python benchmarks/bench_centre_errors.py --kinds dim --seeds 40 --cache DIR
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchmarks.bench_image_presets as bip  # noqa: E402
from calib_core.detect.image.detect import detect_sphere_in_image  # noqa: E402

CHI2_2_99 = 9.21


def _row(name: str, rows: list) -> str:
    e = np.array([r[0] for r in rows])
    s = np.array([r[1] for r in rows])
    m = np.array([r[2] for r in rows])
    return (f"| {name} | {len(rows)} | {np.sqrt(np.mean(e ** 2)):.3f} | {np.sqrt(np.mean(s ** 2)):.3f} "
            f"| {np.mean(m):.2f} | {np.mean(m > CHI2_2_99):.2f} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kinds", default="dim")
    ap.add_argument("--seeds", type=int, default=40)
    ap.add_argument("--first", type=int, default=1000)
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--cache", default=None)
    a = ap.parse_args(argv)
    bip.CACHE = Path(a.cache) if a.cache else None
    groups = defaultdict(list)
    for kind in a.kinds.split(","):
        for seed in range(a.first, a.first + a.seeds):
            case = bip._case(kind, seed, a.scale)
            det = detect_sphere_in_image(case.image, case.cam, case.radius_m)
            if not det.found:
                continue
            d = det.center_uv_px - case.true_uv_px
            if np.hypot(*d) > bip.TOL_PX:
                continue
            m2 = float(d @ np.linalg.solve(det.cov_uv_px2, d))
            row = (float(np.hypot(*d)), float(np.sqrt(np.trace(det.cov_uv_px2))), m2)
            groups[kind].append(row)
            groups[f"{kind} {case.label.split('/')[1]}"].append(row)
    print(f"\nCentre errors of the hits against their stated covariance (seeds {a.first}-{a.first + a.seeds - 1})")
    print("| case | hits | RMS error (px) | RMS stated (px, sqrt trace) | mean Mahalanobis^2 | share > 9.21 |")
    print("|---|---|---|---|---|---|")
    for name in sorted(groups):
        print(_row(name, groups[name]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
