"""Solver benchmark: accuracy against the Cramer-Rao bound and cv2.solvePnP, scale recovery, timing,
and (when the synth package is there) end-to-end accuracy of ``calibrate`` on synthetic sessions.

    .venv/bin/python benchmarks/bench_solver.py [--trials 200] [--e2e-seeds 3] [--no-e2e]

Part A draws, per trial, a fresh rig and sphere layout (calib_core.solve.simulate) with Gaussian
noise on both sensors, and solves camera 1 with
- the ML solver (calib_core.solve.single.solve_camera, RANSAC on, leave-one-out off),
- cv2.solvePnP ITERATIVE on the raw pixels (plain reprojection error), started from SQPnP.
The bound is computed here, independently of the solver's code: Fisher information
sum_i G_i^T S_i^-1 G_i in *pixel* space with finite-difference Jacobians of CameraModel.project,
S_i = cov_uv + J_X cov_X J_X^T; RMS errors are compared with sqrt(E[trace(CRB block)]).
Part B runs the full two-camera joint solve with the range scale on noisy stereo transforms
and compares the scale error with its bound (13 parameters: pose, stereo with its prior, scale).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from calib_core.geometry import T_from_rotvec, transform_points  # noqa: E402
from calib_core.solve.model import camera_data, exp_so3, log_so3  # noqa: E402
from calib_core.solve.refine import Link  # noqa: E402
from calib_core.solve.rig import default_stereo_cov, solve_rig  # noqa: E402
from calib_core.solve.simulate import synthetic_rig  # noqa: E402
from calib_core.solve.single import solve_camera  # noqa: E402


def perturb(T, d):
    Tp = T.copy()
    Tp[:3, :3] = exp_so3(d[:3]) @ T[:3, :3]
    Tp[:3, 3] = T[:3, 3] + d[3:]
    return Tp


def num_jac(f, x, h=1e-7):
    cols = []
    for i in range(len(x)):
        d = np.zeros(len(x))
        d[i] = h
        cols.append((f(x + d) - f(x - d)) / (2 * h))
    return np.column_stack(cols)


def crb_single(cam, T, X, cov_uv, cov_X):
    """6x6 Cramer-Rao bound (left rotation vector rad, translation m) for one camera."""
    F = np.zeros((6, 6))
    for i in range(len(X)):
        G = num_jac(lambda d: cam.project(transform_points(perturb(T, d), X[i]))[0], np.zeros(6))
        JX = num_jac(lambda x: cam.project(transform_points(T, x))[0], X[i])
        S = cov_uv[i] + JX @ cov_X[i] @ JX.T
        F += G.T @ np.linalg.solve(S, G)
    return np.linalg.inv(F)


def crb_joint_scale(rig, stereo_cov):
    """13x13 bound for (cam1 pose, stereo perturbation, scale); returns the scale variance."""
    c1, c2 = rig.cameras["cam1"], rig.cameras["cam2"]

    def z(theta, Xc):
        T1 = perturb(rig.T_cam_sonar["cam1"], theta[:6])
        T21 = perturb(rig.T_cam2_cam1, theta[6:12])
        Xt = Xc / (rig.scale + theta[12])
        return np.concatenate([c1.project(transform_points(T1, Xt))[0], c2.project(transform_points(T21 @ T1, Xt))[0]])

    F = np.zeros((13, 13))
    F[6:12, 6:12] = np.linalg.inv(stereo_cov)
    for i in range(len(rig.X_true_sonar_m)):
        Xc = rig.scale * rig.X_true_sonar_m[i]
        G = num_jac(lambda th: z(th, Xc), np.zeros(13))
        JX = num_jac(lambda x: z(np.zeros(13), x), Xc)
        S = np.zeros((4, 4))
        S[:2, :2], S[2:, 2:] = rig.cov_uv_px2["cam1"][i], rig.cov_uv_px2["cam2"][i]
        S += JX @ rig.cov_X_m2[i] @ JX.T
        F += G.T @ np.linalg.solve(S, G)
    return np.linalg.inv(F)[12, 12]


def err6(T, T_true):
    return np.concatenate([log_so3(T[:3, :3] @ T_true[:3, :3].T), T[:3, 3] - T_true[:3, 3]])


def cv2_iterative(cam, uv, X):
    ok, rv, tv = cv2.solvePnP(X, uv, cam.K, cam.dist, flags=cv2.SOLVEPNP_SQPNP)
    ok, rv, tv = cv2.solvePnP(X, uv, cam.K, cam.dist, rv, tv, useExtrinsicGuess=True, flags=cv2.SOLVEPNP_ITERATIVE)
    return T_from_rotvec(rv.ravel(), tv.ravel())


def part_a(trials, configs):
    rows = []
    for n, spx, sm in configs:
        e_ml, e_cv, crbs, times = [], [], [], []
        nees = {"ml": ([], []), "cv": ([], [])}
        for k in range(trials):
            rig = synthetic_rig(1000 * n + k, n_captures=n, sigma_px=spx, sigma_m=sm)
            cam, T = rig.cameras["cam1"], rig.T_cam_sonar["cam1"]
            cd = camera_data("cam1", cam, rig.capture_ids, rig.uv_px["cam1"], rig.cov_uv_px2["cam1"], rig.X_sonar_m,
                             rig.cov_X_m2)
            t0 = time.perf_counter()
            sol = solve_camera(cd, loo=False)
            times.append(time.perf_counter() - t0)
            e_ml.append(err6(sol.T_cam_sonar, T))
            e_cv.append(err6(cv2_iterative(cam, rig.uv_px["cam1"], rig.X_sonar_m), T))
            C = crb_single(cam, T, rig.X_true_sonar_m, rig.cov_uv_px2["cam1"], rig.cov_X_m2)
            crbs.append(np.diag(C))
            for key, e in (("ml", e_ml[-1]), ("cv", e_cv[-1])):  # errors whitened by the bound's blocks
                nees[key][0].append(e[:3] @ np.linalg.solve(C[:3, :3], e[:3]) / 3)
                nees[key][1].append(e[3:] @ np.linalg.solve(C[3:, 3:], e[3:]) / 3)
        e_ml, e_cv, crbs = np.array(e_ml), np.array(e_cv), np.array(crbs)
        eff = {k: (math.sqrt(np.mean(v[0])), math.sqrt(np.mean(v[1]))) for k, v in nees.items()}
        rot = lambda e: math.degrees(math.sqrt(np.mean(np.sum(e[:, :3] ** 2, axis=1))))  # noqa: E731
        tra = lambda e: 1000 * math.sqrt(np.mean(np.sum(e[:, 3:] ** 2, axis=1)))  # noqa: E731
        b_rot = math.degrees(math.sqrt(np.mean(np.sum(crbs[:, :3], axis=1))))
        b_tra = 1000 * math.sqrt(np.mean(np.sum(crbs[:, 3:], axis=1)))
        rows.append(dict(n=n, spx=spx, sm=sm, ml_rot=rot(e_ml), cv_rot=rot(e_cv), b_rot=b_rot, ml_t=tra(e_ml),
                         cv_t=tra(e_cv), b_t=b_tra, ms=1000 * np.median(times), eff=eff))
    return rows


def part_b(trials, n, spx, sm, scale=1.01, stereo_sigma=None):
    errs, bounds, times = [], [], []
    cov = default_stereo_cov() if stereo_sigma is None else np.diag([math.radians(stereo_sigma[0]) ** 2] * 3
                                                                        + [stereo_sigma[1] ** 2] * 3)
    rng = np.random.default_rng(77)
    for k in range(trials):
        rig = synthetic_rig(5000 + k, n_captures=n, sigma_px=spx, sigma_m=sm, scale=scale)
        d = rng.multivariate_normal(np.zeros(6), cov)
        T21_meas = perturb(rig.T_cam2_cam1, d)
        t0 = time.perf_counter()
        sols = {c: solve_camera(camera_data(c, rig.cameras[c], rig.capture_ids, rig.uv_px[c], rig.cov_uv_px2[c],
                                            rig.X_sonar_m, rig.cov_X_m2), loo=False) for c in ("cam1", "cam2")}
        rs = solve_rig(sols, {"cam2": Link(T21_meas, cov)}, "cam1", estimate_scale=True)
        times.append(time.perf_counter() - t0)
        errs.append(rs.scale - scale)
        bounds.append(crb_joint_scale(rig, cov))
    return dict(n=n, stereo=stereo_sigma or (0.05, 0.001), rms=math.sqrt(np.mean(np.square(errs))),
                bound=math.sqrt(np.mean(bounds)),
                bias=float(np.mean(errs)), ms=1000 * np.median(times))


def part_timing(reps=5):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from test_solve_calibrate import write_session

    from calib_core.detections import load_detections
    from calib_core.session import load_session
    from calib_core.solve.calibrate import calibrate_session

    rig = synthetic_rig(4242, n_captures=9)
    with tempfile.TemporaryDirectory() as tmp:
        root = write_session(Path(tmp) / "s", rig)
        s = load_session(root)
        dets = load_detections(s)
        calibrate_session(s, dets, {"detect": False})  # warm-up (imports)
        ts = []
        for _ in range(reps):
            t0 = time.perf_counter()
            calibrate_session(s, dets, {"detect": False, "estimate_scale": True})
            ts.append(time.perf_counter() - t0)
    return float(np.median(ts))


def part_e2e(seeds, presets):
    """calibrate (detection included) on generated sessions vs their ground_truth.yaml."""
    try:
        from calib_core.synth.generate import generate_session
        from calib_core.synth.ground_truth import load_ground_truth
    except ImportError as e:
        print(f"(end-to-end part skipped: {e})")
        return []
    from calib_core import pipeline
    from calib_core.detections import load_detections
    from calib_core.geometry import pose_error
    from calib_core.session import load_session
    from calib_core.solve.calibrate import calibrate_session

    rows = []
    for label, preset, overrides, scale_opt in presets:
        for seed in seeds:
            with tempfile.TemporaryDirectory() as tmp:
                t0 = time.perf_counter()
                root = generate_session(Path(tmp) / "s", preset, seed, **overrides)
                t_gen = time.perf_counter() - t0
                gt = load_ground_truth(root)
                s = load_session(root)
                t0 = time.perf_counter()
                dets = pipeline.detect_session(s, load_detections(s))
                t_det = time.perf_counter() - t0
                t0 = time.perf_counter()
                cal = calibrate_session(s, dets, {"detect": False, "estimate_scale": scale_opt})
                t_cal = time.perf_counter() - t0
                for cam, c in cal["cameras"].items():
                    dr, dt = pose_error(np.asarray(c["T_cam_sonar"]), np.asarray(gt["cameras"][cam]["T_cam_sonar"]))
                    rows.append(dict(preset=label, seed=seed, cam=cam, rot=math.degrees(dr), t=1000 * dt,
                                     s1r=max(c["sigma_1"]["rotation_deg"]), s1t=max(c["sigma_1"]["translation_mm"]),
                                     used=len(c["captures_used"]), n=len(s.captures),
                                     scale=cal["range_scale"]["value"], scale_true=gt.get("range_scale", 1.0),
                                     scale_est=cal["range_scale"]["estimated"], t_gen=t_gen, t_det=t_det, t_cal=t_cal))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=300)
    ap.add_argument("--scale-trials", type=int, default=100)
    ap.add_argument("--e2e-seeds", type=int, default=2)
    ap.add_argument("--no-e2e", action="store_true")
    a = ap.parse_args(argv)
    configs = [(6, 0.3, 0.003), (9, 0.3, 0.003), (15, 0.3, 0.003), (30, 0.3, 0.003), (9, 1.0, 0.010)]
    print(f"A. Camera pose, Monte Carlo ({a.trials} random rigs/layouts per row), noise on both sensors")
    print(f"{'N':>3} {'px':>4} {'mm':>4} | {'ML rot':>7} {'cv2 rot':>7} {'CRB rot':>7} {'ML/CRB':>6} | "
          f"{'ML t':>6} {'cv2 t':>6} {'CRB t':>6} {'ML/CRB':>6} | {'eff ML r/t':>11} {'eff cv2 r/t':>11} | {'ms':>5}")
    rows = part_a(a.trials, configs)
    for r in rows:
        print(f"{r['n']:>3} {r['spx']:>4.1f} {1000 * r['sm']:>4.0f} | {r['ml_rot']:>7.3f} {r['cv_rot']:>7.3f} "
              f"{r['b_rot']:>7.3f} {r['ml_rot'] / r['b_rot']:>6.3f} | {r['ml_t']:>6.2f} {r['cv_t']:>6.2f} "
              f"{r['b_t']:>6.2f} {r['ml_t'] / r['b_t']:>6.3f} | {r['eff']['ml'][0]:>5.3f} {r['eff']['ml'][1]:>5.3f} "
              f"{r['eff']['cv'][0]:>5.3f} {r['eff']['cv'][1]:>5.3f} | {r['ms']:>5.1f}")
    print("   (rotation: RMS angle, deg; translation: RMS norm, mm; eff = sqrt(mean e^T CRB^-1 e / 3) per block,\n"
          "    i.e. error relative to the bound trial by trial (1.000 = at the bound); ms = ML solve incl. RANSAC)")
    print(f"\nB. Range scale, joint two-camera solve, true scale 1.01, stereo transform drawn from its covariance, "
          f"{a.scale_trials} trials")
    sc = [part_b(a.scale_trials, n, 0.3, 0.003) for n in (9, 30)]
    sc += [part_b(a.scale_trials, n, 0.3, 0.003, stereo_sigma=(0.02, 0.0003)) for n in (9, 30)]
    for r in sc:
        print(f"N={r['n']:>2} stereo {r['stereo'][0]:.2f} deg/{1000 * r['stereo'][1]:.1f} mm: "
              f"RMS scale error {100 * r['rms']:.3f} %  bound {100 * r['bound']:.3f} %  ratio {r['rms'] / r['bound']:.3f}  bias {100 * r['bias']:+.3f} %  ({r['ms']:.0f} ms per joint calibration)")
    t_cal = part_timing()
    print(f"\nC. calibrate_session, 2 cameras x 9 captures (RANSAC, ML, scale, leave-one-out, joint, Table I), "
          f"detections given: {t_cal:.2f} s")
    e2e = [] if a.no_e2e else part_e2e(list(range(1, a.e2e_seeds + 1)),
                                       [("canal", "canal", {}, False),
                                        ("canal-s1.02", "canal", {"range_scale": 1.02}, True)])
    if e2e:
        print("\nD. End-to-end on generated sessions (detection + calibrate) vs ground_truth.yaml")
        print(f"{'preset':>11} {'seed':>4} {'cam':>5} {'rot deg':>8} {'t mm':>6} {'1s deg':>7} {'1s mm':>6} "
              f"{'used':>5} {'scale':>8} {'true':>6} {'det s':>6} {'cal s':>6}")
        for r in e2e:
            print(f"{r['preset']:>11} {r['seed']:>4} {r['cam']:>5} {r['rot']:>8.3f} {r['t']:>6.1f} {r['s1r']:>7.3f} "
                  f"{r['s1t']:>6.1f} {r['used']:>2}/{r['n']:<2} {r['scale']:>8.4f} {r['scale_true']:>6.3f} "
                  f"{r['t_det']:>6.1f} {r['t_cal']:>6.2f}")
    nine = next(r for r in rows if r["n"] == 9 and r["spx"] == 0.3)
    worst = max(max(r["ml_rot"] / r["b_rot"], r["ml_t"] / r["b_t"]) for r in rows)
    worst_eff = max(max(r["eff"]["ml"]) for r in rows)
    print("\nTargets")
    checks = [
        ("ML RMS error <= 1.05 x CRB (worst row)", f"{worst:.3f}x", worst <= 1.05),
        ("ML per-trial efficiency <= 1.05 (worst row)", f"{worst_eff:.3f}", worst_eff <= 1.05),
        ("9 captures, 0.3 px / 3 mm: rotation < 0.2 deg", f"{nine['ml_rot']:.3f} deg", nine["ml_rot"] < 0.2),
        ("9 captures, 0.3 px / 3 mm: translation < 10 mm", f"{nine['ml_t']:.2f} mm", nine["ml_t"] < 10),
        ("scale within 0.2 % (RMS, 9 captures, stereo 1 mm)", f"{100 * sc[0]['rms']:.3f} %", sc[0]["rms"] < 0.002),
        ("scale within 0.2 % (RMS, 30 captures, stereo 1 mm)", f"{100 * sc[1]['rms']:.3f} %", sc[1]["rms"] < 0.002),
        ("scale within 0.2 % (RMS, 9 captures, stereo 0.3 mm)", f"{100 * sc[2]['rms']:.3f} %", sc[2]["rms"] < 0.002),
        ("scale error <= 1.05 x its bound (worst)", f"{max(r['rms'] / r['bound'] for r in sc):.3f}x",
         max(r["rms"] / r["bound"] for r in sc) <= 1.05),
        ("calibrate < 2 s for 9 captures", f"{t_cal:.2f} s", t_cal < 2.0),
    ]
    if e2e:
        canal = [r for r in e2e if r["preset"] == "canal"]
        if canal:
            rr = math.sqrt(np.mean([r["rot"] ** 2 for r in canal]))
            tt = math.sqrt(np.mean([r["t"] ** 2 for r in canal]))
            checks += [("end-to-end canal: rotation < 0.2 deg (RMS)", f"{rr:.3f} deg", rr < 0.2),
                       ("end-to-end canal: translation < 10 mm (RMS)", f"{tt:.1f} mm", tt < 10)]
        sc_rows = [r for r in e2e if r["scale_est"]]
        if sc_rows:
            se = max(abs(r["scale"] / r["scale_true"] - 1) for r in sc_rows)
            checks.append(("end-to-end canal with scale 1.02: scale within 0.2 %", f"{100 * se:.3f} %", se < 0.002))
        tc = max(r["t_cal"] for r in e2e)
        checks.append(("end-to-end calibrate (after detection) < 2 s", f"{tc:.2f} s", tc < 2.0))
    for name, val, ok in checks:
        print(f"  [{'met' if ok else 'MISSED'}] {name}: {val}")


if __name__ == "__main__":
    main()
