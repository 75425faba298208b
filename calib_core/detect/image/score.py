"""The image detection's score as a probability: P(the detection is the sphere, within 3 px).

Two stages. A logistic model on features of the accepted outline (COEF; fitted on synthetic
single-image cases, training seeds 0-39, the second-round fit), then a recalibration of its
logit, monotone in it (CALIBRATION since score round 2, with a capped size term, see below;
PLATT: p = sigmoid(a * logit + b) before, kept for comparison) fitted by ``benchmarks/fit_image_score.py``
on the free search in training data: generated sessions of the holder / room presets (seeds
1-3, which the logistic never saw) and the single-image cases (seeds 0-39). Hard negatives
(the detector's verification run, as the sonar-guided look runs it, at the places of the
other round things) are measured, not fitted: their share of wrong answers is set by how many
places are hinted at. Test sets, never fitted to: cases seeds 1000-1039, sessions seeds 41-60
and the real kinectnet photographs (reliability tables in BENCHMARKS.md).

Why a recalibration and not a new fit: a fresh logistic on the same features learns how
smooth and complete rendered outlines are (synthetic right outlines: coverage ~0.97, spread
~0.15 of the clean limit; real photographs: ~0.89 and ~0.45), and scored 14-42 right kinectnet
detections under 0.5 whatever the ridge weight and feature subset tried. A two-parameter
monotone map keeps the ranking that transfers and only corrects how far apart the
probabilities are (the logistic alone was too sure at both ends: right session outlines of low
contrast scored ~0.2).

Score round 2: the recalibration also reads the outline's apparent size, capped. Right
outlines of low contrast in the generated sessions (radius 45-90 px, contrast 8-25) scored
0.2-0.7 although all were right, because the training's wrong answers are small outlines
(radius 13-26 px: a texture arc makes a small circle far more easily than a large one, the
number of edge samples that must agree grows with the perimeter). So p = sigmoid(w0 + w1 *
logit + w2 * min(log radius, log RADIUS_CAP_PX)) (CALIBRATION, fitted by fit_image_score.py on
the same calibration split as PLATT). The cap: no extra confidence beyond RADIUS_CAP_PX (an
uncapped size term was rejected in the first round: any large rough outline scored ~1.00).

Score round 3: the recalibration also reads the fit's own quality (``fit_quality``: the share of
the outline seen, discounted by its spread), capped at QUALITY_CAP. On the photographic kinds
(glossy gym balls, beach balls with gores, motion blur; synth/photo/cases.py) the wrong outlines
(texture or gore arcs, a ball's part, ball-free images) had fit quality 0.26-0.63 while 95 % of
the right ones had >= 0.6; the logit and the size term scored them 0.5-1.0. So p = sigmoid(w0 +
w1 logit + w2 size_term + w3 min(fit_quality, QUALITY_CAP)) (CALIBRATION, fitted on the
calibration split with the photographic kinds' training seeds 0-39 and 1000-1039 added). The cap is the largest
(0.05 grid) for which the logit keeps a positive weight: uncapped, the quality term takes over
the ranking (w_logit < 0) and a clean, smooth outline would score lower than a rough one.
The 2-3 wrong outlines per 110 that the term does not catch (a beach-ball fit dragged 4-6 px by
its gores with a clean rim, textured ball-free interiors) keep scores > 0.9: BENCHMARKS.md
"Score round 3".

Approximation: synthetic scenes are not real ones; the reliability tables say how far the
probabilities can be trusted on each.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FEATURES = ("coverage", "rms_rel", "outside_mismatch", "log_contrast", "runner_up", "log_radius", "fit_quality")
# COEF reads the first six; fit_quality enters only the recalibration (quality_term)
N_LOGIT = 6
# fitted by the second-round fit_image_score.py (git history; training cases seeds 0-39, with and without
# the ball; 197 detections, 150 right, 47 wrong), ridge 0.1, on the second-round detector;
# intercept first, then FEATURES order. Kept as the ranking (see the module docstring).
COEF = np.array([-5.2736, 1.2452, -9.0932, -4.8996, 2.6376, 0.0000, 0.5479])
# (a, b) of the recalibration p = sigmoid(a * logit + b): benchmarks/fit_image_score.py on the
# free search of the training data (314 detections, 305 right, 9 wrong; detector of main at 01111cd)
PLATT = (0.6492, 1.2840)
L2 = 1.0  # ridge weight of the comparison refit (fit_image_score.py --refit)
# (w0, w_logit, w_size, w_quality) of p = sigmoid(w0 + w_logit * logit + w_size * size_term +
# w_quality * quality_term): fit_image_score.py on the calibration split (free search of
# sessions-train, cases-train and photo-train seeds 0-39 and 1000-1039; score round 3; round 2 had (-14.700, 0.911, 5.240)
# without the quality term)
CALIBRATION = (-23.362, 0.101, 4.338, 18.856)
RADIUS_CAP_PX = 45.0  # the size term stops growing here (see the module docstring)
QUALITY_CAP = 0.70  # the quality term stops growing here (see the module docstring)


def features(extras: dict, radius_px: float, clean_rms_px: float) -> np.ndarray:
    """Feature vector of one accepted outline (see FEATURES)."""
    return np.array([float(extras.get("outline_coverage", 0.0)),
                     float(extras.get("edge_rms_px", 0.0)) / max(clean_rms_px, 1e-6),
                     float(extras.get("outside_mismatch", 0.0)),
                     float(np.log1p(max(extras.get("edge_contrast", 0.0), 0.0))),
                     float(extras.get("runner_up_ratio", 0.0)),
                     float(np.log(max(radius_px, 1.0))),
                     float(extras.get("fit_quality", 0.0))])


def logit(x: np.ndarray, coef: np.ndarray = COEF) -> float:
    """The logistic model's log-odds for feature vector ``x`` (before the recalibration)."""
    return float(coef[0] + np.dot(coef[1:], x[:len(coef) - 1]))


def size_term(x: np.ndarray) -> float:
    """min(log radius, log RADIUS_CAP_PX) of feature vector ``x``."""
    return float(min(x[FEATURES.index("log_radius")], np.log(RADIUS_CAP_PX)))


def quality_term(x: np.ndarray) -> float:
    """min(fit_quality, QUALITY_CAP) of feature vector ``x``."""
    return float(min(x[FEATURES.index("fit_quality")], QUALITY_CAP))


def probability(x: np.ndarray, fallback: float, platt: tuple[float, float] | None = None) -> float:
    """P(right) for feature vector ``x`` (CALIBRATION; or, given ``platt``, that Platt line on the
    logit alone, the first round's form); ``fallback`` when no model is fitted."""
    if COEF is None:
        return float(fallback)
    if platt is not None:
        return float(_sigmoid(platt[0] * logit(x) + platt[1]))
    w0, w1, w2, w3 = CALIBRATION
    return float(_sigmoid(w0 + w1 * logit(x) + w2 * size_term(x) + w3 * quality_term(x)))


def entry_logit(entry: dict) -> float | None:
    """The logistic's log-odds (before any calibration) of a detections.yaml image entry of the
    free search, from the outline features it records; None when it records none."""
    from calib_core.detect.image.fit import clean_rms_px

    r = entry.get("radius_px")
    if not isinstance(r, (int, float)) or "outline_coverage" not in entry:
        return None
    return logit(features(entry, float(r), clean_rms_px(float(r))))


def recalibrate(z: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """(a, b) of the Platt line: the logistic regression of ``y`` on the logits ``z``."""
    w = fit_logistic(np.asarray(z, float)[:, None], np.asarray(y, float), l2=1e-3)
    return float(w[1]), float(w[0])


def _sigmoid(z):
    return 1.0 / (1.0 + np.exp(-np.clip(z, -40.0, 40.0)))


@dataclass
class ScoreModel:
    """Logistic coefficients (intercept first) and the Platt line on the logit (a fresh fit,
    for comparison: :func:`fit`)."""

    coef: np.ndarray
    platt: tuple[float, float] = (1.0, 0.0)

    def logit(self, X: np.ndarray) -> np.ndarray:
        return self.coef[0] + np.asarray(X, float) @ self.coef[1:]

    def probability(self, x: np.ndarray) -> float:
        a, b = self.platt
        return float(_sigmoid(a * self.logit(x) + b))


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
    """A fresh model (the comparison to the recalibration; not what the detector uses): ridge logistic on all of (X, y), then a Platt line fitted on out-of-fold logits (each
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
    return ScoreModel(coef, recalibrate(z, y))


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
