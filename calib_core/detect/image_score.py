"""The image detection's score as a probability: P(the detection is the sphere, within 3 px).

A regularised logistic model on four features of the accepted outline, recalibrated (Platt:
a straight line on the logit, fitted on out-of-fold predictions) so that a score of 0.9 is
right about 9 times in 10 on data the model did not see. Fitted by
``benchmarks/fit_image_score.py`` on synthetic training seeds only (single-image cases seeds
0-39, generated sessions seeds 1-3, hard negatives included: the verification run at the
places of other round things, as the sonar-guided look runs it); measured on held-out seeds
(cases 1000-1039, sessions 41-60) and on real photographs (kinectnet, never fitted to).

The features are chosen to mean the same in a real photograph as in a rendered one:
- ``coverage``: the share of the outline with edge support (geometry, not texture or colour);
- ``rms_rel``: the outline's spread about the fitted cone relative to the clean-outline limit,
  capped at 2 (roundness; beyond the limit the outline is refused anyway, so the cap keeps the
  model from learning how smooth rendered edges are);
- ``outside_mismatch``: the share of the band just outside that looks like the inside (part of
  a larger object);
- ``log_contrast``: log(1 + edge contrast in grey levels), capped at log(1 + 40): only a faint
  outline lowers the score, a bright photograph's strong edges do not raise it.
The apparent radius and the runner-up ratio are left out: the first is a property of a data
set's rig, the second is 0 in a hinted look and < 0.5 by construction in the free search.

Approximation: synthetic scenes are not real ones; the reliability tables say how far the
probabilities can be trusted on each.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FEATURES = ("coverage", "rms_rel", "outside_mismatch", "log_contrast")
RMS_REL_CAP = 2.0
CONTRAST_CAP = 40.0  # grey levels
L2 = 1.0  # ridge weight of the logistic fit (standardised features)
# fitted by benchmarks/fit_image_score.py: intercept then FEATURES order, then Platt (a, b)
COEF = None
PLATT = (1.0, 0.0)


def features(extras: dict, radius_px: float, clean_rms_px: float) -> np.ndarray:
    """Feature vector of one accepted outline (see FEATURES; ``radius_px`` is not used)."""
    rms_rel = float(extras.get("edge_rms_px", 0.0)) / max(clean_rms_px, 1e-6)
    contrast = min(max(float(extras.get("edge_contrast", 0.0)), 0.0), CONTRAST_CAP)
    return np.array([float(extras.get("outline_coverage", 0.0)), min(rms_rel, RMS_REL_CAP),
                     float(extras.get("outside_mismatch", 0.0)), float(np.log1p(contrast))])


def _sigmoid(z):
    return 1.0 / (1.0 + np.exp(-np.clip(z, -40.0, 40.0)))


@dataclass
class ScoreModel:
    """Logistic coefficients (intercept first) and the Platt line on the logit."""

    coef: np.ndarray
    platt: tuple[float, float] = (1.0, 0.0)

    def logit(self, X: np.ndarray) -> np.ndarray:
        return self.coef[0] + np.asarray(X, float) @ self.coef[1:]

    def probability(self, x: np.ndarray) -> float:
        a, b = self.platt
        return float(_sigmoid(a * self.logit(x) + b))


def probability(x: np.ndarray, fallback: float) -> float:
    """P(right) for feature vector ``x``; ``fallback`` when no model is fitted."""
    if COEF is None:
        return float(fallback)
    return ScoreModel(COEF, PLATT).probability(x)


def fit_logistic(X: np.ndarray, y: np.ndarray, l2: float = 1e-2, iters: int = 50) -> np.ndarray:
    """Intercept + coefficients of an L2-regularised logistic regression (Newton / IRLS)."""
    A = np.column_stack([np.ones(len(X)), X])
    w = np.zeros(A.shape[1])
    reg = l2 * np.eye(A.shape[1])
    reg[0, 0] = 0.0
    for _ in range(iters):
        p = _sigmoid(A @ w)
        g = A.T @ (p - y) + reg @ w
        H = (A * (p * (1 - p))[:, None]).T @ A + reg + 1e-9 * np.eye(A.shape[1])
        step = np.linalg.solve(H, g)
        w -= step
        if np.abs(step).max() < 1e-8:
            break
    return w


def _standardised_fit(X, y, l2):
    """Logistic fit on standardised columns (so one ridge weight suits every feature), returned
    in the raw features' units."""
    mu, sd = X.mean(axis=0), X.std(axis=0) + 1e-9
    w = fit_logistic((X - mu) / sd, y, l2=l2)
    coef = np.concatenate([[w[0] - np.sum(w[1:] * mu / sd)], w[1:] / sd])
    return coef


def fit(X: np.ndarray, y: np.ndarray, l2: float = L2, folds: int = 5, seed: int = 0) -> ScoreModel:
    """Ridge logistic on all of (X, y), then a Platt line fitted on out-of-fold logits (each
    sample's logit from a model that did not see it): the recalibration corrects the
    over-confidence of a fit scored on its own training data."""
    X, y = np.asarray(X, float), np.asarray(y, float)
    coef = _standardised_fit(X, y, l2)
    fold = np.random.default_rng(seed).integers(0, folds, len(y))
    z = np.empty(len(y))
    for k in range(folds):
        m = fold == k
        ck = _standardised_fit(X[~m], y[~m], l2)
        z[m] = ck[0] + X[m] @ ck[1:]
    ab = fit_logistic(z[:, None], y, l2=1e-3)
    return ScoreModel(coef, (float(ab[1]), float(ab[0])))


RELIABILITY_BINS = (0.0, 0.5, 0.8, 0.9, 0.95, 1.0001)


def reliability_rows(scored):
    """(lo, hi, detections, mean score, share right) per score bin with detections."""
    s = np.array([p for p, _ in scored], float)
    ok = np.array([bool(r) for _, r in scored])
    rows = []
    for lo, hi in zip(RELIABILITY_BINS[:-1], RELIABILITY_BINS[1:]):
        m = (s >= lo) & (s < hi)
        if m.any():
            rows.append((lo, min(hi, 1.0), int(m.sum()), float(s[m].mean()), float(ok[m].mean())))
    return rows


def reliability_table(scored, title: str) -> str:
    """Markdown reliability table of (score, right) pairs: per score bin, the detections, their
    mean score and the share that was right (a calibrated score has the two close)."""
    lines = [f"\n{title}", "| score bin | detections | mean score | right | gap |", "|---|---|---|---|---|"]
    for lo, hi, n, mean, right in reliability_rows(scored):
        lines.append(f"| [{lo:.2f}, {hi:.2f}{')' if hi < 1 else ']'} | {n} | {mean:.3f} | {right:.3f} "
                     f"| {right - mean:+.3f} |")
    return "\n".join(lines)
