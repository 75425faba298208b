"""Are the range side's stated sphere-centre covariances honest? Per sensor, per holder, per axis.

Single captures (calib_core.synth.range.capture: exact truth, no cameras) of every range sensor
(16-ring LiDAR, RGB-D, sonar, and the held-out 128-ring LiDAR, rosette LiDAR and active stereo)
x holder (chair, table: resting on a surface; stick, hand: held), seeds ``--first`` ..; the beam
width is estimated from 8 other captures of the pair, as a session would. Every right detection
(within ``--tol-mm``) gives its error against the truth in the ray frame: along the line of
sight, across it horizontally (across the fan / along a LiDAR ring) and across it vertically
(across the rings / along the fan), and z2 = error^2 / the stated variance on that axis (1 =
honest; for a Gaussian the median is 0.45). ``rms/sd`` = RMS error / RMS stated sigma per axis.

``--sweep PRESET ...``: the same on sessions of range presets (seed ``--first`` .., scale 0.5,
images not rendered), detected as ``sonarcal detect`` does (the session's beam width).

    .venv/bin/python benchmarks/bench_range_cov.py [--captures 20] [--first 1000] [--cache DIR]
    .venv/bin/python benchmarks/bench_range_cov.py --sweep lidar-chair rgbd-stick seabed canal --sessions 4
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from calib_core.detect.sonar.detect import detect_sphere_in_cloud  # noqa: E402
from calib_core.detect.sonar.beam import estimate_beam_width_deg  # noqa: E402
from calib_core.synth.range.capture import SENSORS, range_capture  # noqa: E402

HOLDERS = ("chair", "table", "stick", "hand")
AXES = ("along", "horiz", "vert")


def ray_frame(X: np.ndarray) -> np.ndarray:
    """(3,3) rows: along the line of sight, across it horizontally, across it vertically."""
    u = X / np.linalg.norm(X)
    a = np.cross([0.0, 0.0, 1.0], u)
    a /= np.linalg.norm(a)
    return np.stack([u, a, np.cross(u, a)])


def axis_z2(center, cov, truth) -> tuple[np.ndarray, np.ndarray]:
    """(errors (3,) m, stated variances (3,) m^2) in the ray frame of ``truth``."""
    B = ray_frame(np.asarray(truth, float))
    return B @ (np.asarray(center, float) - truth), np.diag(B @ np.reshape(cov, (3, 3)) @ B.T)


def _cloud(cache: Path | None, seed: int, sensor: str, holder: str, radius_m=None):
    if cache is None:
        return range_capture(seed, sensor, holder, radius_m=radius_m)
    f = cache / f"{sensor}-{holder}-s{seed}-r{radius_m}.npz"
    if f.is_file():
        z = np.load(f)
        return z["P"], z["c"], float(z["r"])
    P, c, r = range_capture(seed, sensor, holder, radius_m=radius_m)
    np.savez(f, P=P, c=c, r=r)
    return P, c, r


def capture_case(sensor: str, holder: str, seeds, tol_m: float, cache) -> dict:
    """Errors and stated variances of the right detections of one sensor x holder."""
    r_est = 0.3 if sensor == "lidar16" else 0.2
    width = estimate_beam_width_deg([_cloud(cache, s, sensor, holder, r_est)[0] for s in range(8)],
                                    r_est, 1.0).beam_width_deg
    E, V, D, U, n_wrong, n_refused = [], [], [], [], 0, 0
    for seed in seeds:
        P, c, r = _cloud(cache, seed, sensor, holder)
        det = detect_sphere_in_cloud(P, r, width)
        if not det.found:
            n_refused += 1
            continue
        if np.linalg.norm(det.center_sonar_m - c) > tol_m:
            n_wrong += 1
            continue
        e, v = axis_z2(det.center_sonar_m, det.cov_sonar_m2, c)
        E.append(e)
        V.append(v)
        D.append(np.linalg.norm(c))
        U.append(floor_unit(det.center_sonar_m, width))
    return {"E": np.array(E).reshape(-1, 3), "V": np.array(V).reshape(-1, 3), "width": width, "D": np.array(D),
            "U": np.array(U), "wrong": n_wrong, "refused": n_refused}


def sweep_case(preset: str, seeds, tol_m: float, cache: Path) -> dict:
    """The same over sessions of a range preset, detected as ``sonarcal detect`` does."""
    from benchmarks.bench_detection_range import _sweep_session
    from calib_core.pipeline import SessionData, detect_sonar_entry, session_beam_width
    from calib_core.session import load_session
    from calib_core.synth.ground_truth import load_ground_truth

    E, V, D, U, wrong, refused, widths = [], [], [], [], 0, 0, []
    for seed in seeds:
        root = _sweep_session(cache, preset, seed, 0.5)
        gt, data = load_ground_truth(root), SessionData(load_session(root))
        data.beam_width_deg = session_beam_width(data, [c.id for c in data.session.captures], {})
        widths.append(data.effective_beam_width_deg)
        scale = float(gt.get("range_scale") or 1.0)
        for cid, g in gt["captures"].items():
            if not g.get("target", True) or (g.get("moved_m") or 0) > 0.01:
                continue
            e = detect_sonar_entry(data, cid)
            truth = scale * np.asarray(g["center_sonar_m"], float)
            if e.get("center") is None or e.get("cov_m2") is None:
                refused += 1
            elif np.linalg.norm(np.asarray(e["center"]) - truth) > tol_m:
                wrong += 1
            else:
                err, v = axis_z2(e["center"], e["cov_m2"], truth)
                E.append(err)
                V.append(v)
                D.append(np.linalg.norm(truth))
                U.append(floor_unit(e["center"], data.effective_beam_width_deg))
    return {"E": np.array(E).reshape(-1, 3), "V": np.array(V).reshape(-1, 3), "D": np.array(D), "U": np.array(U),
            "width": float(np.median(widths)), "wrong": wrong, "refused": refused}


def floor_unit(center_m, width_deg: float) -> float:
    """(range x beam width)^2 (m^2): the model floor's variance per axis is MODEL_FLOOR_BEAM_FRACTION^2 of it."""
    return float(np.linalg.norm(center_m) * np.radians(width_deg)) ** 2


def floor_table(results: list[dict], floors) -> list[str]:
    """Pooled z2 per axis had the detector used each model floor in ``floors`` instead of its own
    (the floor is added to the fit's covariance after the fit: the centres do not change)."""
    from calib_core.detect.sonar.detect import MODEL_FLOOR_BEAM_FRACTION as f0

    E = np.vstack([r["E"] for r in results if len(r["E"])])
    V = np.vstack([r["V"] for r in results if len(r["E"])])
    U = np.concatenate([r["U"] for r in results if len(r["E"])])
    fit = np.maximum(V - f0**2 * U[:, None], 1e-14)  # the fit's own variance per axis (floor isotropic)
    out = ["| model floor (x range x beam width) | z2 along | z2 horiz | z2 vert | z2 all | med z2 |",
           "|---|---|---|---|---|---|"]
    for f in floors:
        Z = E**2 / (fit + f**2 * U[:, None])
        out.append(f"| {f:g}{' (now)' if f == f0 else ''} | " + " | ".join(f"{z:.2f}" for z in Z.mean(0))
                   + f" | {Z.mean():.2f} | {np.median(Z):.2f} |")
    return out


HEADER = ("| case | width deg | right | wrong/refused | z2 along | z2 horiz | z2 vert | z2 all | med z2 | "
          "z2 all less a common angle | rms/sd along | horiz | vert | sd mm along | horiz | vert |")


def less_common_angle(E: np.ndarray, D: np.ndarray) -> np.ndarray:
    """The errors less the case's mean angular offset across the ray (what a beam pointing
    offset of the sensor, i.e. a rotation of its frame, gives every capture alike)."""
    out = E.copy()
    out[:, 1:] -= np.outer(D, (E[:, 1:] / D[:, None]).mean(0))
    return out


def row(name: str, res: dict) -> str:
    E, V = res["E"], res["V"]
    if not len(E):
        return f"| {name} | {res['width']:.3f} | 0 | {res['wrong']}/{res['refused']} |" + " - |" * 12
    Z = E**2 / V
    z_less = float((less_common_angle(E, res["D"]) ** 2 / V).mean())
    ratio = np.sqrt((E**2).mean(0) / V.mean(0))
    sd = np.sqrt(V.mean(0)) * 1000
    return (f"| {name} | {res['width']:.3f} | {len(E)} | {res['wrong']}/{res['refused']} | "
            + " | ".join(f"{z:.2f}" for z in Z.mean(0)) + f" | {Z.mean():.2f} | {np.median(Z):.2f} | {z_less:.2f} | "
            + " | ".join(f"{q:.2f}" for q in ratio) + " | " + " | ".join(f"{s:.2f}" for s in sd) + " |")


def pooled(name: str, results: list[dict]) -> str:
    """One row over several cases (the common angle is removed per case)."""
    less = [less_common_angle(r["E"], r["D"]) if len(r["E"]) else r["E"] for r in results]
    E, V = np.vstack([r["E"] for r in results]), np.vstack([r["V"] for r in results])
    text = row(name, {"E": E, "V": V, "D": np.concatenate([r["D"] for r in results]),
                      "width": float(np.median([r["width"] for r in results])),
                      "wrong": sum(r["wrong"] for r in results), "refused": sum(r["refused"] for r in results)})
    if not len(E):
        return text
    cells = text.split(" | ")
    cells[9] = f"{float((np.vstack(less) ** 2 / V).mean()):.2f}"
    return " | ".join(cells)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--captures", type=int, default=20, help="captures per sensor x holder")
    ap.add_argument("--first", type=int, default=1000, help="first seed")
    ap.add_argument("--sensors", nargs="+", default=list(SENSORS))
    ap.add_argument("--holders", nargs="+", default=list(HOLDERS))
    ap.add_argument("--tol-mm", type=float, default=20.0, help="a centre farther off is wrong, left out")
    ap.add_argument("--cache", type=Path, help="keep the simulated clouds (and sessions) here")
    ap.add_argument("--sweep", nargs="*", metavar="PRESET", help="sessions of these range presets instead")
    ap.add_argument("--sessions", type=int, default=4, help="sessions per preset (--sweep)")
    ap.add_argument("--floors", nargs="*", type=float, metavar="F",
                    help="also print the pooled z2 had the sonar's model floor been each F")
    args = ap.parse_args(argv)
    if args.cache:
        args.cache.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    print(HEADER)
    print("|" + "---|" * 16)
    if args.sweep:
        import tempfile
        cache = args.cache or Path(tempfile.mkdtemp(prefix="bench_range_cov_"))
        res = [sweep_case(p, range(args.first, args.first + args.sessions), args.tol_mm / 1000, cache)
               for p in args.sweep]
        for p, r in zip(args.sweep, res):
            print(row(p, r), flush=True)
        print(pooled("all", res))
        everything = res
    else:
        seeds = range(args.first, args.first + args.captures)
        per_sensor = {}
        for sensor in args.sensors:
            for holder in args.holders:
                r = capture_case(sensor, holder, seeds, args.tol_mm / 1000, args.cache)
                per_sensor.setdefault(sensor, []).append(r)
                print(row(f"{sensor} {holder}", r), flush=True)
        for sensor, res in per_sensor.items():
            print(pooled(f"**{sensor}**", res))
        everything = [r for res in per_sensor.values() for r in res]
        print(pooled("**all**", everything))
    if args.floors:
        print("\n" + "\n".join(floor_table(everything, args.floors)))
    print(f"\n({time.perf_counter() - t0:.0f} s; load average {' '.join(f'{v:.2f}' for v in os.getloadavg())})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
