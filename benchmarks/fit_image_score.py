"""Fit the image detection's probability model (calib_core/detect/image_score.py COEF).

Training data: synthetic cases (calib_core.synth.image_cases) of every kind (clutter, big,
turbid, chair), seeds [0, N) at 0.4 x 1080p, each rendered with the ball and without it (with and without the
background where the case has one). A detection within 3 px of the true centre is a
positive; any other detection (elsewhere, or in an image without the ball) a negative.
Prints the coefficients to paste into image_score.COEF and the training reliability.

Run: .venv/bin/python benchmarks/fit_image_score.py [--seeds N]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from calib_core.detect.image import detect_sphere_in_image  # noqa: E402
from calib_core.detect.image_fit import clean_rms_px  # noqa: E402
from calib_core.detect.image_score import FEATURES, features, fit_logistic  # noqa: E402
from calib_core.synth.image_cases import KINDS, render_case  # noqa: E402

TOL_PX = 3.0


def samples(seeds, scale):
    X, y = [], []
    for kind in KINDS:
        for seed in seeds:
            for with_ball in (True, False):
                case = render_case(kind, seed, scale, with_ball=with_ball)
                for bg in ((case.background, None) if case.background is not None else (None,)):
                    det = detect_sphere_in_image(case.image, case.cam, case.radius_m, background=bg)
                    if not det.found:
                        continue
                    ok = with_ball and float(np.hypot(*(det.center_uv_px - case.true_uv_px))) <= TOL_PX
                    r = det.radius_px
                    X.append(features(det.extras, r, clean_rms_px(r)))
                    y.append(float(ok))
    return np.array(X), np.array(y)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=60)
    ap.add_argument("--scale", type=float, default=0.4)
    ap.add_argument("--l2", type=float, default=0.1, help="ridge weight (the data are nearly separable)")
    ap.add_argument("--save", help="also write the samples to this .npz")
    a = ap.parse_args(argv)
    X, y = samples(range(a.seeds), a.scale)
    if a.save:
        np.savez(a.save, X=X, y=y)
    w = fit_logistic(X, y, l2=a.l2)
    print(f"{len(y)} detections, {int(y.sum())} right, {int(len(y) - y.sum())} wrong")
    print("features:", ("intercept",) + FEATURES)
    print("COEF = np.array([" + ", ".join(f"{v:.4f}" for v in w) + "])")
    p = 1 / (1 + np.exp(-(w[0] + X @ w[1:])))
    for lo, hi in ((0, 0.5), (0.5, 0.8), (0.8, 0.95), (0.95, 1.01)):
        m = (p >= lo) & (p < hi)
        if m.any():
            print(f"  p in [{lo:.2f}, {min(hi, 1):.2f}): {m.sum():4d} detections, mean p {p[m].mean():.3f}, "
                  f"right {y[m].mean():.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
