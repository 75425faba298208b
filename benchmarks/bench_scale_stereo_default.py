"""The assumed stereo uncertainty and the range-scale test: a stereo transform drawn with a
checkerboard calibration's error (the synthetic sessions': 0.08 deg / 2 mm per axis,
calib_core/synth/generate.py::_checkerboard_error) and solved with the uncertainty the session
states (or the solver assumes), true scale 1.00 and 1.02.

    .venv/bin/python benchmarks/bench_scale_stereo_default.py [--trials 300] [--n 8]

Rows: stated stereo sigma (deg / mm per axis). Columns per true scale: share of trials where the
F test chose the scaled model (at 1.00: the false-alarm rate, 0.1 % stated), RMS scale error,
cam1's pose RMS with the product's default and with the scale held at 1 (--no-scale).
Detections: 0.3 px / 3 mm (``--sigma``), stated correctly (calib_core.solve.simulate), as bench_scale.py.
``--no-widen``: the stereo covariance used as stated (before calib_core/solve/stereo_factor.py; the
scale test's deflation by the systematic term, added in the same round, stays).
BENCHMARKS.md "Twenty-fourth round" ran ``--trials 100 --sigma 0.1 0.001`` with and without ``--no-widen``.
"""

from __future__ import annotations

import argparse
import functools
import math
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench_scale import cdata, rms, stereo, stereo_cov  # noqa: E402
from calib_core.geometry import pose_error  # noqa: E402
from calib_core.solve.refine import Link, refine  # noqa: E402
import calib_core.solve.rig as rig_module  # noqa: E402
import calib_core.solve.stereo_factor as stereo_factor_module  # noqa: E402
from calib_core.solve.rig import solve_rig  # noqa: E402
from calib_core.solve.simulate import synthetic_rig  # noqa: E402
from calib_core.solve.single import solve_camera  # noqa: E402
from calib_core.solve.stereo_cov import DEFAULT_STEREO_SIGMA_M, DEFAULT_STEREO_SIGMA_RAD  # noqa: E402

DRAWN = (0.08, 0.002)  # the synthetic sessions' checkerboard stereo error, 1-sigma per axis


def trials_for(trials: int, n: int, scale: float, stated: tuple, drawn: tuple, sigma=(0.3, 0.003),
               stated_factor: float = 1.0) -> np.ndarray:
    """Per trial: (scale, estimated?, cam1 t error mm with the default, held at 1). ``stated_factor``:
    the detections' stated sigmas are this multiple of their true ones."""
    out = []
    for k in range(trials):
        rig = synthetic_rig(40_000 + k, n_captures=n, scale=scale, sigma_px=sigma[0], sigma_m=sigma[1])
        for cam in rig.cov_uv_px2:
            rig.cov_uv_px2[cam] = rig.cov_uv_px2[cam] * stated_factor ** 2
        rig.cov_X_m2 = rig.cov_X_m2 * stated_factor ** 2
        T21 = stereo(rig, np.random.default_rng(50_000 + k), stereo_cov(drawn))
        sols = {c: solve_camera(cdata(rig, c), estimate_scale=False, loo=False) for c in ("cam1", "cam2")}
        row = []
        for mode in (None, False):
            rs = solve_rig(sols, {"cam2": Link(T21, stereo_cov(stated))}, "cam1", estimate_scale=mode)
            row += [rs.scale, rs.scale_sigma is not None, 1000 * pose_error(rs.T_cam_sonar["cam1"], rig.T_cam_sonar["cam1"])[1]]
        out.append([row[0], row[1], row[2], row[5]])
    return np.array(out, float)


def stereo_as_stated(prob_free, state, robust=None):
    """Stands in for calib_core.solve.stereo_factor.stereo_factor with no widening (factor 1)."""
    return 1.0, {"factor": 1.0, "chi2": 0.0, "redundancy": 0.0}, prob_free, refine(prob_free, state, robust=robust)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=300)
    ap.add_argument("--n", type=int, default=8)
    ap.add_argument("--no-widen", action="store_true",
                    help="before this round: the stereo block's variance factor not estimated (stated covariance as is)")
    ap.add_argument("--sigma", type=float, nargs=2, default=(0.3, 0.003), help="image px and sonar m noise")
    ap.add_argument("--stated-factor", type=float, default=1.0,
                    help="the detections' stated sigmas are this multiple of the true ones (1.4: conservative, as "
                         "the rendered sessions' detectors state them)")
    ap.add_argument("--one-group", action="store_true",
                    help="the stereo block's factor against 1, not relative to the detections' own (before session 25)")
    args = ap.parse_args(argv)
    if args.no_widen:
        rig_module.stereo_factor = stereo_as_stated
    elif args.one_group:
        rig_module.stereo_factor = functools.partial(stereo_factor_module.stereo_factor, relative=False)
    mode = "before (no widening)" if args.no_widen else "one-group factor" if args.one_group else "now"
    print(f"{mode}; detections {args.sigma[0]} px / {1000 * args.sigma[1]:g} mm, stated x{args.stated_factor:g}; load average before: {os.getloadavg()}; stereo drawn at {DRAWN[0]} deg / {1000 * DRAWN[1]:g} mm; "
          f"solver default {math.degrees(DEFAULT_STEREO_SIGMA_RAD):.2g} deg / {1000 * DEFAULT_STEREO_SIGMA_M:.2g} mm")
    print("stated deg/mm | true s | scale chosen | RMS s err % | t RMS mm (default) | t RMS mm (held at 1) | ratio")
    for stated in ((0.05, 0.001), (0.08, 0.002)):
        for s in (1.0, 1.02):
            r = trials_for(args.trials, args.n, s, stated, DRAWN, args.sigma, args.stated_factor)
            print(f"{stated[0]}/{1000 * stated[1]:g} | {s:.2f} | {100 * r[:, 1].mean():.1f} % | "
                  f"{100 * rms((r[:, 0] - s) / s):.3f} | {rms(r[:, 2]):.2f} | {rms(r[:, 3]):.2f} | "
                  f"{rms(r[:, 2]) / rms(r[:, 3]):.3f}", flush=True)
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
