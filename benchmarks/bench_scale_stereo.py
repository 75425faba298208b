"""Two cameras with a stereo transform, true scale 1.02, scale always estimated (--scale): where
does the scale error come from? The stereo transform's stated covariance and the error actually
drawn from it are varied apart (rotation only, translation only, none); the detections are as in
bench_scale.py table A (0.3 px, 3 mm, stated correctly).

    .venv/bin/python benchmarks/bench_scale_stereo.py [TRIALS] [N]

Columns: RMS of the relative scale error, median stated sigma, RMS of error / stated sigma (about
1 when the stereo uncertainty is propagated honestly), pose RMS of cam1, the scale's sigma were the stereo exact (what the detections allow, as the
CLI states it) and how often the CLI says that the stereo transform limits the scale.
"""
import math
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench_scale import cdata, rms, stereo, stereo_cov  # noqa: E402
from calib_core.solve.refine import Link  # noqa: E402
from calib_core.solve.rig import solve_rig  # noqa: E402
from calib_core.solve.simulate import synthetic_rig  # noqa: E402
from calib_core.solve.single import solve_camera  # noqa: E402
from calib_core.solve.scale import stereo_limit_note  # noqa: E402
from calib_core.geometry import pose_error  # noqa: E402
CASES = [("stated 0.05/1, drawn 0.05/1", (0.05, 1e-3), (0.05, 1e-3)),
         ("stated 0.05/1, exact stereo", (0.05, 1e-3), None),
         ("stated 0.05/0.001 rot only drawn", (0.05, 1e-6), (0.05, 1e-6)),
         ("stated 0.0001/1 trans only drawn", (1e-4, 1e-3), (1e-4, 1e-3)),
         ("stated 0.02/0.3 drawn", (0.02, 3e-4), (0.02, 3e-4)),
         ("stated 0.0001/0.001 (exact)", (1e-4, 1e-6), (1e-4, 1e-6))]


def main():
    T = int(sys.argv[1]) if len(sys.argv) > 1 else 40
    N = int(sys.argv[2]) if len(sys.argv) > 2 else 9
    print(f"load average before: {os.getloadavg()}")
    for name, st, dr in CASES:
        out = []
        for k in range(T):
            rig = synthetic_rig(30_000 + k, n_captures=N, scale=1.02)
            T21 = rig.T_cam2_cam1 if dr is None else stereo(rig, np.random.default_rng(k), stereo_cov(dr))
            sols = {c: solve_camera(cdata(rig, c), estimate_scale=False, loo=False) for c in ("cam1", "cam2")}
            rs = solve_rig(sols, {"cam2": Link(T21, stereo_cov(st))}, "cam1", estimate_scale=True)
            e = pose_error(rs.T_cam_sonar["cam1"], rig.T_cam_sonar["cam1"])
            out.append((rs.scale - 1.02, rs.scale_sigma, math.degrees(e[0]), 1000 * e[1], rs.scale_sigma_detections,
                        bool(stereo_limit_note(rs.scale_sigma, rs.scale_sigma_detections, True))))
        a = np.array(out)
        print(f"N={N} {name:36s} RMS s err {100*rms(a[:,0]):.3f} %  med sigma {100*np.median(a[:,1]):.3f} %  RMS z {rms(a[:,0]/a[:,1]):.2f}  rot {rms(a[:,2]):.3f} t {rms(a[:,3]):.2f}  "
              f"med sigma if stereo exact {100*np.median(a[:,4]):.3f} %  'stereo limits it' said {100*a[:,5].mean():.0f} %", flush=True)
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
