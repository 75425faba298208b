"""Blurred outlines: is the stated centre uncertainty as wide as the errors? (issue 11, round 11)

For the held-out ``motion`` image cases (a ball carried during the exposure, 2-15 px of blur
at 960x540) and, for comparison, the sharp ``clutter`` ones: per blur bin, the detections
within 3 px of the truth, their centre RMS error, the median stated 1-sigma per axis
(sqrt(trace cov / 2)), the median measured edge width (FWHM of the gradient, px) and the mean
Mahalanobis^2 of the error under the stated covariance (2 for a covariance that is right,
larger when it is over-confident).

Run: .venv/bin/python benchmarks/bench_blur_cov.py [--seeds 40] [--first 1000] [--cache DIR]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchmarks.bench_image_presets as presets  # noqa: E402
from calib_core.detect.image.detect import detect_sphere_in_image  # noqa: E402

BINS = ((0, 5), (5, 10), (10, 16))


def _rows(kind: str, seeds) -> list[tuple]:
    out = []
    for seed in seeds:
        case = presets._case(kind, seed, 0.5)
        det = detect_sphere_in_image(case.image, case.cam, case.radius_m)
        if not det.found:
            continue
        err = np.asarray(det.center_uv_px) - case.true_uv_px
        if np.hypot(*err) > presets.TOL_PX:
            continue
        blur = float(case.label.split("/")[1][:-2]) if kind == "motion" else 0.0
        cov = np.asarray(det.cov_uv_px2)
        out.append((blur, float(np.hypot(*err)), float(np.sqrt(np.trace(cov) / 2)),
                    float(err @ np.linalg.solve(cov, err)), float(det.extras.get("edge_width_px", np.nan))))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=40)
    ap.add_argument("--first", type=int, default=1000)
    ap.add_argument("--cache", type=Path, default=None)
    a = ap.parse_args(argv)
    presets.CACHE = a.cache
    seeds = range(a.first, a.first + a.seeds)
    print("| case | blur (px) | hits | centre RMS (px) | stated sigma per axis, median (px) "
          "| edge width, median (px) | mean Mahalanobis^2 (2 = right) |")
    print("|---|---|---|---|---|---|---|")
    for kind, bins in (("clutter", ((0, 1),)), ("motion", BINS)):
        rows = np.array(_rows(kind, seeds)).reshape(-1, 5)
        for lo, hi in bins:
            r = rows[(rows[:, 0] >= lo) & (rows[:, 0] < hi)]
            if not len(r):
                continue
            print(f"| {kind} | {lo}-{hi - 1 if kind == 'motion' else 0} | {len(r)} | {np.sqrt(np.mean(r[:, 1] ** 2)):.3f} "
                  f"| {np.median(r[:, 2]):.3f} | {np.nanmedian(r[:, 4]):.2f} | {np.mean(r[:, 3]):.2f} |")
    print("load average:", Path("/proc/loadavg").read_text().split()[:3])
    return 0


if __name__ == "__main__":
    sys.exit(main())
