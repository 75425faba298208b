"""The look at a predicted place and size (``calib_core.detect.image.predicted``) on held-out cases.

For rendered single-image cases (``calib_core.synth.image_cases``, kinds chair and clutter, seeds
from 1000), the prediction is the truth disturbed as a rough rig registration would disturb it
(centre off by ``--offset`` px in a random direction, apparent size off by a random ``--size``
fraction). Counted:
- with the ball: found within 3 px / found farther off / not found (with reasons), the largest
  error, and the median error over its stated 1-sigma;
- the same scene rendered without the ball, looked at in the same place: "found" there is a
  false sphere (the null test against texture is what should refuse it).

With ``--range-bias B`` (e.g. 0.02: a 2 % range-scale error of the sonar, so the prediction's
range is off by B on top of the random size error) a second table: the look's range against the
truth, with the size prior (``PRIOR_REL_SIGMA``, as the look runs) and without it (prior sigma
1000 %, the size free): how far the range is pulled towards the prediction (the least-squares
slope of the range's relative error on the prediction's), its mean error, and its error over its
stated sigma. The one-camera apparent-size scale (issue 12) reads ranges: a range pulled towards
the sonar's prediction would pull that scale towards 1. A third row per kind ("free refit"):
the look's own outline refitted with the size free (:func:`free_refit_range`, edge points within
TOL_FRAC radii of the look's outline), the option of recording a size measured without the prior.

Run: .venv/bin/python benchmarks/bench_predicted_look.py [--kinds chair clutter] [--seeds 12] [--range-bias 0.02]
     [--range-only] [--cache DIR]
"""

from __future__ import annotations

import argparse
import pickle
import sys
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from calib_core.detect.image import predicted as image_predicted  # noqa: E402
from calib_core.detect.image.detect import prepare_background  # noqa: E402
from calib_core.detect.image.cone import fit_cone, normalize_near  # noqa: E402
from calib_core.detect.image.fit import CORR_LENGTH_PX, EDGE_SPACING_PX, Signal  # noqa: E402
from calib_core.detect.image.predicted import detect_at_prediction  # noqa: E402
from calib_core.detect.reasons import reason_kind  # noqa: E402
from calib_core.synth.image_cases import render_case  # noqa: E402


TOL_FRAC = 0.1  # free refit: edge points within this many radii (+ INLIER_PX) of the look's outline


def free_refit_range(image, cam, radius_m: float, uv, r_pred: float, background, shift_frac: float,
                     det) -> tuple[float, float] | None:
    """(range m, its stated sigma) of the look's outline refitted with the size free: every edge
    peak along the predicted outline's normals, the nearest per normal within TOL_FRAC radii of
    the look's outline, a free cone fit (:func:`fit_cone`) started at the look's cone."""
    w0, a0 = image_predicted.predicted_cone(cam, uv, r_pred)
    band = max(3.0, shift_frac * r_pred) + (image_predicted.NULL_SHIFT + TOL_FRAC) * r_pred + 2.0
    m, (H, W) = int(r_pred + 2 * band + 8), image.shape[:2]
    box = (max(0, int(uv[0]) - m), max(0, int(uv[1]) - m), min(W, int(uv[0]) + m + 1), min(H, int(uv[1]) + m + 1))
    sig = Signal(image, None if background is None else prepare_background(background).image, box)
    pts, normal_of, _, _, _ = image_predicted.edge_points(cam, sig, w0, a0, band)
    xy = normalize_near(cam, pts)
    w = cam.rays(np.asarray(det.center_uv_px, float).reshape(1, 2))[0]
    w, a = w / np.linalg.norm(w), float(np.arcsin(radius_m / det.range_m))
    q, _, _ = image_predicted._tangent_plane(cam, xy, w)
    Rq = cam.fx * np.tan(a)
    d = np.abs(np.linalg.norm(q, axis=1) - Rq)
    order = np.lexsort((d, normal_of))
    first = np.r_[True, normal_of[order][1:] != normal_of[order][:-1]]
    idx = order[first]
    idx = idx[d[idx] < TOL_FRAC * Rq + image_predicted.INLIER_PX]
    f = fit_cone(cam, xy[idx], start=(w, a), corr_points=CORR_LENGTH_PX / EDGE_SPACING_PX, inlier_px=2.0)
    if f is None:
        return None
    s = radius_m * np.cos(f.a_rad) / np.sin(f.a_rad) ** 2 * np.sqrt(f.cov_params[2, 2])
    return radius_m / np.sin(f.a_rad), float(s)


def _blur_px(case) -> float:
    """The motion kind's blur length (px, from its label "…/12px"); 0 for the other kinds."""
    part = case.label.split("/")[1] if case.label.count("/") >= 2 else ""
    return float(part[:-2]) if part.endswith("px") and part[:-2].isdigit() else 0.0


CACHE: Path | None = None


def _render(kind: str, seed: int, with_ball: bool = True):
    """render_case at scale 0.5, through a pickle cache in CACHE when one is set."""
    if CACHE is None:
        return render_case(kind, seed, 0.5, with_ball=with_ball)
    path = CACHE / f"look_{kind}_{seed}_{int(with_ball)}.pkl"
    if path.exists():
        return pickle.loads(path.read_bytes())
    case = render_case(kind, seed, 0.5, with_ball=with_ball)
    CACHE.mkdir(parents=True, exist_ok=True)
    path.with_suffix(".tmp").write_bytes(pickle.dumps(case))
    path.with_suffix(".tmp").replace(path)
    return case


def run_kind(kind: str, seeds, offset_px: float, size_frac: float, range_bias: float = 0.0,
             with_empty: bool = True, free_refit: bool = False) -> dict:
    st = {"n": 0, "right": 0, "off": 0, "miss": Counter(), "errs": [], "z": [], "blur": [], "false": 0, "empty": 0,
          "range": []}
    for s in seeds:
        rng = np.random.default_rng(s)
        case = _render(kind, s)
        if case.range_m is None:
            continue
        r_px = case.cam.fx * case.radius_m / case.range_m
        ang = rng.uniform(0, 2 * np.pi)
        uv = case.true_uv_px + offset_px * np.array([np.cos(ang), np.sin(ang)])
        r_pred = r_px * (1 + rng.uniform(-size_frac, size_frac)) / (1 + range_bias)
        shift = max(3.0, 2 * offset_px) / r_pred
        det = detect_at_prediction(case.image, case.cam, case.radius_m, uv, r_pred, case.background, shift_frac=shift)
        st["n"] += 1
        if det.found:
            # (range's relative error, prediction's relative range error, error / stated sigma)
            pred_m = case.cam.fx * case.radius_m / r_pred
            rng_m, rng_sigma = det.range_m, det.extras["range_sigma_m"]
            if free_refit:
                fr = free_refit_range(case.image, case.cam, case.radius_m, uv, r_pred, case.background, shift, det)
                rng_m, rng_sigma = fr if fr is not None else (np.nan, np.nan)
            if np.isfinite(rng_m):
                st["range"].append((rng_m / case.range_m - 1, pred_m / case.range_m - 1,
                                    (rng_m - case.range_m) / rng_sigma))
            e = det.center_uv_px - case.true_uv_px
            st["errs"].append(float(np.hypot(*e)))
            st["z"].append(float(np.sqrt(e @ np.linalg.solve(det.cov_uv_px2, e) / 2)))
            st["blur"].append(_blur_px(case))
            st["right" if np.hypot(*e) <= 3 else "off"] += 1
        else:
            st["miss"][reason_kind(det.reason)] += 1
        if not with_empty:
            continue
        empty = _render(kind, s, with_ball=False)
        d0 = detect_at_prediction(empty.image, empty.cam, case.radius_m, uv, r_pred, empty.background, shift_frac=shift)
        st["empty"] += 1
        st["false"] += d0.found
    return st


def _blurred(st: dict) -> str:
    """The found looks on balls blurred by 5 px or more: count, centre RMS, mean Mahalanobis^2."""
    b = np.asarray(st["blur"]) >= 5
    if not b.any():
        return "-"
    e, z = np.asarray(st["errs"])[b], np.asarray(st["z"])[b]
    return f"{b.sum()}, {np.sqrt(np.mean(e ** 2)):.2f}, {2 * np.mean(z ** 2):.2f}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kinds", nargs="+", default=["chair", "clutter"])
    ap.add_argument("--seeds", type=int, default=12)
    ap.add_argument("--offset", type=float, default=3.0, help="prediction's centre error (px)")
    ap.add_argument("--size", type=float, default=0.03, help="prediction's relative size error (uniform +-)")
    ap.add_argument("--range-bias", type=float, default=0.0,
                    help="prediction's range off by this fraction too: adds the range table (with / without the prior)")
    ap.add_argument("--range-only", action="store_true", help="only the range table (with --range-bias)")
    ap.add_argument("--cache", type=Path, default=None, help="keep the rendered cases here (rendering is most of the time)")
    a = ap.parse_args(argv)
    global CACHE
    CACHE = a.cache
    seeds = range(1000, 1000 + a.seeds)
    print(f"Look at the predicted place and size, seeds 1000-{999 + a.seeds}, scale 0.5, prediction off by "
          f"{a.offset:g} px and up to {100 * a.size:g} % in size")
    print("| kind | cases | found within 3 px | found > 3 px off | not found (reason: count) | max err (px) "
          "| median err / sigma | mean Mahalanobis^2 (2 = right) | found, blur >= 5 px: n, centre RMS (px), mean Mahalanobis^2 "
          "| scenes without the ball: found (false) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for kind in [] if a.range_only else a.kinds:
        st = run_kind(kind, seeds, a.offset, a.size)
        miss = ", ".join(f"{k}: {v}" for k, v in st["miss"].most_common()) or "-"
        mx = f"{max(st['errs']):.2f}" if st["errs"] else "-"
        z = f"{np.median(st['z']):.2f}" if st["z"] else "-"
        m2 = f"{2 * np.mean(np.square(st['z'])):.2f}" if st["z"] else "-"
        print(f"| {kind} | {st['n']} | {st['right']} | {st['off']} | {miss} | {mx} | {z} | {m2} | {_blurred(st)} "
              f"| {st['false']} of {st['empty']} |")
    if a.range_bias:
        range_table(a.kinds, seeds, a.offset, a.size, a.range_bias)
    print("load average:", Path("/proc/loadavg").read_text().split()[:3])
    return 0


def range_table(kinds, seeds, offset_px: float, size_frac: float, bias: float) -> None:
    """The look's range with and without the size prior, the prediction's range off by ``bias``."""
    print(f"\nThe look's range, prediction's range off by {100 * bias:+g} % (and up to {100 * size_frac:g} % at "
          f"random), seeds {seeds[0]}-{seeds[-1]}")
    print("| kind | size prior | found | pull towards the prediction (slope) | mean range error % | RMS range error % "
          "| RMS error / stated sigma |")
    print("|---|---|---|---|---|---|---|")
    keep = image_predicted.PRIOR_REL_SIGMA
    for kind in kinds:
        for prior, free in ((keep, False), (10.0, False), (keep, True)):
            image_predicted.PRIOR_REL_SIGMA = prior
            try:
                r = np.array(run_kind(kind, seeds, offset_px, size_frac, bias, with_empty=False,
                                      free_refit=free)["range"]).reshape(-1, 3)
            finally:
                image_predicted.PRIOR_REL_SIGMA = keep
            label = f"{100 * prior:g} %" + (", then a free refit" if free else "")
            if not len(r):
                print(f"| {kind} | {label} | 0 | - | - | - | - |")
                continue
            slope = float(np.polyfit(r[:, 1], r[:, 0], 1)[0]) if len(r) > 2 else float("nan")
            print(f"| {kind} | {label} | {len(r)} | {slope:.2f} | {100 * r[:, 0].mean():+.2f} "
                  f"| {100 * np.sqrt(np.mean(r[:, 0] ** 2)):.2f} | {np.sqrt(np.mean(r[:, 2] ** 2)):.2f} |")


if __name__ == "__main__":
    sys.exit(main())
