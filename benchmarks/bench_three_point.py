"""How far off the predictions of a rig registration on only 3 plain detections are, where the
pipeline trusts them (issue 11, seventh round: ``pipeline._trusted`` on 3 plain detections checked
by partly hidden outlines).

For each cached session of ``bench_image_sessions.py`` (run that first; sonar entries cached by
its ``--flow``), the session flow gives each camera's plain detections. Many times over, 3 of the
right ones are kept plain, 2 others become "partly hidden outlines" (centre and range disturbed as
stated by ``--partial-px`` / ``--partial-range``) and the rest become images with nothing. The
registration (:func:`calib_core.disambiguate.image.resolve_candidates`) then predicts where those are;
the table compares each prediction the pipeline would trust with the truth. No image is looked at
again: this measures the gate, not the look.

    python benchmarks/bench_three_point.py [--presets lidar-chair clutter] [--seeds 41-60] [--trials 20]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.bench_image_sessions import parse_seeds, session_dir  # noqa: E402
from benchmarks.image_flow import _sonar_only  # noqa: E402
from calib_core.disambiguate.image import resolve_candidates  # noqa: E402
from calib_core import pipeline  # noqa: E402
from calib_core.pipeline import SessionData, _expected_error_px, _trusted, detect_session  # noqa: E402
from calib_core.session import load_session  # noqa: E402
from calib_core.synth.ground_truth import load_ground_truth  # noqa: E402


def _plain(dets: dict, gt: dict, cam: str) -> dict:
    """{capture: (u, v, range_m, truth_uv)} for the right (<= 1 px) plain detections with a sonar centre."""
    out = {}
    for cid, d in dets.items():
        e, son = d.get(cam) or {}, d.get("sonar") or {}
        truth = gt["captures"][cid]["images"][cam].get("center_uv_px")
        if e.get("center") is None or son.get("center") is None or truth is None or not e.get("range_m"):
            continue
        if np.hypot(*(np.asarray(e["center"]) - truth)) <= 1.0:
            out[cid] = (*e["center"], float(e["range_m"]), np.asarray(truth, float))
    return out


def _trial(model, centres: dict, plain: dict, rng, a) -> list:
    """[(actual px, expected px)] for the predictions trusted in one random trial."""
    ids = list(plain)
    rng.shuffle(ids)
    keep, rough, lost = ids[:3], ids[3:5], ids[5:]
    cands = {c: np.array([plain[c][:3]]) for c in keep}
    for c in rough:
        u, v, r = plain[c][:3]
        cands[c] = np.array([[u + rng.normal(0, a.partial_px), v + rng.normal(0, a.partial_px), r * (1 + rng.normal(0, a.partial_range))]])
    res = resolve_candidates(model, centres, cands, predict_for=rough + lost, rough=rough)
    out = []
    for c, (u, v, r) in res.predicted_uvr.items():
        if c in lost + rough and _trusted(res, len(cands), c):
            exp = _expected_error_px(res, c) if res.support == 3 else float("nan")
            out.append((float(np.hypot(u - plain[c][3][0], v - plain[c][3][1])), exp, res.support, abs(r / plain[c][2] - 1)))
    return out


def rng_txt(rows: list) -> str:
    """"median / max" of the trusted predictions' relative range errors, in %."""
    if not rows:
        return "-"
    e = np.array([r[3] for r in rows]) * 100
    return f"{np.median(e):.1f} / {np.max(e):.1f} %"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--presets", nargs="+", default=["lidar-chair", "clutter"])
    ap.add_argument("--seeds", default="41-60")
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--cache", default="/tmp/sonarcal-image-sessions")
    ap.add_argument("--trials", type=int, default=20, help="random trials per session and camera")
    ap.add_argument("--partial-px", type=float, default=3.0, help="partly hidden outline centre error, px per axis (1 sigma)")
    ap.add_argument("--partial-range", type=float, default=0.03, help="its range error, relative (1 sigma)")
    ap.add_argument("--max-error", type=float, default=None, help="try another pipeline.CHECKED_MAX_ERROR_PX")
    a = ap.parse_args()
    if a.max_error is not None:
        pipeline.CHECKED_MAX_ERROR_PX = a.max_error
    print(f"CHECKED_MAX_ERROR_PX = {pipeline.CHECKED_MAX_ERROR_PX}")
    print("| preset | sessions x cameras | trials | trials with a trusted 3-point prediction | trusted predictions | error median / max (px) | > 3 px | > 4 px | actual / expected (median) | range error median / max |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for preset in a.presets:
        rows, n_sc, n_trials, n_hit = [], 0, 0, 0
        for seed in parse_seeds(a.seeds):
            root = session_dir(Path(a.cache), preset, seed, a.scale)
            data, gt = SessionData(load_session(root)), load_ground_truth(root)
            dets = detect_session(data, _sonar_only(root, data), workers=1)
            rng = np.random.default_rng(seed)
            for cam in data.session.cameras:
                plain = _plain(dets, gt, cam)
                if len(plain) < 6:
                    continue
                n_sc += 1
                centres = {c: np.asarray(dets[c]["sonar"]["center"], float) for c in plain}
                for _ in range(a.trials):
                    got = [g for g in _trial(data.camera(cam), centres, plain, rng, a) if g[2] == 3]
                    n_trials += 1
                    n_hit += bool(got)
                    rows += got
        err = np.array([r[0] for r in rows]) if rows else np.array([np.nan])
        ratio = np.median([r[0] / r[1] for r in rows]) if rows else float("nan")
        print(f"| {preset} | {n_sc} | {n_trials} | {n_hit} | {len(rows)} | {np.median(err):.2f} / {np.max(err):.2f} | "
              f"{int(np.sum(err > 3))} | {int(np.sum(err > 4))} | {ratio:.2f} | {rng_txt(rows)} |")
    print("partial outlines: centre", a.partial_px, "px per axis, range", a.partial_range, "relative (1 sigma); scale", a.scale)
    print("load average:", Path("/proc/loadavg").read_text().split()[:3])
    return 0


if __name__ == "__main__":
    sys.exit(main())
