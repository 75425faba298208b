"""Is the stated pose covariance honest? Synthetic presets end to end, with and without the
model errors common to every capture (calib_core.solve.systematic).

    .venv/bin/python benchmarks/bench_honesty.py [--presets rgbd-stick soundspeed ...] [--seeds 41 42]
                                                 [--cache DIR]

Each session is generated (half resolution) and detected once (kept in --cache), then
calibrated twice: with the systematic terms set to zero (the stated covariance scaled by the
variance factor, as before) and with the defaults. Per camera solve: the true pose error's
squared Mahalanobis distance per dof in the stated covariance (1 = honest), and what the
detections show against the truth: image and sonar centres' squared Mahalanobis per dof in
their stated covariances, and the mean (bias) and spread of the sonar centres' errors along
their rays from the sonar.
"""

from __future__ import annotations

import argparse
import os
import pickle
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from calib_core.geometry import invert_T, pose_error, rotvec_from_T  # noqa: E402
from calib_core.pipeline import SessionData, correspondences, detect_session  # noqa: E402
from calib_core.session import load_session  # noqa: E402
from calib_core.solve import systematic  # noqa: E402
from calib_core.solve.calibrate import calibrate_session  # noqa: E402
from calib_core.synth.generate import generate_session  # noqa: E402
from calib_core.synth.ground_truth import load_ground_truth  # noqa: E402


def session(cache: Path, preset: str, seed: int) -> Path:
    p = cache / f"{preset}-{seed}"
    if not (p / "dets.pkl").exists():
        shutil.rmtree(p, ignore_errors=True)
        generate_session(p, preset, seed, scale=0.5)
        d = detect_session(SessionData(load_session(p)), {})
        (p / "dets.pkl").write_bytes(pickle.dumps(d))
    return p


def _m2(c: dict, T_true: np.ndarray) -> float:
    T = np.asarray(c["T_cam_sonar"])
    e = np.r_[rotvec_from_T(T @ invert_T(T_true)), T[:3, 3] - T_true[:3, 3]]
    return float(e @ np.linalg.solve(np.asarray(c["covariance"], float)[:6, :6], e) / 6)


def detections_vs_truth(s, gt, dets, cam, used) -> tuple[float, float, float, float]:
    corr = correspondences(s, dets, cam)
    sc = gt.get("range_scale", 1.0)
    im, so, rad = [], [], []
    for i, cid in enumerate(corr.capture_ids):
        if cid not in used:
            continue
        g = gt["captures"][cid]
        r = corr.uv_px[i] - np.asarray(g["images"][cam]["center_uv_px"])
        im.append(r @ np.linalg.solve(corr.cov_uv_px2[i], r) / 2)
        X = g.get("center_sonar_at_image_m")
        Xt = np.asarray(X if X is not None else g["center_sonar_m"], float) * sc
        dx = corr.X_sonar_m[i] - Xt
        so.append(dx @ np.linalg.solve(corr.cov_X_m2[i], dx) / 3)
        rad.append(dx @ Xt / np.linalg.norm(Xt))
    return float(np.mean(im)), float(np.mean(so)), 1000 * float(np.mean(rad)), 1000 * float(np.std(rad))


def calibrate(s, dets, with_systematic: bool) -> dict:
    keep = systematic.SONAR_RADIAL_SIGMA_M, systematic.IMAGE_OFFSET_SIGMA_PX
    if not with_systematic:
        systematic.SONAR_RADIAL_SIGMA_M, systematic.IMAGE_OFFSET_SIGMA_PX = 0.0, 0.0
    try:
        return calibrate_session(s, dets, {"detect": False, "leave_one_out": False})
    finally:
        systematic.SONAR_RADIAL_SIGMA_M, systematic.IMAGE_OFFSET_SIGMA_PX = keep


def rows_of(p: Path) -> list:
    s, gt = load_session(p), load_ground_truth(p)
    dets = pickle.loads((p / "dets.pkl").read_bytes())
    try:
        before, after = calibrate(s, dets, False), calibrate(s, dets, True)
    except Exception as e:  # report, do not stop the sweep
        return [(p.name, "-", f"FAILED: {str(e)[:80]}")]
    out = []
    for cam, c in after["cameras"].items():
        T_true = gt["cameras"][cam]["T_cam_sonar"]
        im, so, bias, sd = detections_vs_truth(s, gt, dets, cam, set(c["captures_used"]))
        rot, t = pose_error(np.asarray(c["T_cam_sonar"]), T_true)
        out.append((p.name, cam, _m2(before["cameras"][cam], T_true), _m2(c, T_true), im, so, bias, sd,
                    np.degrees(rot), 1000 * t, c["solution"]))
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", nargs="+", default=["rgbd-stick", "soundspeed", "flange", "quick", "lidar-chair"])
    ap.add_argument("--seeds", type=int, nargs="+", default=[41, 42])
    ap.add_argument("--cache", type=Path, default=None)
    a = ap.parse_args(argv)
    print(f"load average before: {os.getloadavg()}")
    print(f"systematics: sonar centres along their rays {1000 * systematic.SONAR_RADIAL_SIGMA_M:g} mm, image "
          f"centres {systematic.IMAGE_OFFSET_SIGMA_PX:g} px (common to all captures)")
    head = ["session", "cam", "m2/dof before", "m2/dof now", "image m2/dof", "sonar m2/dof", "sonar ray bias mm",
            "ray sd mm", "rot deg", "t mm", "solution"]
    print(" | ".join(head))
    tmp = None if a.cache else tempfile.TemporaryDirectory()
    cache = a.cache or Path(tmp.name)
    cache.mkdir(parents=True, exist_ok=True)
    rows = []
    for seed in a.seeds:
        for preset in a.presets:
            for r in rows_of(session(cache, preset, seed)):
                print(" | ".join(f"{v:.2f}" if isinstance(v, float) else str(v) for v in r), flush=True)
                if len(r) > 3:
                    rows.append(r)
    if rows:
        b, n = np.array([r[2] for r in rows]), np.array([r[3] for r in rows])
        print(f"\nover {len(rows)} camera solves: mean squared Mahalanobis per dof {b.mean():.2f} before, "
              f"{n.mean():.2f} now (1 = honest); median {np.median(b):.2f} / {np.median(n):.2f}")
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
