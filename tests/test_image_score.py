"""The image detection score as a probability (calib_core.detect.image_score)."""

import numpy as np

from calib_core.detect.image_score import features, fit_logistic, probability, reliability_table


def test_fit_logistic_recovers_a_known_model():
    rng = np.random.default_rng(0)
    X = rng.normal(0, 1, (4000, 2))
    w_true = np.array([0.5, 2.0, -1.0])
    p = 1 / (1 + np.exp(-(w_true[0] + X @ w_true[1:])))
    y = (rng.random(4000) < p).astype(float)
    w = fit_logistic(X, y, l2=1e-3)
    assert np.allclose(w, w_true, atol=0.15)


def test_probability_is_monotone_in_coverage_and_bounded():
    ex = {"outline_coverage": 0.5, "edge_rms_px": 0.4, "outside_mismatch": 0.05, "edge_contrast": 60.0}
    lo = probability(features(ex, 40.0, 0.9), 0.0)
    hi = probability(features(dict(ex, outline_coverage=0.95), 40.0, 0.9), 0.0)
    rough = probability(features(dict(ex, edge_rms_px=0.9), 40.0, 0.9), 0.0)
    assert 0.0 <= lo < hi <= 1.0
    assert rough < probability(features(ex, 40.0, 0.9), 0.0)


def test_reliability_table_bins():
    t = reliability_table([(0.99, True), (0.97, True), (0.3, False), (0.6, True)], "t")
    assert "| [0.95, 1.00] | 2 | 0.980 | 1.000 |" in t
    assert "| [0.00, 0.50) | 1 | 0.300 | 0.000 |" in t
