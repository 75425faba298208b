"""Side-lit balls: the image centre's shift towards the light against its stated covariance (issue 11/12).

Three sources of hits (detections within 3 px of the true projected centre):
- ``--sidelit N``: matte balls rendered with the tests' analytic maker (tests/test_detect_image_scenes.py,
  exact silhouette, Lambertian shading from a light at a random side share and azimuth, ambient
  0-40 %, a flat background of 5, 20 or 60 DN, blur 0.5-1.5 px), random per seed;
- ``--kinds``: cached image kinds of bench_image_presets.py (``--cache``; renders the missing ones);
- ``--sessions``: session folders holding ground_truth.yaml and e2e_detections.pkl
  (bench_end_to_end.py --cache DIR --keep-detections, detected with this code).
Per group: the RMS error, the RMS stated sigma per axis and the mean squared Mahalanobis distance
(2 for an honest covariance; share beyond 9.21, 1 % for a Gaussian), without ("before") and with the
lopsided limb's floor (calib_core.detect.image.limb; "before" = the stated covariance less the
floor the detection records as ``lopsided_limb_px``: the same detection, centre unchanged); for
sessions also the mean offset per camera (px) and its size against the stated sigma.

    .venv/bin/python benchmarks/bench_limb_shift.py --sidelit 60 [--kinds dim,underwater --seeds 20
        --cache DIR] [--sessions DIR/canal-s41-x0.5 ...]
"""

from __future__ import annotations

import argparse
import pickle
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

import benchmarks.bench_image_presets as bip  # noqa: E402
from benchmarks._table import print_table  # noqa: E402
from calib_core.detect.image.detect import detect_sphere_in_image  # noqa: E402
from calib_core.synth.ground_truth import load_ground_truth  # noqa: E402

CHI2_2_99 = 9.21
TOL_PX = 3.0


def sidelit_case(seed: int):
    """(image, camera, sphere radius m, true centre px, label) of one side-lit matte ball."""
    from test_detect_image_scenes import make_camera, render, sphere_pose_at

    rng = np.random.default_rng(seed)
    cam = make_camera(960, 540, 600.0)
    C = sphere_pose_at(cam, rng.uniform([300, 170], [660, 370]), rng.uniform(0.5, 2.0))
    az, side = rng.uniform(0, 2 * np.pi), rng.uniform(0.2, 1.0)
    to_light = np.array([side * np.cos(az), side * np.sin(az), -np.sqrt(1 - side ** 2)])
    ambient, bg_dn = rng.uniform(0.0, 0.4), float(rng.choice([5.0, 20.0, 60.0]))
    bg = np.full((540, 960, 3), bg_dn, np.float32)
    img, truth = render(cam, bg, C, 0.11, rng, colour=tuple(rng.uniform(120, 250, 3)), mesh=False, chain=False,
                        blur_px=rng.uniform(0.5, 1.5), noise=rng.uniform(0.5, 3.0), light=(to_light, ambient))
    return img, cam, 0.11, truth, f"sidelit bg {bg_dn:.0f}"


def _row(err, cov, lop_px) -> tuple:
    """(error (2,), stated covariance after (2,2), before (2,2))."""
    cov = np.asarray(cov, float).reshape(2, 2)
    return np.asarray(err, float), cov, cov - float(lop_px or 0.0) ** 2 * np.eye(2)


def _hit(det, truth) -> tuple | None:
    if not det.found:
        return None
    d = det.center_uv_px - np.asarray(truth, float)
    return _row(d, det.cov_uv_px2, det.extras.get("lopsided_limb_px")) if np.hypot(*d) <= TOL_PX else None


def _summary(name: str, rows: list) -> list:
    e = np.array([r[0] for r in rows])
    m2 = {k: np.array([float(r[0] @ np.linalg.solve(r[k], r[0])) for r in rows]) for k in (1, 2)}
    sd = {k: np.sqrt(np.mean([np.trace(r[k]) / 2 for r in rows])) for k in (1, 2)}
    return [name, len(rows), f"{np.sqrt(np.mean((e ** 2).sum(axis=1))):.3f}", f"{sd[2]:.3f} / {sd[1]:.3f}",
            f"{m2[2].mean():.2f} / {m2[1].mean():.2f}", f"{np.mean(m2[2] > CHI2_2_99):.2f} / {np.mean(m2[1] > CHI2_2_99):.2f}"]


def _session_rows(folder: Path, groups: dict, offsets: list) -> None:
    gt = load_ground_truth(folder)
    dets = pickle.loads((folder / "e2e_detections.pkl").read_bytes())["detections"]
    per_cam = defaultdict(list)
    for cid, cams in dets.items():
        for cam, e in cams.items():
            t = ((gt["captures"].get(cid) or {}).get("images") or {}).get(cam) or {}
            whole = t.get("visible") and t.get("in_image") and (t.get("occluded_fraction") or 0) < 0.05
            if not whole or e.get("center") is None or e.get("cov_px2") is None:
                continue
            d = np.asarray(e["center"], float) - np.asarray(t["center_uv_px"], float)
            if np.hypot(*d) <= TOL_PX:
                per_cam[cam].append(_row(d, e["cov_px2"], e.get("lopsided_limb_px")))
    for cam, rows in sorted(per_cam.items()):
        groups[f"{folder.name} {cam}"] = rows
        mean = np.mean([r[0] for r in rows], axis=0)
        sd = {k: np.sqrt(np.mean([np.trace(r[k]) / 2 for r in rows])) for k in (1, 2)}
        offsets.append([f"{folder.name} {cam}", len(rows), f"({mean[0]:+.3f}, {mean[1]:+.3f})",
                        f"{np.hypot(*mean):.3f}", f"{sd[2]:.3f} / {sd[1]:.3f}"])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sidelit", type=int, default=0, help="this many side-lit renders")
    ap.add_argument("--sidelit-first", type=int, default=0)
    ap.add_argument("--kinds", default="")
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first", type=int, default=1000)
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--cache", type=Path, default=None)
    ap.add_argument("--sessions", nargs="*", type=Path, default=[])
    a = ap.parse_args(argv)
    bip.CACHE = a.cache
    groups, offsets = defaultdict(list), []
    for seed in range(a.sidelit_first, a.sidelit_first + a.sidelit):
        img, cam, r_m, truth, label = sidelit_case(seed)
        hit = _hit(detect_sphere_in_image(img, cam, r_m), truth)
        if hit is not None:
            groups["sidelit"].append(hit)
            groups[label].append(hit)
    for kind in filter(None, a.kinds.split(",")):
        for seed in range(a.first, a.first + a.seeds):
            case = bip._case(kind, seed, a.scale)
            hit = _hit(detect_sphere_in_image(case.image, case.cam, case.radius_m), case.true_uv_px)
            if hit is not None:
                groups[kind].append(hit)
                groups[f"{kind} {case.label.split('/')[1]}"].append(hit)
    for folder in a.sessions:
        _session_rows(folder, groups, offsets)
    print_table(["case", "hits", "RMS error px", "RMS stated sigma px (before / now)",
                 "mean Mahalanobis^2 (before / now)", "share > 9.21 (before / now)"],
                [_summary(k, v) for k, v in sorted(groups.items()) if v],
                "Centre errors against the stated covariance, without / with the lopsided limb's floor")
    if offsets:
        print_table(["session camera", "hits", "mean offset px (u, v)", "its size px", "RMS stated sigma px (before / now)"],
                    offsets, "Sessions: the shift every capture shares")
    print("load average:", Path("/proc/loadavg").read_text().split()[:3])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
