"""Image centres: the real error against the stated covariance, by apparent radius (and edge width).

Reads sessions and their detections cached by bench_scale_clean.py (``--cache``; each session
folder holds ground_truth.yaml and scale3_detections.pkl) and compares every image detection
within 3 px of the true projected centre, on an image showing the whole sphere, with its stated
covariance: squared Mahalanobis distance per dof (z^2, 1 = honest) per radius bin, the RMS error
and the RMS stated sigma. ``--model`` recomputes the stated covariance from the fit's part
(stated minus the old floor, SYS_FRACTION x edge RMS per axis) with the current floor of
calib_core.detect.image.fit (``current``) or the floor before this round (``old``), so before and
after are compared on the same detections.

    .venv/bin/python benchmarks/bench_centre_z2.py --cache DIR [--model old current]
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


def samples(cache: Path):
    """(error uv px (2,), fit-only covariance (2,2), radius px, edge RMS px, edge width px) per right detection."""
    out = []
    for root in sorted(p for p in cache.iterdir() if (p / "scale3_detections.pkl").is_file()):
        gt = load_ground_truth(root)
        dets = pickle.loads((root / "scale3_detections.pkl").read_bytes())
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
                w = w if (e.get("support") or 0) >= image_fit.TIGHT_MIN_SUPPORT else np.nan
                C = np.asarray(e["cov_px2"], float).reshape(2, 2) - old_floor_px2(rms, rad, w) * np.eye(2)
                out.append((err, C, rad, rms, w))
    return out


def old_floor_px2(rms: float, radius: float, width: float) -> float:
    """The floor per axis (px^2) before this round: SYS_FRACTION x edge RMS and the blur plateau."""
    return (OLD_SYS_FRACTION * rms) ** 2 + blur_floor_px2(radius, width)


def stated(C_fit: np.ndarray, radius: float, rms: float, width: float, model: str) -> np.ndarray:
    floor = old_floor_px2(rms, radius, width) if model == "old" else image_fit.centre_floor_px2(rms, radius, width)
    return C_fit + floor * np.eye(2)


def table(rows, model: str) -> None:
    print(f"model: {model}")
    print("radius px | n | median edge RMS px | z^2 per dof (mean) | median | RMS error px | RMS stated sigma px")
    r = np.array([s[2] for s in rows])
    for lo, hi in zip(RADIUS_BINS[:-1], RADIUS_BINS[1:]):
        sel = [s for s, ri in zip(rows, r) if lo <= ri < hi]
        if not sel:
            continue
        z2 = [float(e @ np.linalg.solve(stated(C, rad, rms, w, model), e)) / 2 for e, C, rad, rms, w in sel]
        sig = [np.sqrt(np.trace(stated(C, rad, rms, w, model)) / 2) for e, C, rad, rms, w in sel]
        err = [float(e @ e) / 2 for e, *_ in sel]
        print(f"{lo}-{hi} | {len(sel)} | {np.median([s[3] for s in sel]):.2f} | {np.mean(z2):.2f} | {np.median(z2):.2f} | {np.sqrt(np.mean(err)):.3f} | "
              f"{np.sqrt(np.mean(np.square(sig))):.3f}")
    z2 = [float(e @ np.linalg.solve(stated(C, rad, rms, w, model), e)) / 2 for e, C, rad, rms, w in rows]
    print(f"all | {len(rows)} | {np.mean(z2):.2f} | {np.median(z2):.2f} | share z^2 > 6.9 (1 % for chi2(2)/2): "
          f"{100 * np.mean(np.array(z2) > 6.9):.1f} %\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", required=True)
    ap.add_argument("--model", nargs="+", default=["old", "current"], choices=("old", "current"))
    args = ap.parse_args()
    rows = samples(Path(args.cache))
    for m in args.model:
        table(rows, m)


if __name__ == "__main__":
    main()
