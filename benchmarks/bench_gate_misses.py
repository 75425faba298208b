"""Which moved targets does the gate miss, and could any test have caught them? (issue 12)

    .venv/bin/python benchmarks/bench_gate_misses.py [--trials 300] [--n 9] [--tails gauss t5 t3]

Replays part C of bench_gate.py (same seeds, same moves: one capture's sonar centre moved
10-20 cm across camera 1's ray through it, true noise 1 px / 10 mm) and measures, for every
trial, how visible the move is:

- ``img px/sig``: the move seen in the image (its projection at the true pose, px) over the
  stated image sigma. Large by construction: the move is across the ray.
- ``evidence``: the move's noncentrality against everything else, in sigma: sqrt(d^T (S_i +
  G_i C_(i) G_i^T)^-1 d), where d is the change of the capture's residual (normalised image
  coordinates, true pose), S_i its true residual covariance (image and sonar noise) and
  C_(i) the pose covariance from the *other* captures at the true sigmas. This is what an
  oracle test (true sigmas, true pose linearisation, the others fixing the pose) sees; a move
  the other captures' pose can absorb (a far capture at the edge of the layout, high leverage)
  has little evidence however large it is in pixels.
- ``oracle power``: the chance that the oracle chi-square(2) test at the gate's per-capture
  level (ALPHA / n) flags it: P(chi2_2(lambda) > crit). Its mean over the trials is the best
  catch rate any test at that false-alarm rate could reach with the true sigmas known.
- ``F power``: the same for the gate's own kind of test, the noise level estimated from the
  other captures (noncentral F(2, 2n - 8)): the best a test that trusts no stated sigma can do.

- ``range mm`` / ``size ev``: the other cue a camera has, the sphere's apparent size (its range
  in the camera from the known diameter, ``calib_core.solve.scale``): the change of the sphere's
  camera range the move causes (a move across the ray changes it only to second order,
  sqrt(r^2 + d^2) - r) over the sigma of that comparison, sqrt(sigma_size^2 + sigma_sonar^2), with
  sigma_size = r^2 sigma_outline / (f R) for a 0.22 m sphere and an outline (radius) sigma of
  ``--outline-px`` (the tool's default, 2 px, and an optimistic 0.5 px).

Printed: per noise law, the catch rate (the issue's row), both expected rates, the catch rate
among observable moves (evidence >= k sigma, k where the oracle's power reaches 99 %: a
separate row, never the issue's), the catch rate among moves the F test catches with >= 99 %
power, and every miss with its numbers.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_gate import SIGMA_M, SIGMA_PX, data, draw, moved  # noqa: E402
from calib_core.geometry import transform_points  # noqa: E402
from calib_core.solve.gate import ALPHA  # noqa: E402
from calib_core.solve.model import per_camera_stats, prediction_jacobian  # noqa: E402
from calib_core.solve.single import solve_camera  # noqa: E402


def oracle_crit(n: int) -> float:
    """chi-square(2) critical value at 1 - ALPHA/n (closed form)."""
    return -2.0 * math.log(ALPHA / n)


def k_observable(n: int, power: float = 0.99) -> float:
    """Evidence (sigma) at which the oracle test catches with ``power``."""
    from scipy.optimize import brentq
    from scipy.stats import ncx2

    crit = oracle_crit(n)
    return math.sqrt(brentq(lambda lam: ncx2.sf(crit, 2, lam) - power, 1e-6, 1e4))


def f_power(lam: float, n: int) -> float:
    """Power of the gate's own test (F(2, 2n-8), noise level from the other captures) at
    noncentrality ``lam``: the best any test can do when the sigmas are not trusted."""
    from scipy.stats import ncf

    from calib_core.solve.gate import drop_critical

    dof = 2 * n - 8
    return float(ncf.sf(drop_critical(np.array([dof]), n)[0], 2, dof, lam))


def evidence(rig, X_clean, X_moved, i: int) -> tuple[float, float, float, float]:
    """(move in px, evidence in sigma, oracle power, F-test power) of row i's move at the true
    pose, true sigmas."""
    from scipy.stats import ncx2

    T = rig.T_cam_sonar["cam1"]
    cam = rig.cameras["cam1"]
    n = len(X_clean)
    cd = data(rig, cam.project(transform_points(T, X_clean)), X_clean, SIGMA_PX, SIGMA_M)
    _, r0, S, _, _ = per_camera_stats(cd, T)
    Xm = X_clean.copy()
    Xm[i] = X_moved[i]
    _, r1, _, _, _ = per_camera_stats(data(rig, cd.uv_px, Xm, SIGMA_PX, SIGMA_M), T)
    d = r1[i] - r0[i]
    G = prediction_jacobian(cd, T, np.arange(n))
    others = np.arange(n) != i
    info = np.einsum("nai,nab,nbj->ij", G[others], np.linalg.inv(S[others]), G[others])
    C = np.linalg.inv(info)
    V = S[i] + G[i] @ C @ G[i].T
    lam = float(d @ np.linalg.solve(V, d))
    px = float(np.linalg.norm(cam.project(transform_points(T, Xm[i:i + 1])) - cam.project(transform_points(T, X_clean[i:i + 1]))))
    return px, math.sqrt(lam), float(ncx2.sf(oracle_crit(n), 2, lam)), f_power(lam, n)


DIAMETER_M = 0.22


def size_evidence(rig, X_clean, X_moved, i: int, outline_px: float) -> tuple[float, float]:
    """(change of the camera range, mm; that change in sigma of the apparent-size comparison)."""
    T = rig.T_cam_sonar["cam1"]
    f = float(rig.cameras["cam1"].K[0, 0])
    r0 = float(np.linalg.norm(transform_points(T, X_clean[i:i + 1])[0]))
    r1 = float(np.linalg.norm(transform_points(T, X_moved[i:i + 1])[0]))
    sigma = math.hypot(r0 * r0 * outline_px / (f * DIAMETER_M / 2), SIGMA_M)
    return 1000 * (r1 - r0), abs(r1 - r0) / sigma


def trials_of(tails: str, trials: int, n: int, factor: float):
    """Per trial: (seed, row, px, evidence, oracle power, caught, F-test power)."""
    out = []
    for k in range(trials):
        rig, uv, X, rng = draw(20_000 + k, n, tails)
        bad = k % n
        Xm = moved(rig, X, bad, rng)
        sol = solve_camera(data(rig, uv, Xm, factor * SIGMA_PX, factor * SIGMA_M), loo=False)
        X1 = rig.X_true_sonar_m + (Xm - X)
        px, ev, pw, fp = evidence(rig, rig.X_true_sonar_m, X1, bad)
        dr, ev2 = size_evidence(rig, rig.X_true_sonar_m, X1, bad, 2.0)
        _, ev05 = size_evidence(rig, rig.X_true_sonar_m, X1, bad, 0.5)
        out.append((20_000 + k, bad, px, ev, pw, not sol.used[bad], fp, dr, ev2, ev05))
    return out


def report(tails: str, rows, n: int, k_obs: float, factor: float) -> None:
    caught = np.array([r[5] for r in rows])
    ev = np.array([r[3] for r in rows])
    power = np.array([r[4] for r in rows])
    obs = ev >= k_obs
    print(f"\n{tails}, stated/true {factor:g}, {len(rows)} sessions x {n} captures")
    print(f"  moved caught (all moves; the issue's row)          {100 * caught.mean():6.1f}%")
    fpow = np.array([r[6] for r in rows])
    print(f"  oracle expected catch rate (true sigmas known)      {100 * power.mean():6.1f}%")
    print(f"  F-test expected catch rate (sigma from the data)    {100 * fpow.mean():6.1f}%")
    print(f"  observable moves (evidence >= {k_obs:.2f} sigma)          {int(obs.sum()):4d} of {len(rows)}")
    print(f"  moved caught among observable moves (separate row) {100 * caught[obs].mean():6.1f}%")
    sure = fpow >= 0.99
    print(f"  moves the F test itself catches with >= 99 % power   {int(sure.sum()):4d} of {len(rows)}, "
          f"caught {100 * caught[sure].mean():.1f}%")
    dr = np.abs([r[7] for r in rows])
    e2, e05 = np.array([r[8] for r in rows]), np.array([r[9] for r in rows])
    print(f"  apparent size: camera range change median {np.median(dr):.1f} mm, max {dr.max():.1f} mm; evidence "
          f"median {np.median(e2):.2f} / max {e2.max():.2f} sigma (outline 2 px), "
          f"median {np.median(e05):.2f} / max {e05.max():.2f} sigma (0.5 px)")
    misses = [r for r in rows if not r[5]]
    if misses:
        print(f"  misses: {'seed':>6} {'row':>3} {'move px':>8} {'img px/sig':>10} {'evidence sig':>12} "
              f"{'oracle power':>12} {'F power':>8} {'observable':>10} {'range mm':>8} {'size ev 2px/0.5px':>17}")
        for s, i, px, e, pw, _, fp, d_r, s2, s05 in misses:
            print(f"          {s:>6} {i:>3} {px:>8.1f} {px / (factor * SIGMA_PX):>10.1f} {e:>12.2f} "
                  f"{100 * pw:>11.1f}% {100 * fp:>7.1f}% {'yes' if e >= k_obs else 'no':>10} {d_r:>8.1f} "
                  f"{s2:>8.2f}/{s05:.2f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=300)
    ap.add_argument("--n", type=int, default=9)
    ap.add_argument("--factor", type=float, default=1.0)
    ap.add_argument("--tails", nargs="+", default=["gauss", "t5", "t3"])
    a = ap.parse_args(argv)
    print(f"load average before: {os.getloadavg()}")
    k_obs = k_observable(a.n)
    print(f"oracle: chi-square(2) test at 1 - {ALPHA:g}/{a.n} (critical {oracle_crit(a.n):.2f}); "
          f"observable = evidence >= {k_obs:.2f} sigma (oracle power >= 99 %)")
    for tails in a.tails:
        report(tails, trials_of(tails, a.trials, a.n, a.factor), a.n, k_obs, a.factor)
    print(f"\nload average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
