"""The range scale on sessions with no scale error: how often the product's default (the F test of
calib_core/solve/scale.py) estimates a scale that is not there, and what pulls it.

Per session (synth -> detect_session -> calibrate_session with the product's defaults): the scale
test's p and verdict, the scale's estimate, the stereo transform's error in the session against
the ground truth (baseline-length error in mm and in sigmas of the covariance the solver uses, its
rotation error in deg), and the pose error. ``--stereo truth`` replaces the session's stereo
transform by the true one (attribution: what is left is the detections' doing). Detections are
cached in ``--cache`` (a pickle beside each session), so variants re-run only the solve.

    .venv/bin/python benchmarks/bench_scale_clean.py --presets underwater canal clutter --seeds 41 42 \
        [--cache DIR] [--stereo session|truth] [--scale 0.5]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import pickle
import tempfile
from pathlib import Path

import numpy as np

from calib_core.errors import SessionError
from calib_core.geometry import pose_error
from calib_core.pipeline import SessionData, detect_session
from calib_core.session import load_session
from calib_core.solve.calibrate import calibrate_session
from calib_core.solve.stereo_cov import key_stereo_cov
from calib_core.synth.generate import generate_session
from calib_core.synth.ground_truth import load_ground_truth


def session_and_detections(folder: Path, preset: str, seed: int, scale: float):
    root = folder / f"{preset}-s{seed}-x{scale:g}"
    if not (root / "ground_truth.yaml").is_file():
        generate_session(root, preset, seed, scale=scale)
    session, gt = load_session(root), load_ground_truth(root)
    pk = root / "scale3_detections.pkl"
    if pk.is_file():
        dets = pickle.loads(pk.read_bytes())
    else:
        dets = detect_session(SessionData(session), {})
        pk.write_bytes(pickle.dumps(dets))
    return session, gt, dets


def stereo_error(session, gt) -> tuple[float, float, float]:
    """(baseline-length error mm, the same in sigmas of the covariance used, rotation error deg)
    of the session's first stereo transform; nan without one."""
    keys = [k for k in (session.stereo or {}) if k in (gt.get("stereo") or {})]
    if not keys:
        return math.nan, math.nan, math.nan
    k = keys[0]
    T, T_true = np.asarray(session.stereo[k], float), np.asarray(gt["stereo"][k], float)
    C = key_stereo_cov(session, k)[0]
    u = T_true[:3, 3] / np.linalg.norm(T_true[:3, 3])
    d_len = float(np.linalg.norm(T[:3, 3]) - np.linalg.norm(T_true[:3, 3]))
    rot, _ = pose_error(T, T_true)
    return 1000 * d_len, d_len / math.sqrt(float(u @ C[3:, 3:] @ u)), math.degrees(rot)


def run_one(session, gt, dets, stereo: str) -> list:
    if stereo == "truth" and gt.get("stereo"):
        session = dataclasses.replace(session, stereo={k: np.asarray(v, float) for k, v in gt["stereo"].items()})
    res = calibrate_session(session, dets, {"detect": False})
    sc = res["range_scale"]
    test = sc.get("test") or {}
    errs = []
    for cam, c in res["cameras"].items():
        rot, t = pose_error(np.asarray(c["T_cam_sonar"]), gt["cameras"][cam]["T_cam_sonar"])
        errs.append(f"{math.degrees(rot):.3f}/{1000 * t:.1f}")
    dl, dz, dr = stereo_error(session, gt)
    p = test.get("p_value")
    return [f"{'yes' if sc.get('estimated') else 'no'}", "-" if p is None else f"{p:.3g}",
            f"{sc.get('value', 1.0):.4f}", f"{dl:+.1f}", f"{dz:+.1f}", f"{dr:.3f}", " ".join(errs)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", nargs="+", default=["underwater", "canal", "clutter"])
    ap.add_argument("--seeds", type=int, nargs="+", default=[41, 42])
    ap.add_argument("--scale", type=float, default=0.5, help="image resolution factor")
    ap.add_argument("--cache", help="keep sessions and detections here")
    ap.add_argument("--stereo", choices=("session", "truth"), default="session")
    args = ap.parse_args()
    print(" | ".join(["preset", "seed", "true scale", "scale estimated", "F test p", "scale", "stereo |t| err mm",
                      "in sigmas", "stereo rot err deg", "pose err deg/mm per camera"]))
    n = n_est = 0
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(args.cache or tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for seed in args.seeds:
            for preset in args.presets:
                session, gt, dets = session_and_detections(folder, preset, seed, args.scale)
                true = float(gt.get("range_scale", 1.0))
                try:
                    row = run_one(session, gt, dets, args.stereo)
                except SessionError as e:  # report, do not stop the sweep
                    print(f"{preset} | {seed} | {true:g} | FAILED: {e.problem[:100]}", flush=True)
                    continue
                if abs(true - 1.0) < 1e-9:
                    n += 1
                    n_est += row[0] == "yes"
                print(" | ".join([preset, str(seed), f"{true:g}"] + row), flush=True)
    print(f"\nclean sessions: {n}; scale estimated on {n_est} ({100 * n_est / max(n, 1):.0f} %; "
          f"the test's stated false-alarm rate is 0.1 %)")


if __name__ == "__main__":
    main()
