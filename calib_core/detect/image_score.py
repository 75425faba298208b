"""The image detection's score as a probability: P(the detection is the sphere, within 3 px).

A logistic model on features of the accepted outline, fitted on synthetic training seeds
(``benchmarks/fit_image_score.py``: cluttered rooms, close balls and turbid water rendered
with and without the ball, seeds 0-29 at 0.4 x 1080p; a detection within 3 px of the true
centre is a positive, any other detection a negative). Its calibration is measured on held-out
seeds and on real photographs (``benchmarks/bench_image_presets.py``,
``benchmarks/bench_real_images.py``: reliability tables).

Approximation: synthetic scenes are not real ones; the reliability tables say how far the
probabilities can be trusted on each.
"""

from __future__ import annotations

import numpy as np

FEATURES = ("coverage", "rms_rel", "outside_mismatch", "log_contrast", "runner_up", "log_radius")
# fitted by benchmarks/fit_image_score.py --seeds 40 (training seeds 0-39 only, with and without
# the ball; 197 detections, 150 right, 47 wrong), ridge 0.1, on the second-round detector (its
# outside-mismatch values changed); intercept first, then FEATURES order. (The first fit, on 136
# detections, leaned on the radius: 4.56 per log px, so any large rough outline scored ~1.)
# A third-round refit (with the chair kind and an edge RMS x contrast feature) was dropped: the
# third-round detector leaves so few wrong outlines in training (9 of 197) that the fit learnt
# the synthetic edges' smoothness and scored 39 right kinectnet detections under 0.5.
COEF = np.array([-5.2736, 1.2452, -9.0932, -4.8996, 2.6376, 0.0000, 0.5479])


def features(extras: dict, radius_px: float, clean_rms_px: float) -> np.ndarray:
    """Feature vector of one accepted outline (see FEATURES)."""
    return np.array([float(extras.get("outline_coverage", 0.0)),
                     float(extras.get("edge_rms_px", 0.0)) / max(clean_rms_px, 1e-6),
                     float(extras.get("outside_mismatch", 0.0)),
                     float(np.log1p(max(extras.get("edge_contrast", 0.0), 0.0))),
                     float(extras.get("runner_up_ratio", 0.0)),
                     float(np.log(max(radius_px, 1.0)))])


def probability(x: np.ndarray, fallback: float) -> float:
    """P(right) for feature vector ``x``; ``fallback`` when no model is fitted."""
    if COEF is None:
        return float(fallback)
    z = COEF[0] + float(np.dot(COEF[1:], x))
    return float(1.0 / (1.0 + np.exp(-z)))


def fit_logistic(X: np.ndarray, y: np.ndarray, l2: float = 1e-2, iters: int = 50) -> np.ndarray:
    """Intercept + coefficients of an L2-regularised logistic regression (Newton / IRLS)."""
    A = np.column_stack([np.ones(len(X)), X])
    w = np.zeros(A.shape[1])
    reg = l2 * np.eye(A.shape[1])
    reg[0, 0] = 0.0
    for _ in range(iters):
        p = 1.0 / (1.0 + np.exp(-A @ w))
        g = A.T @ (p - y) + reg @ w
        H = (A * (p * (1 - p))[:, None]).T @ A + reg + 1e-9 * np.eye(A.shape[1])
        step = np.linalg.solve(H, g)
        w -= step
        if np.abs(step).max() < 1e-8:
            break
    return w


RELIABILITY_BINS = (0.0, 0.5, 0.8, 0.9, 0.95, 1.0001)


def reliability_table(scored, title: str) -> str:
    """Markdown reliability table of (score, right) pairs: per score bin, the detections, their
    mean score and the share that was right (a calibrated score has the two close)."""
    lines = [f"\n{title}", "| score bin | detections | mean score | right |", "|---|---|---|---|"]
    s = np.array([p for p, _ in scored], float)
    ok = np.array([bool(r) for _, r in scored])
    for lo, hi in zip(RELIABILITY_BINS[:-1], RELIABILITY_BINS[1:]):
        m = (s >= lo) & (s < hi)
        if m.any():
            lines.append(f"| [{lo:.2f}, {min(hi, 1.0):.2f}{')' if hi < 1 else ']'} | {int(m.sum())} "
                         f"| {s[m].mean():.3f} | {ok[m].mean():.3f} |")
    return "\n".join(lines)
