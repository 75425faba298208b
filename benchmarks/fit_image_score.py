"""Fit the image detection's probability model (calib_core/detect/image_score.py) and measure it.

One command for the lead: it collects labelled detections (``benchmarks/score_samples.py``:
training = synthetic cases seeds 0-39 and sessions seeds 1-3, hard negatives included; test =
cases seeds 1000-1039, sessions seeds 41-60, kinectnet), fits the model on the training set
only, and prints the coefficients to paste into ``image_score.COEF`` and the reliability tables
of the test sets for the model in the code now and for the new fit. Records are cached per
source in ``--cache`` (``--fresh`` re-detects everything, e.g. after a detector change).

Run: .venv/bin/python benchmarks/fit_image_score.py [--fresh] [--quick]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import score_samples as ss  # noqa: E402

from calib_core.detect import image_score  # noqa: E402
from calib_core.detect.image_fit import clean_rms_px  # noqa: E402
from calib_core.synth.image_cases import KINDS  # noqa: E402

SESSION_PRESETS = ("lidar-chair", "rgbd-stick", "rgbd-table", "clutter", "seabed-slab", "decoys", "review")
TEST_SESSION_PRESETS = ("lidar-chair", "rgbd-stick", "rgbd-table", "clutter", "seabed-slab")
KINECTNET = (ROOT.parent.parent / "shared" / "data" / "kinectnet-dev", Path("/work/shared/data/kinectnet-dev"))


def sources(quick: bool) -> dict:
    """name -> (function making the records, is it training data)."""
    n_tr, n_te = (10, 10) if quick else (40, 40)
    s_tr, s_te = (range(1, 2), range(41, 44)) if quick else (range(1, 4), range(41, 61))
    sess = Path("/tmp/sonarcal-image-sessions")
    out = {
        "cases-train": (lambda: ss.case_records(KINDS, range(n_tr), 0.4, True), True),
        "sessions-train": (lambda: ss.session_records(SESSION_PRESETS, s_tr, 0.5, sess, True), True),
        "cases-test": (lambda: ss.case_records(KINDS, range(1000, 1000 + n_te), 0.5, False), False),
        "sessions-test": (lambda: ss.session_records(TEST_SESSION_PRESETS, s_te, 0.5, sess, False), False),
    }
    kn = next((p for p in KINECTNET if (p / "session.yaml").is_file()), None)
    if kn is not None:
        out["kinectnet"] = (lambda: ss.kinectnet_records(kn, ROOT / "benchmarks" / "data" / "kinectnet_centres.yaml"),
                            False)
    return out


def load(name: str, make, cache: Path, fresh: bool) -> np.ndarray:
    f = cache / f"{name}.npy"
    if f.is_file() and not fresh:
        return np.load(f)
    print(f"collecting {name} ...", flush=True)
    R = make()
    cache.mkdir(parents=True, exist_ok=True)
    np.save(f, R)
    return R


def feature_matrix(R: np.ndarray) -> np.ndarray:
    """image_score.features of every record."""
    col = {k: i for i, k in enumerate(ss.FIELDS)}
    rows = []
    for r in R:
        extras = {k: r[col[k]] for k in ("outline_coverage", "edge_rms_px", "outside_mismatch", "edge_contrast",
                                         "runner_up_ratio")}
        rows.append(image_score.features(extras, r[col["radius_px"]], clean_rms_px(r[col["radius_px"]])))
    return np.array(rows).reshape(-1, len(image_score.FEATURES))


def scored(R: np.ndarray, p: np.ndarray, hinted: bool | None = False):
    y = R[:, ss.FIELDS.index("right")] > 0.5
    h = R[:, ss.FIELDS.index("hinted")] > 0.5
    m = np.ones(len(R), bool) if hinted is None else (h == hinted)
    return list(zip(p[m], y[m]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", default="/tmp/sonarcal-score-samples")
    ap.add_argument("--fresh", action="store_true", help="re-detect every source")
    ap.add_argument("--quick", action="store_true", help="few seeds (a smoke run)")
    ap.add_argument("--l2", type=float, default=image_score.L2)
    a = ap.parse_args(argv)
    cache = Path(a.cache) / ("quick" if a.quick else "full")
    data = {name: (load(name, make, cache, a.fresh), train) for name, (make, train) in sources(a.quick).items()}
    train = np.vstack([R for R, t in data.values() if t])
    X, y = feature_matrix(train), train[:, ss.FIELDS.index("right")]
    hinted = train[:, ss.FIELDS.index("hinted")]
    print(f"\ntraining: {len(y)} detections, {int(y.sum())} right, {int(len(y) - y.sum())} wrong "
          f"({int(hinted.sum())} from hinted looks, {int(((hinted > 0) & (y < 1)).sum())} of them wrong)")
    model = image_score.fit(X, y, l2=a.l2)
    print("features:", ("intercept",) + image_score.FEATURES)
    print("COEF = np.array([" + ", ".join(f"{v:.4f}" for v in model.coef) + "])")
    print("ISO_X = np.array([" + ", ".join(f"{v:.4f}" for v in model.iso_x) + "])")
    print("ISO_Y = np.array([" + ", ".join(f"{v:.4f}" for v in model.iso_y) + "])")
    for name, (R, t) in data.items():
        if len(R) == 0:
            continue
        F = feature_matrix(R)
        p_new = np.array([model.probability(x) for x in F])
        p_now = R[:, ss.FIELDS.index("score_now")]
        for label, p in (("detector's score as run", p_now), ("new fit", p_new)):
            for h in ((False, True) if t else (False,)):
                look = "hinted looks" if h else "free search"
                print(image_score.reliability_table(scored(R, p, h),
                                                    f"{name} ({'TRAINING' if t else 'test'}), {look}: {label}"))
    print("load average:", Path("/proc/loadavg").read_text().split()[:3])
    return 0


if __name__ == "__main__":
    sys.exit(main())
