"""Calibrate a real session as a new user would and compare each pose with rough outside checks.

    .venv/bin/python benchmarks/bench_real_session.py [SESSION] [--checks FILE]

Defaults to ../shared/data/kinectnet-dev with benchmarks/data/kinectnet_pose_checks.yaml (skipped
with a message when the data is absent). The session is copied to a temporary folder, then
``sonarcal calibrate`` runs on the copy in a subprocess (start-up included). Printed per camera:
captures used/left out, rotation and translation difference to the check, within tolerance or
not, and the leave-one-out honesty: the mean of the squared leave-one-out Mahalanobis distances
over the used captures, per degree of freedom, against the detections' covariances ("raw") and
against the stated uncertainty after the tool's variance factor ("stated"; about 1 when honest).
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_SESSION = ROOT.parent / "shared" / "data" / "kinectnet-dev"
DEFAULT_CHECKS = ROOT / "benchmarks" / "data" / "kinectnet_pose_checks.yaml"


def expected_pose(check: dict, session: Path) -> np.ndarray:
    """The 4x4 T_cam_sonar a check names (identity, or the authors' transform, maybe inverted)."""
    if check.get("T") == "identity":
        return np.eye(4)
    R = np.loadtxt(session / check["authors_rotation"]).reshape(3, 3)
    t_m = np.loadtxt(session / check["authors_translation_mm"]).reshape(3) / 1000.0
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t_m
    return np.linalg.inv(T) if check.get("invert") else T


def pose_difference(T_a: np.ndarray, T_b: np.ndarray) -> tuple[float, float]:
    """(rotation angle deg, translation distance mm) between two T_cam_sonar."""
    ang = np.degrees(Rotation.from_matrix(T_a[:3, :3] @ T_b[:3, :3].T).magnitude())
    return float(ang), float(1e3 * np.linalg.norm(T_a[:3, 3] - T_b[:3, 3]))


def loo_honesty(cam_result: dict) -> tuple[float, float]:
    """Mean squared leave-one-out Mahalanobis distance per dof (2 per capture) over the used
    captures: against the detections' own covariances, and against the uncertainty the tool
    states (the same covariances times its variance factor, which also inflates the pose
    covariance). About 1 (slightly above: leave-one-out residuals are larger than in-sample
    ones) when the stated uncertainty is honest."""
    d2 = [r["loo"]["mahalanobis"] ** 2 for r in cam_result.get("residuals", [])
          if r.get("used") and isinstance(r.get("loo"), dict) and r["loo"].get("mahalanobis") is not None]
    if not d2:
        return float("nan"), float("nan")
    raw = float(np.mean(d2) / 2.0)
    vf = cam_result.get("variance_factor") or 1.0
    return raw, raw / max(float(vf), 1.0)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("session", nargs="?", default=str(DEFAULT_SESSION))
    ap.add_argument("--checks", default=str(DEFAULT_CHECKS))
    ap.add_argument("--no-scale", action="store_true", help="pass --no-scale to calibrate (range scale held at 1)")
    args = ap.parse_args(argv)
    src = Path(args.session)
    if not (src / "session.yaml").is_file():
        print(f"skipped: no session at {src}")
        return 0
    checks = yaml.safe_load(Path(args.checks).read_text()) if Path(args.checks).is_file() else {}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp) / src.name
        shutil.copytree(src, work)
        exe = Path(sys.executable).with_name("sonarcal")
        t0 = time.perf_counter()
        cmd = [str(exe), "calibrate", str(work), "--quiet"] + (["--no-scale"] if args.no_scale else [])
        proc = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if proc.returncode != 0:
            print(f"calibrate failed (exit {proc.returncode}): {proc.stderr.strip().splitlines()[-1:]}")
            return 1
        cal = json.loads((work / "results" / "calibration.json").read_text())
    print(f"session {src.name}: calibrate took {wall:.1f} s wall (fresh, detection included)")
    print(f"{'camera':8} {'used':>5} {'out':>4} {'d_rot deg':>10} {'d_t mm':>8} {'tol':>12} {'within':>7} {'LOO raw':>8} {'LOO stated':>10}")
    for cam, res in cal["cameras"].items():
        used = len(res.get("captures_used", []))
        out = len(res.get("outliers", []))
        raw, hon = loo_honesty(res)
        chk = checks.get(cam)
        if chk:
            dr, dt = pose_difference(np.asarray(res["T_cam_sonar"]), expected_pose(chk, src))
            ok = dr <= chk["tol_deg"] and dt <= chk["tol_mm"]
            print(f"{cam:8} {used:5d} {out:4d} {dr:10.2f} {dt:8.1f} {chk['tol_deg']:>5} / {chk['tol_mm']:<4} "
                  f"{'yes' if ok else 'NO':>7} {raw:8.2f} {hon:10.2f}")
        else:
            print(f"{cam:8} {used:5d} {out:4d} {'-':>10} {'-':>8} {'-':>12} {'-':>7} {raw:8.2f} {hon:10.2f}")
    from calib_core.solve.summary import scale_line

    print(scale_line(cal))
    missing = [c for c in checks if c not in cal["cameras"]]
    if missing:
        print(f"not calibrated: {', '.join(missing)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
