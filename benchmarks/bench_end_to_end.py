"""End to end across scene presets: synth -> detect_session -> calibrate_session vs ground truth.

Prints one row per camera: pose error, captures used, detections not found, image detections
within 3 px of the truth among images showing the whole sphere, false detections used in the
solve, the captures the solver flagged as outliers and the ones that truly moved, and the range
scale (the product's default: estimated where observable and a test finds a scale error).
Seeds default to ones no test uses. Usage:

    .venv/bin/python benchmarks/bench_end_to_end.py [--seeds 31 32] [--scale 0.5] [--presets canal moved ...]
        [--cache DIR]
"""

from __future__ import annotations

import argparse
import copy
import pickle
import tempfile
import time
from pathlib import Path

import numpy as np

from calib_core.geometry import invert_T, pose_error, rotvec_from_T
import calib_core.solve.rig as rig_module
from calib_core.solve.refine import refine
from calib_core.detect.image import fit as image_fit
from calib_core.pipeline import SessionData, detect_session
from calib_core.session import load_session
from calib_core.solve.calibrate import calibrate_session
from calib_core.synth.generate import generate_session
from calib_core.synth.ground_truth import load_ground_truth
from calib_core.synth.presets import PRESETS


def _image_truth(gt: dict, cid: str, cam: str) -> dict:
    return ((gt["captures"].get(cid) or {}).get("images") or {}).get(cam) or {}


def detection_counts(gt: dict, dets: dict, cam: str, used: set, tol_px: float = 3.0) -> tuple[str, int, list]:
    """("found/visible", false used, wrong): image detections within ``tol_px`` of the true
    projected centre among images showing the whole sphere; used captures whose image centre is
    more than ``tol_px`` off (or whose target moved) -- a false detection that reached the solve;
    the captures whose image centre is more than ``tol_px`` off (a gate that flags one is right)."""
    visible = found = false_used = 0
    wrong = []
    for cid, d in dets.items():
        truth = _image_truth(gt, cid, cam)
        e = d.get(cam) or {}
        uv = e.get("center")
        off = (None if uv is None or truth.get("center_uv_px") is None
               else float(np.hypot(*(np.asarray(uv, float) - truth["center_uv_px"]))))
        whole = truth.get("visible") and truth.get("in_image") and (truth.get("occluded_fraction") or 0) < 0.05
        if whole:
            visible += 1
            found += off is not None and off <= tol_px
        if cid in used and (off is None or off > tol_px or (gt["captures"][cid].get("moved_m") or 0) > 0.01):
            false_used += 1
        if off is not None and off > tol_px:
            wrong.append(cid)
    return f"{found}/{visible}", false_used, sorted(wrong)


def without_limb_floor(dets: dict, fraction: float) -> dict:
    """The detections with the image centres' covariance as stated before the twenty-fourth round
    (without the lopsided limb's floor, ``fraction`` x width: calib_core.detect.image.fit.EDGE_WIDTH_FRACTION
    when they were detected)."""
    out = copy.deepcopy(dets)
    for per_cam in out.values():
        for e in per_cam.values():
            w = e.get("edge_width_px")
            if e.get("cov_px2") is None or w is None or not np.isfinite(w) or w <= 0 or "center" not in e:
                continue
            C = np.asarray(e["cov_px2"], float).reshape(2, 2) - (fraction * w) ** 2 * np.eye(2)
            e["cov_px2"] = C.ravel().tolist()
    return out


def stereo_as_stated(prob_free, state, robust=None):
    """``--before``: stands in for calib_core.solve.stereo_factor.stereo_factor (factor 1, the
    scale-free fit as solve_rig then takes it; harmless on the code before the round, which has none)."""
    return 1.0, {"factor": 1.0}, prob_free, refine(prob_free, state, robust=robust)


def run_one(folder: Path, preset: str, seed: int, scale: float, cached: bool = False, keep: bool = False,
            before: bool = False) -> list[list]:
    """``cached``: ``folder`` is a cache (bench_image_sessions.py's naming); reuse a session there.
    ``keep``: keep the detections in the cache too and reuse them. ``before``: as before the
    twenty-fourth round (no limb floor on image centres, the stereo covariance as stated)."""
    root = folder / (f"{preset}-s{seed}-x{scale:g}" if cached else f"{preset}-{seed}")
    if not (cached and (root / "ground_truth.yaml").is_file()):
        generate_session(root, preset, seed, scale=scale)
    session, gt = load_session(root), load_ground_truth(root)
    t0 = time.perf_counter()
    pk = root / "e2e_detections.pkl"
    if keep and pk.is_file():
        kept = pickle.loads(pk.read_bytes())
    else:
        kept = {"detections": detect_session(SessionData(session), {}),
                "limb_fraction": getattr(image_fit, "EDGE_WIDTH_FRACTION", 0.0)}
        if keep:
            pk.write_bytes(pickle.dumps(kept))
    dets = kept["detections"]
    t_det = time.perf_counter() - t0
    if before:
        dets = without_limb_floor(dets, kept["limb_fraction"])
    targets = {c for c, v in gt["captures"].items() if v.get("target", True)}
    missed = sum(1 for c, d in dets.items() if c in targets for e in d.values() if e.get("center") is None)
    moved = sorted(c for c, v in gt["captures"].items() if (v.get("moved_m") or 0) > 0.01)
    try:
        t0 = time.perf_counter()
        # detections were just made: do not let calibrate re-detect the auto entries
        # the product's defaults: the range scale estimated where observable and a test finds it
        res = calibrate_session(session, dets, {"detect": False})
        t_cal = time.perf_counter() - t0
    except Exception as e:  # report, do not stop the sweep
        return [[preset, seed, "-", f"FAILED: {str(e)[:90]}"]]
    rows = []
    for cam, c in res["cameras"].items():
        T, T_true = np.asarray(c["T_cam_sonar"]), gt["cameras"][cam]["T_cam_sonar"]
        rot, t = pose_error(T, T_true)
        # the reported covariance is on (rotation vector, translation): squared Mahalanobis
        # distance of the true error per degree of freedom, ~1 when the uncertainty is honest
        e = np.r_[rotvec_from_T(T @ invert_T(T_true)), T[:3, 3] - T_true[:3, 3]]
        m2 = float(e @ np.linalg.solve(np.asarray(c["covariance"], float)[:6, :6], e) / 6)
        flagged = sorted(o.get("capture", "?") if isinstance(o, dict) else str(o) for o in c.get("outliers", []))
        scale = res.get("range_scale", {})
        recall, false_used, wrong = detection_counts(gt, dets, cam, set(c["captures_used"]))
        rows.append([preset, seed, cam, f"{np.degrees(rot):.3f}", f"{t * 1000:.1f}",
                     f"{len(c['captures_used'])}/{len(targets)}", missed, recall, false_used,
                     ",".join(flagged) or "-",
                     ",".join(moved) or "-",
                     f"{scale.get('value', 1.0):.4f}/{gt.get('range_scale', 1.0):.3f}" if scale.get("estimated") else "-",
                     f"{m2:.2f}", f"{t_det:.1f}", f"{t_cal:.2f}", ",".join(wrong) or "-"])
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[31, 32])
    ap.add_argument("--scale", type=float, default=0.5, help="image resolution factor")
    ap.add_argument("--presets", nargs="+", default=[p for p in PRESETS if p != "wrongdiam"])
    ap.add_argument("--cache", help="keep generated sessions in this folder and reuse them (as bench_image_sessions.py)")
    ap.add_argument("--keep-detections", action="store_true", help="keep detections in --cache and reuse them")
    ap.add_argument("--before", action="store_true",
                    help="detections as before the twenty-fourth round (image centres without the limb floor) and "
                         "no stereo variance factor; run it with PYTHONPATH at the code before the round for its "
                         "solver (the cached detections made by the current code)")
    args = ap.parse_args()
    if args.before:
        rig_module.stereo_factor = stereo_as_stated
    head = ["preset", "seed", "cam", "rot deg", "t mm", "used", "not found", "image <=3px/whole",
            "false used", "flagged", "truly moved",
            "scale est/true", "mahal2/dof", "detect s", "solve s", "image > 3 px off"]
    print(" | ".join(head))
    errs, counts = [], []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(args.cache) if args.cache else Path(tmp)
        for seed in args.seeds:
            for preset in args.presets:
                for row in run_one(folder, preset, seed, args.scale, bool(args.cache),
                                   args.keep_detections and bool(args.cache), args.before):
                    print(" | ".join(str(v) for v in row), flush=True)
                    if len(row) > 4:
                        errs.append((float(row[3]), float(row[4]), float(row[12])))
                        flagged = set() if row[9] == "-" else set(row[9].split(","))
                        # flagged rightly: the target moved, or the image detection is false
                        moved = set() if row[10] == "-" else set(row[10].split(","))
                        moved |= set() if row[15] == "-" else set(row[15].split(","))
                        counts.append((len(flagged - moved), int(row[5].split("/")[0]) + len(flagged - moved),
                                       int(row[8]), row[11] != "-" and row[11].endswith("/1.000")))
    if errs:
        e = np.array(errs)
        print(f"\nover {len(e)} camera solves: rotation RMS {np.sqrt(np.mean(e[:, 0] ** 2)):.3f} deg "
              f"(max {e[:, 0].max():.3f}), translation RMS {np.sqrt(np.mean(e[:, 1] ** 2)):.1f} mm "
              f"(max {e[:, 1].max():.1f}); pose error / stated covariance: mean squared Mahalanobis "
              f"per dof {e[:, 2].mean():.2f} (1 = honest)")
        c = np.array(counts, float)
        print(f"good captures flagged: {int(c[:, 0].sum())} of {int(c[:, 1].sum())} "
              f"({100 * c[:, 0].sum() / max(c[:, 1].sum(), 1):.1f} %); false detections used: {int(c[:, 2].sum())}; "
              f"camera solves with a range scale estimated on a session without one: {int(c[:, 3].sum())}")
    print("wrongdiam is left out: with a wrong diameter the sonar refuses the sphere and names the "
          "diameter it sees (by design; see sonarcal detect)")


if __name__ == "__main__":
    main()
