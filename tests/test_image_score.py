"""The image detection score as a probability (calib_core.detect.image.score)."""

import numpy as np

from calib_core.detect.image import score as image_score
from calib_core.detect.image.score import (ScoreModel, features, fit, fit_logistic, logit, probability,
                                           recalibrate, reliability_rows, reliability_table)


def test_fit_logistic_recovers_a_known_model():
    rng = np.random.default_rng(0)
    X = rng.normal(0, 1, (4000, 2))
    w_true = np.array([0.5, 2.0, -1.0])
    p = 1 / (1 + np.exp(-(w_true[0] + X @ w_true[1:])))
    y = (rng.random(4000) < p).astype(float)
    w = fit_logistic(X, y, l2=1e-3)
    assert np.allclose(w, w_true, atol=0.15)


def _known(n, rng):
    X = np.column_stack([rng.uniform(0.3, 1.0, n), rng.uniform(0, 2, n), rng.uniform(0, 0.5, n),
                         rng.uniform(1, 4, n)])
    z = -4 + 8 * X[:, 0] - 1.5 * X[:, 1] - 3 * X[:, 2] + 0.5 * X[:, 3]
    y = (rng.random(n) < 1 / (1 + np.exp(-z))).astype(float)
    return X, y


def test_fit_is_calibrated_on_held_out_data():
    """Scores of a fitted model match the share right, bin by bin, on fresh samples."""
    rng = np.random.default_rng(1)
    X, y = _known(3000, rng)
    model = fit(X, y, l2=1.0)
    Xt, yt = _known(6000, rng)
    rows = reliability_rows([(model.probability(x), bool(r)) for x, r in zip(Xt, yt)])
    for lo, hi, n, mean, right in rows:
        if n >= 200:
            assert abs(mean - right) < 0.05, (lo, hi, n, mean, right)


def test_recalibration_corrects_an_over_confident_logit():
    """Logits twice too large: the Platt line halves them (slope ~0.5, no shift)."""
    rng = np.random.default_rng(2)
    z = rng.normal(0, 2, 5000)
    y = (rng.random(5000) < 1 / (1 + np.exp(-z))).astype(float)
    a, b = recalibrate(2 * z, y)
    assert abs(a - 0.5) < 0.05 and abs(b) < 0.1


def test_probability_applies_the_recalibration_to_the_logit():
    ex = {"outline_coverage": 0.8, "edge_rms_px": 0.4, "outside_mismatch": 0.05, "edge_contrast": 30.0,
          "fit_quality": 0.5}
    x = features(ex, 40.0, 0.9)
    z = logit(x)
    assert np.isclose(probability(x, 0.0, platt=(1.0, 0.0)), 1 / (1 + np.exp(-z)))
    w0, w1, w2, w3 = image_score.CALIBRATION
    assert np.isclose(probability(x, 0.0), 1 / (1 + np.exp(-(w0 + w1 * z + w2 * np.log(40.0) + w3 * 0.5))))
    assert w1 > 0 and w2 > 0 and w3 > 0  # monotone: the ranking of the logistic is kept


def test_the_logit_does_not_read_the_fit_quality():
    """fit_quality enters the recalibration only (pipeline's CLEAR_LOGIT decisions stay put)."""
    ex = {"outline_coverage": 0.8, "edge_rms_px": 0.4, "outside_mismatch": 0.05, "edge_contrast": 30.0}
    assert logit(features({**ex, "fit_quality": 0.3}, 40.0, 0.9)) == logit(features({**ex, "fit_quality": 0.9},
                                                                                     40.0, 0.9))


def test_quality_term_lowers_ragged_outlines_up_to_the_cap():
    """The photographic kinds' wrong outlines (fit quality 0.26-0.63) score far lower than the same
    outline at the cap; past the cap the quality adds nothing."""
    ex = {"outline_coverage": 0.6, "edge_rms_px": 0.6, "outside_mismatch": 0.1, "edge_contrast": 60.0}
    p = {q: probability(features({**ex, "fit_quality": q}, 30.0, 0.7), 0.0) for q in (0.3, 0.5, 0.7, 0.95)}
    assert p[0.3] < 0.1 < p[0.5] < p[0.7]
    assert p[0.7] == p[0.95]


def test_size_term_raises_the_score_of_larger_outlines_up_to_the_cap():
    """A low-contrast, rough outline (as the right ones in the sessions scored 0.2-0.7): larger is
    likelier right (a texture arc makes a small circle more easily), no gain past the cap."""
    ex = {"outline_coverage": 0.75, "edge_rms_px": 0.65, "outside_mismatch": 0.2, "edge_contrast": 12.0,
          "fit_quality": 0.7}
    p = {r: probability(features(ex, r, 0.05 * r), 0.0) for r in (15.0, 30.0, 45.0, 60.0, 90.0)}
    assert p[15.0] < p[30.0] < p[45.0]
    # past the cap only the logistic's own (weak) size feature still acts
    z = {r: logit(features(ex, r, 0.05 * r)) for r in (45.0, 90.0)}
    w1 = image_score.CALIBRATION[1]
    assert np.isclose(np.log(p[90.0] / (1 - p[90.0])) - np.log(p[45.0] / (1 - p[45.0])), w1 * (z[90.0] - z[45.0]))
    assert p[60.0] > 0.8 > probability(features(ex, 15.0, 0.75), 0.0)


def test_entry_logit_reads_the_features_an_entry_records():
    from calib_core.detect.image.fit import clean_rms_px

    e = {"center": [1.0, 2.0], "radius_px": 40.0, "outline_coverage": 0.8, "edge_rms_px": 0.4,
         "outside_mismatch": 0.05, "edge_contrast": 30.0, "runner_up_ratio": 0.1}
    assert np.isclose(image_score.entry_logit(e), logit(features(e, 40.0, clean_rms_px(40.0))))
    assert image_score.entry_logit({"center": [1.0, 2.0], "score": 0.9}) is None


def test_probability_is_monotone_and_bounded():
    ex = {"outline_coverage": 0.5, "edge_rms_px": 0.4, "outside_mismatch": 0.05, "edge_contrast": 30.0}
    p = lambda e: probability(features(e, 40.0, 0.9), 0.0)  # noqa: E731
    assert 0.0 <= p(ex) < p(dict(ex, outline_coverage=0.95)) <= 1.0
    assert p(dict(ex, edge_rms_px=0.9)) < p(ex)
    assert p(dict(ex, outside_mismatch=0.5)) < p(ex)
    assert p(dict(ex, edge_contrast=3.0)) < p(ex)


def test_score_model_applies_its_platt_line():
    m = ScoreModel(np.array([0.0, 1.0]), (0.5, 1.0))
    assert np.isclose(m.probability(np.array([2.0])), 1 / (1 + np.exp(-2.0)))


def test_reliability_table_bins():
    t = reliability_table([(0.99, True), (0.97, True), (0.3, False), (0.6, True)], "t")
    assert "| [0.95, 1.00] | 2 | 0.980 | 1.000 | +0.020 |" in t
    assert "| [0.00, 0.50) | 1 | 0.300 | 0.000 | -0.300 |" in t
