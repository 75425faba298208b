"""Capture planning benchmark: captures needed to reach a target precision when each next capture
follows the guidance, against random placement and a regular grid; and predicted against achieved
sigma after a guided capture.

    .venv/bin/python benchmarks/bench_plan.py [--rigs 60] [--trials 40] [--criterion d]

Rigs: calib_core.synth.rig.sample_rig (even seeds one camera, odd seeds the paper's two-camera
rig), sonar field 90 x 90 deg (the synthetic BV5000), sphere 0.22 m, working range 1-4 m from
the sonar. Detections are simulated without rendering: image centre = true projection +
N(0, 0.5 px) per axis; sonar centre = truth + N(0, cov) with 2 mm along the sonar ray and
2.5 mm per metre of range across it (the stated covariances are the true ones). Each camera is
solved independently by the solver's ML refinement (calib_core.solve.refine, the covariance
multiplied by max(1, variance factor) as solve_camera reports it) after every capture; a
strategy stops when every camera's reported 1-sigma is <= 0.1 deg and <= 5 mm on every axis.

Every strategy starts from the same 4 random captures. Then
- guided: the planner's first suggestion (calib_core.plan), from the current *estimated* poses
  and the noise model fitted to the captures taken; the operator misses it by N(0, 5 cm) per axis;
- random: uniform over the common view (sonar and every camera see the whole sphere);
- grid: a regular grid over the common view (5 x 4 pixel positions of cam1 x 4 distances, kept
  where every sensor sees the sphere), taken in farthest-point order (a generous grid).
Capped at 80 captures (counted as 80 when not reached).

Prediction: after N random captures (--before, default 6 and 15) the planner predicts each camera's
1-sigma after its first suggestion; the sphere is put there, and --trials fresh noise draws of all
N+1 captures are solved (from the true pose); achieved sigma = RMS error per axis. Reported: RMS
of (error / predicted sigma) pooled over rigs, cameras, axes and draws, for the prediction as the
tool shows it (x max(1, variance factor of the N captures), as the solver reports) and without.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._table import print_table  # noqa: E402
from calib_core.plan import (CameraState, Limits, NoiseModel, SonarField, Target, candidates, fit_noise,  # noqa: E402
                             plan_next, visibility)
from calib_core.solve.model import RigState, camera_data, log_so3  # noqa: E402
from calib_core.solve.refine import RigProblem, refine  # noqa: E402
from calib_core.synth.rig import sample_rig  # noqa: E402

SIGMA_PX, ALONG_M, ACROSS_PER_M = 0.5, 0.002, 0.0025
RADIUS_M, START, CAP, JITTER_M = 0.11, 4, 80, 0.05
TARGET = Target(0.1, 5.0)
LIMITS = Limits(working_range_m=(1.0, 4.0))


@dataclass
class World:
    """One synthetic rig: cameras {name: (model, true T_cam_sonar)}, field and true noise."""

    cams: dict
    field: SonarField
    noise: NoiseModel
    pool: np.ndarray = field(default=None)


def draw_world(seed: int) -> World:
    rng = np.random.default_rng(seed)
    rig = sample_rig(rng, 1 if seed % 2 == 0 else 2, 1920, 1080)
    cams = {n: (rig.cams[n][0], rig.T_cam_sonar(n)) for n in rig.cams}
    w = World(cams, SonarField(), NoiseModel(np.eye(2) * SIGMA_PX**2, ALONG_M, ACROSS_PER_M))
    w.pool = common_points(w, uniform_points(w, rng, 6000))
    return w


def uniform_points(w: World, rng, n: int) -> np.ndarray:
    """Uniform in volume over the field and working range."""
    a0, a1 = np.radians(w.field.azimuth_deg)
    s0, s1 = np.sin(np.radians(w.field.elevation_deg))
    r0, r1 = LIMITS.working_range_m
    az = np.degrees(rng.uniform(a0, a1, n))
    el = np.degrees(np.arcsin(rng.uniform(s0, s1, n)))
    r = (rng.uniform(r0**3, r1**3, n)) ** (1 / 3)
    return w.field.to_sonar(az, el, r)


def common_points(w: World, X: np.ndarray) -> np.ndarray:
    keep = w.field.contains(X, RADIUS_M) & visibility(w.cams, X, RADIUS_M, LIMITS).all(axis=1)
    return X[keep]


def grid_sequence(w: World) -> np.ndarray:
    """Regular grid over the common view (see the module doc), farthest-point order from the middle."""
    cam, T = w.cams["cam1"]
    us, vs = np.linspace(0.12, 0.88, 5) * cam.width_px, np.linspace(0.12, 0.88, 4) * cam.height_px
    uv = np.array([[u, v] for u in us for v in vs])
    rays = cam.rays(uv)
    rays = rays / np.linalg.norm(rays, axis=1, keepdims=True)
    Rinv, t = T[:3, :3].T, T[:3, 3]
    o = -Rinv @ t  # camera centre in the sonar frame
    pts = []
    for d in np.linspace(1.3, 3.8, 4):
        pts.append(o + (d * rays) @ Rinv.T)
    X = common_points(w, np.vstack(pts))
    if len(X) == 0:
        return X
    order = [int(np.argmin(np.linalg.norm(X - X.mean(axis=0), axis=1)))]
    dmin = np.linalg.norm(X - X[order[0]], axis=1)
    while len(order) < len(X):
        k = int(np.argmax(dmin))
        order.append(k)
        dmin = np.minimum(dmin, np.linalg.norm(X - X[k], axis=1))
    return X[order]


def measure(w: World, X_true: np.ndarray, rng) -> dict:
    """One simulated capture: measured sonar centre and covariance, pixel centre per camera seeing it."""
    cX = w.noise.sonar_cov(X_true[None])[0]
    vis = visibility(w.cams, X_true[None], RADIUS_M, LIMITS)[0]
    cap = {"X_true": X_true, "X": X_true + rng.multivariate_normal(np.zeros(3), cX), "cX": cX, "uv": {}}
    for seen, (name, (cam, T)) in zip(vis, w.cams.items()):
        if seen:
            cap["uv"][name] = cam.project((T[:3, :3] @ X_true + T[:3, 3])[None])[0] + rng.normal(0, SIGMA_PX, 2)
    return cap


def solve(w: World, caps: list, start: dict) -> dict:
    """{camera: (T estimate, reported 6x6 covariance, inflate)} for cameras with >= 4 captures."""
    out = {}
    for name, (cam, _) in w.cams.items():
        rows = [c for c in caps if name in c["uv"]]
        if len(rows) < 4:
            continue
        n = len(rows)
        cd = camera_data(name, cam, [f"c{i}" for i in range(n)], [c["uv"][name] for c in rows],
                         np.repeat(w.noise.cov_uv_px2[None], n, 0), [c["X"] for c in rows], [c["cX"] for c in rows])
        res = refine(RigProblem([cd]), RigState(start[name], {name: np.eye(4)}))
        inflate = max(1.0, res.variance_factor) if res.dof > 0 else 1.0
        out[name] = (res.state.T_ref_sonar, res.cov[:6, :6] * inflate, inflate)
    return out


def planner_states(w: World, est: dict, inflate: bool = True) -> list:
    return [CameraState(n, w.cams[n][0], T, C if inflate else C / k, k if inflate else 1.0) for n, (T, C, k) in est.items()]


def guided_next(w: World, caps: list, est: dict, rng, criterion: str, jitter: bool = True) -> np.ndarray:
    cams_est = {n: (w.cams[n][0], est[n][0]) for n in est}
    taken = np.array([c["X"] for c in caps])
    cands = candidates(cams_est, w.field, RADIUS_M, LIMITS, taken, pose_cov={n: est[n][1] for n in est})
    noise = fit_noise(np.repeat(w.noise.cov_uv_px2[None], len(caps), 0), taken, np.array([c["cX"] for c in caps]))
    plan = plan_next(planner_states(w, est), cands, noise, RADIUS_M, TARGET, 1, criterion, LIMITS.min_separation_m)
    if not plan.suggestions:
        return w.pool[rng.integers(len(w.pool))]
    X = plan.suggestions[0].X_sonar_m
    for _ in range(20 if jitter else 0):
        Xj = X + rng.normal(0, JITTER_M, 3)
        if w.field.contains(Xj[None], RADIUS_M)[0] and visibility(w.cams, Xj[None], RADIUS_M, LIMITS)[0].any():
            return Xj
    return X


def met(w: World, est: dict) -> bool:
    return len(est) == len(w.cams) and all(TARGET.met(C) for _, C, _ in est.values())


def run(w: World, strategy: str, seed: int, criterion: str, plan_s: list | None = None) -> int:
    """Captures needed with ``strategy``; guided planning times (s) are appended to ``plan_s``."""
    rng = np.random.default_rng(10_000 + seed)
    start_idx = rng.choice(len(w.pool), START, replace=False)
    caps = [measure(w, w.pool[i], rng) for i in start_idx]
    grid = grid_sequence(w) if strategy == "grid" else None
    truth = {n: T for n, (_, T) in w.cams.items()}
    est = solve(w, caps, truth)
    srng = np.random.default_rng(20_000 + seed)
    while not met(w, est) and len(caps) < CAP:
        k = len(caps) - START
        if strategy == "guided":
            t0 = time.perf_counter()
            X = guided_next(w, caps, est, srng, criterion)
            if plan_s is not None:
                plan_s.append(time.perf_counter() - t0)
        elif strategy == "random":
            X = w.pool[srng.integers(len(w.pool))]
        else:
            if k >= len(grid):
                return CAP
            X = grid[k]
        caps.append(measure(w, X, srng))
        est = solve(w, caps, {**truth, **{n: e[0] for n, e in est.items()}})
    return len(caps) if met(w, est) else CAP


def pose_err(T_est: np.ndarray, T_true: np.ndarray) -> np.ndarray:
    return np.concatenate([log_so3(T_est[:3, :3] @ T_true[:3, :3].T), T_est[:3, 3] - T_true[:3, 3]])


def prediction(w: World, seed: int, trials: int, criterion: str, n_before: int = 6):
    """Per camera: (predicted sigma (6,) as shown, predicted without inflation (6,), errors (trials,6))."""
    rng = np.random.default_rng(30_000 + seed)
    caps = [measure(w, w.pool[i], rng) for i in rng.choice(len(w.pool), n_before, replace=False)]
    truth = {n: T for n, (_, T) in w.cams.items()}
    est = solve(w, caps, truth)
    X = guided_next(w, caps, est, rng, criterion, jitter=False)
    cams_est = {n: (w.cams[n][0], est[n][0]) for n in est}
    out = {}
    for inflate in (True, False):
        states = planner_states(w, est, inflate)
        cands = candidates(cams_est, w.field, RADIUS_M, LIMITS, None, points=X[None])
        noise = fit_noise(np.repeat(w.noise.cov_uv_px2[None], len(caps), 0), np.array([c["X"] for c in caps]),
                          np.array([c["cX"] for c in caps]))
        plan = plan_next(states, cands, noise, RADIUS_M, TARGET, 1, criterion)
        for n, (r, t) in plan.suggestions[0].sigma_after.items():
            out.setdefault(n, []).append(np.concatenate([np.radians(r), t / 1000]))
    positions = [c["X_true"] for c in caps] + [X]
    errs = {n: [] for n in out}
    for _ in range(trials):
        redo = [measure(w, p, rng) for p in positions]
        sol = solve(w, redo, truth)
        for n in errs:
            if n in sol:
                errs[n].append(pose_err(sol[n][0], truth[n]))
    return {n: (out[n][0], out[n][1], np.array(errs[n])) for n in out}


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rigs", type=int, default=60)
    ap.add_argument("--trials", type=int, default=40)
    ap.add_argument("--criterion", default="worst", choices=["worst", "d"])
    ap.add_argument("--seed0", type=int, default=0)
    ap.add_argument("--before", default="6,15", help="random captures before the predicted one (comma list)")
    ap.add_argument("--no-counts", action="store_true", help="prediction part only")
    a = ap.parse_args()
    t0 = time.time()
    counts = {s: [] for s in ("guided", "random", "grid")}
    plan_s: list[float] = []
    kinds = []
    befores = [int(b) for b in a.before.split(",")]
    z = {(b, k, q): [] for b in befores for k in ("shown", "raw") for q in ("rot", "trans")}
    for seed in range(a.seed0, a.seed0 + a.rigs):
        w = draw_world(seed)
        kinds.append(len(w.cams))
        for s in counts:
            counts[s].append(0 if a.no_counts else run(w, s, seed, a.criterion, plan_s))
        for b in befores:
            for n, (pred, pred_raw, E) in prediction(w, seed, a.trials, a.criterion, b).items():
                for q, sl in (("rot", slice(0, 3)), ("trans", slice(3, 6))):
                    z[(b, "shown", q)].append((E[:, sl] / pred[sl]) ** 2)
                    z[(b, "raw", q)].append((E[:, sl] / pred_raw[sl]) ** 2)
        print(f"rig {seed}: cams {len(w.cams)} guided {counts['guided'][-1]} random {counts['random'][-1]} "
              f"grid {counts['grid'][-1]}", file=sys.stderr, flush=True)
    kinds = np.array(kinds)
    rows = []
    for label, m in (("all rigs", kinds > 0), ("one camera", kinds == 1), ("two cameras", kinds == 2)):
        g, r, gr = (np.array(counts[s])[m] for s in ("guided", "random", "grid"))
        rows.append([label, int(m.sum()), f"{g.mean():.1f} / {np.median(g):.0f}", f"{r.mean():.1f} / {np.median(r):.0f}",
                     f"{gr.mean():.1f} / {np.median(gr):.0f}", f"{100 * (1 - g.mean() / r.mean()):.0f} %",
                     f"{100 * (1 - g.mean() / gr.mean()):.0f} %", f"{(g >= CAP).sum()}/{(r >= CAP).sum()}/{(gr >= CAP).sum()}"])
    print_table(["rigs", "n", "guided", "random", "grid", "guided fewer than random", "guided fewer than grid",
                 f"capped at {CAP} (g/r/grid)"], rows,
                title=f"Captures to reach {TARGET.text()} (mean / median; criterion {a.criterion})")
    print()
    prow = []
    for b in befores:
        for k, label in (("shown", "as shown (x max(1, variance factor))"), ("raw", "model only (no inflation)")):
            zr = float(np.sqrt(np.mean(np.concatenate(z[(b, k, "rot")]))))
            zt = float(np.sqrt(np.mean(np.concatenate(z[(b, k, "trans")]))))
            per = [np.sqrt(np.mean(np.concatenate([zr_i, zt_i], axis=1)))
                   for zr_i, zt_i in zip(z[(b, k, "rot")], z[(b, k, "trans")])]
            p10, p50, p90 = np.percentile(per, [10, 50, 90])
            prow.append([f"{b} + 1", label, f"{zr:.2f}", f"{zt:.2f}", f"{p10:.2f} / {p50:.2f} / {p90:.2f}",
                         "met" if max(abs(zr - 1), abs(zt - 1)) <= 0.2 else "missed"])
    print_table(["captures", "prediction", "rotation", "translation",
                 "per rig-camera, 6 axes: p10 / median / p90", "within 20 %"], prow,
                title=f"Achieved / predicted 1-sigma after a guided capture (RMS of error / predicted sigma over "
                      f"{a.rigs} rigs x cameras x 3 axes x {a.trials} noise draws; 1.00 = exact, target 0.8-1.2)")
    if plan_s:
        print(f"\nplanning one guided step (candidates on a 17 x 13 x 10 grid, visibility, noise fit, scoring, "
              f"1 suggestion): median {1000 * np.median(plan_s):.0f} ms, p90 {1000 * np.percentile(plan_s, 90):.0f} ms "
              f"over {len(plan_s)} steps")
    print(f"time {time.time() - t0:.0f} s; load average {open('/proc/loadavg').read().split()[:3]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
