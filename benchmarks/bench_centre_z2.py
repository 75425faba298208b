"""Image centres: the real error against the stated covariance, by apparent radius (and edge width).

Reads sessions and their detections cached by bench_scale_clean.py (``--cache``; each session
folder holds ground_truth.yaml and scale3_detections.pkl) and compares every image detection
within 3 px of the true projected centre, on an image showing the whole sphere, with its stated
covariance: squared Mahalanobis distance per dof (z^2, 1 = honest) per radius bin, the RMS error
and the RMS stated sigma. ``--model`` recomputes the stated covariance from the fit's part
(stated minus the old floor, SYS_FRACTION x edge RMS per axis) with the current floor of
calib_core.detect.image.fit (``current``) or the floor before this round (``old``), so before and
after are compared on the same detections.

    .venv/bin/python benchmarks/bench_centre_z2.py --cache DIR [--model old current] [--pickle e2e_detections.pkl
        --carried current]
"""

from __future__ import annotations

import argparse
import pickle
from pathlib import Path

import numpy as np

from calib_core.detect.image import fit as image_fit
from calib_core.detect.image.blur import blur_floor_px2
from calib_core.synth.ground_truth import load_ground_truth

RADIUS_BINS = (0, 20, 30, 45, 60, 80, 1000)
OLD_SYS_FRACTION = 0.2


def samples(cache: Path, name: str = "scale3_detections.pkl", carried: str = "old"):
    """(error uv px (2,), fit-only covariance (2,2), radius px, edge RMS px, edge width px, blur floor
    applies?) per right detection; ``carried``: the floor the cached detections' covariance holds
    ("old": made before this round's change, "current": after)."""
    out = []
    for root in sorted(p for p in cache.iterdir() if (p / name).is_file()):
        gt = load_ground_truth(root)
        dets = pickle.loads((root / name).read_bytes())
        dets = dets.get("detections", dets) if "detections" in dets else dets
        for cid, per_cam in dets.items():
            for cam, e in per_cam.items():
                t = ((gt["captures"].get(cid) or {}).get("images") or {}).get(cam) or {}
                whole = t.get("visible") and t.get("in_image") and (t.get("occluded_fraction") or 0) < 0.05
                if not whole or e.get("center") is None or e.get("cov_px2") is None or t.get("center_uv_px") is None:
                    continue
                err = np.asarray(e["center"], float) - np.asarray(t["center_uv_px"], float)
                if np.hypot(*err) > 3.0:
                    continue
                rms, rad = float(e.get("edge_rms_px") or 0.0), float(e.get("radius_px") or np.nan)
                w = float(e.get("edge_width_px") or np.nan)
                blur_ok = (e.get("support") or 0) >= image_fit.TIGHT_MIN_SUPPORT
                C = np.asarray(e["cov_px2"], float).reshape(2, 2) - floor_px2(carried, rms, rad, w, blur_ok) * np.eye(2)
                out.append((err, C, rad, rms, w, blur_ok))
    return out


def floor_px2(model: str, rms: float, radius: float, width: float, blur_ok: bool) -> float:
    """The floor per axis (px^2): before this round (SYS_FRACTION x edge RMS and the blur plateau)
    or now (calib_core.detect.image.fit.centre_floor_px2)."""
    if model == "old":
        return (OLD_SYS_FRACTION * rms) ** 2 + (blur_floor_px2(radius, width) if blur_ok else 0.0)
    return image_fit.centre_floor_px2(rms, radius, width, blur_ok)


def stated(row, model: str) -> np.ndarray:
    _, C, rad, rms, w, blur_ok = row
    return C + floor_px2(model, rms, rad, w, blur_ok) * np.eye(2)


def table(rows, model: str) -> None:
    print(f"model: {model}")
    print("radius px | n | median edge RMS px | z^2 per dof (mean) | median | RMS error px | RMS stated sigma px")
    z2 = np.array([float(r[0] @ np.linalg.solve(stated(r, model), r[0])) / 2 for r in rows])
    sig = np.array([np.sqrt(np.trace(stated(r, model)) / 2) for r in rows])
    err2 = np.array([float(r[0] @ r[0]) / 2 for r in rows])
    rad = np.array([r[2] for r in rows])
    for lo, hi in zip(RADIUS_BINS[:-1], RADIUS_BINS[1:]):
        m = (rad >= lo) & (rad < hi)
        if not m.any():
            continue
        print(f"{lo}-{hi} | {m.sum()} | {np.median([r[3] for r, k in zip(rows, m) if k]):.2f} | {z2[m].mean():.2f} | "
              f"{np.median(z2[m]):.2f} | {np.sqrt(err2[m].mean()):.3f} | {np.sqrt(np.mean(sig[m] ** 2)):.3f}")
    print(f"all | {len(rows)} | - | {z2.mean():.2f} | {np.median(z2):.2f} | share z^2 > 4.6 (1 % for chi2(2)/2): "
          f"{100 * np.mean(z2 > 4.6):.1f} %\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", required=True)
    ap.add_argument("--pickle", default="scale3_detections.pkl",
                    help="detections file in each session folder (bench_end_to_end.py --keep-detections: "
                         "e2e_detections.pkl)")
    ap.add_argument("--carried", choices=("old", "current"), default="old",
                    help="the floor the cached detections carry (made before / after this round's change)")
    ap.add_argument("--model", nargs="+", default=["old", "current"], choices=("old", "current"))
    args = ap.parse_args()
    rows = samples(Path(args.cache), args.pickle, args.carried)
    for m in args.model:
        table(rows, m)


if __name__ == "__main__":
    main()
