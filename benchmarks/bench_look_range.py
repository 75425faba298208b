"""A look's range in a later round's registration (issue 11, thirteenth round).

A look at the predicted place takes the predicted size, so its range repeats the prediction
(slope ~1, ``bench_predicted_look.py --range-bias``): when that prediction came from a registration
whose range was off, the look's range is off the same way, while its uv is the ball's own. In the
second round these looks enter the registration as plain detections. This benchmark draws random
registration cases (pure geometry, no images): 9 captures at 2.5-5 m, 3-5 plain detections (0.3 px,
ranges 1 % off), 2-4 looks (0.3 px, ranges ``--bias`` off, all the same sign, as a look's range
follows one registration), and the rest to predict; it compares the later round's registration
with the looks' ranges counted (before) and left out (``range_free``, after).

Run: .venv/bin/python benchmarks/bench_look_range.py [--cases 2000]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from calib_core.camera import CameraModel  # noqa: E402
from calib_core.disambiguate.image import resolve_candidates  # noqa: E402
from calib_core.geometry import invert_T, make_T  # noqa: E402
from calib_core.pipeline import _trusted  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402


def one_case(rng, bias: float):
    cam = CameraModel(960, 600, np.array([[700.0, 0, 487], [0, 700.0, 295], [0, 0, 1]]), np.zeros(5))
    T = make_T(Rotation.from_rotvec(rng.normal(0, 0.2, 3)).as_matrix(), rng.normal(0, 0.3, 3))
    n = 9
    X_cam = np.column_stack([rng.uniform(-1.2, 1.2, n), rng.uniform(-0.6, 0.6, n), rng.uniform(2.5, 5, n)])
    X_sonar = (invert_T(T)[:3, :3] @ X_cam.T).T + invert_T(T)[:3, 3]
    uv, rng_m = cam.project(X_cam), np.linalg.norm(X_cam, axis=1)
    n_plain, n_look = int(rng.integers(3, 6)), int(rng.integers(2, 5))
    ids = [f"p{i}" for i in range(n)]
    sign = rng.choice([-1.0, 1.0])
    cands = {}
    for i in range(n_plain + n_look):
        rel = rng.normal(0, 0.01) if i < n_plain else sign * bias
        cands[ids[i]] = np.array([[*(uv[i] + rng.normal(0, 0.3, 2)), rng_m[i] * (1 + rel)]])
    looks, targets = ids[n_plain:n_plain + n_look], ids[n_plain + n_look:]
    out = []
    for free in ((), looks):
        res = resolve_candidates(cam, dict(zip(ids, X_sonar)), cands, predict_for=targets, range_free=free)
        errs, trusted = [], 0
        for c in targets:
            if c in res.predicted_uvr:
                u, v, _ = res.predicted_uvr[c]
                errs.append(float(np.hypot(u - uv[int(c[1:])][0], v - uv[int(c[1:])][1])))
                trusted += _trusted(res, len(cands), c)
        out.append((res.support, n_plain + n_look, errs, trusted, len(targets)))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=2000)
    args = ap.parse_args(argv)
    print(f"Later-round registration with looks among the plain detections, {args.cases} random cases per row")
    print("| looks' range off | looks' range | cases where every plain detection and look agrees | "
          "prediction error median / 95 % / max (px) | predictions > 3 px | trusted predictions |")
    print("|---|---|---|---|---|---|")
    for bias in (0.0, 0.05, 0.08):
        rng = np.random.default_rng(7)
        rows = [[0, [], 0, 0, 0], [0, [], 0, 0, 0]]
        for _ in range(args.cases):
            for k, (sup, n, errs, trusted, n_t) in enumerate(one_case(rng, bias)):
                rows[k][0] += sup == n
                rows[k][1] += errs
                rows[k][2] += trusted
                rows[k][3] += n_t
        for name, (full, errs, trusted, n_t, _) in zip(("counted (before)", "left out (after)"), rows):
            e = np.asarray(errs) if errs else np.array([np.nan])
            print(f"| {100 * bias:.0f} % | {name} | {full} | {np.median(e):.2f} / {np.percentile(e, 95):.2f} / "
                  f"{np.max(e):.1f} | {int(np.sum(e > 3))} of {len(errs)} | {trusted} of {n_t} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
