"""The stereo block's factor (calib_core.solve.stereo_factor) where the two-group estimate is thin or
bent: few captures (the detections' own factor from a few degrees of freedom) and robust losses.

Synthetic two-camera rigs (calib_core.solve.simulate.synthetic_rig, 0.1 px / 1 mm detections stated
as they are drawn), the stereo transform exact with the assumed covariance (0.05 deg / 1 mm), the
scale 1. Per captures x loss: the factor's median, 10-90 % and max over the seeds, the detections'
own factor's median and min, how often the CLI prints a stereo phrase, and how often a scale is chosen.

    .venv/bin/python benchmarks/bench_stereo_factor_cases.py [--seeds 16] [--captures 4 6 9]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from calib_core.solve.model import camera_data  # noqa: E402
from calib_core.solve.refine import Link  # noqa: E402
from calib_core.solve.rig import default_stereo_cov, solve_rig  # noqa: E402
from calib_core.solve.simulate import synthetic_rig  # noqa: E402
from calib_core.solve.single import solve_camera  # noqa: E402
from calib_core.solve.stereo_factor import stereo_factor_phrase  # noqa: E402


def one(seed: int, n: int, loss: str | None) -> tuple[float, float, bool, bool]:
    """(factor, detections' factor, phrase printed, scale chosen) of one exact-stereo rig."""
    rig = synthetic_rig(seed, n_captures=n, scale=1.0, sigma_px=0.1, sigma_m=0.001)
    sols = {c: solve_camera(camera_data(c, rig.cameras[c], rig.capture_ids, rig.uv_px[c], rig.cov_uv_px2[c],
                                        rig.X_sonar_m, rig.cov_X_m2), estimate_scale=False, loo=False)
            for c in ("cam1", "cam2")}
    rs = solve_rig(sols, {"cam2": Link(rig.T_cam2_cam1, default_stereo_cov())}, "cam1", robust=loss)
    sf = rs.stereo_factor
    return sf["factor"], sf["obs_factor"], bool(stereo_factor_phrase(sf, True)), rs.scale != 1.0


def main(argv=None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=16)
    ap.add_argument("--captures", type=int, nargs="+", default=(4, 6, 9))
    args = ap.parse_args(argv)
    print(f"exact stereo, detections as stated; seeds 100-{99 + args.seeds}; code: {ROOT}")
    print("captures | loss | factor median (10-90 %) max | detections' factor median / min | phrase | scale chosen")
    for n in args.captures:
        for loss in (None, "huber", "cauchy"):
            r = np.array([one(s, n, loss) for s in range(100, 100 + args.seeds)], float)
            f = r[:, 0]
            print(f"{n} | {loss or 'none'} | {np.median(f):.2f} ({np.percentile(f, 10):.2f}-{np.percentile(f, 90):.2f}) "
                  f"{f.max():.2f} | {np.median(r[:, 1]):.2f} / {r[:, 1].min():.2f} | {int(r[:, 2].sum())}/{len(r)} | "
                  f"{int(r[:, 3].sum())}/{len(r)}", flush=True)


if __name__ == "__main__":
    main()
