"""The range-side search draws its randomness from the cloud's own content (issue 11, range5):
a far, sparse ball's outcome does not change with the order of the points or with an
unrelated object elsewhere in the cloud; and a held ball is told from the carrier's head by
what continues their outlines."""

from __future__ import annotations

import numpy as np

from calib_core.detect.sonar.detect import detect_sphere_in_cloud
from calib_core.detect.sonar.outline import longest_attached_arc
from calib_core.detect.sonar.streams import content_rng, lowest_hashes, thin_hashed
from calib_core.synth.range.capture import range_capture


def _box(center_m, half_m: float, rng, n: int = 400) -> np.ndarray:
    """Returns of the sensor-facing faces of a box (not round: never a candidate)."""
    c = np.asarray(center_m, float)
    pts = rng.uniform(-half_m, half_m, (n, 3))
    face = rng.integers(0, 3, n)
    pts[np.arange(n), face] = -half_m * np.sign(c[face])
    return c + pts


def test_draws_are_keyed_to_the_points_not_their_order():
    rng = np.random.default_rng(0)
    P = rng.normal(size=(5000, 3))
    perm = rng.permutation(len(P))
    a, b = thin_hashed(P, 1000, key=3), thin_hashed(P[perm], 1000, key=3)
    assert 800 < len(a) < 1200
    assert {tuple(p) for p in a} == {tuple(p) for p in b}
    # more points elsewhere only move the threshold: nearly the same points stay
    c = thin_hashed(np.vstack([P, rng.normal(size=(50, 3)) + 10]), 1000, key=3)
    assert len({tuple(p) for p in a} - {tuple(p) for p in c}) < 30
    assert np.array_equal(P[lowest_hashes(P, 100)], P[perm][lowest_hashes(P[perm], 100)])
    X = P[:200]
    assert np.array_equal(content_rng(X, 0.01, 5).random(4), content_rng(X[::-1], 0.01, 5).random(4))
    assert not np.array_equal(content_rng(X, 0.01, 5).random(4), content_rng(X, 0.01, 6).random(4))


def test_a_far_sparse_ball_does_not_change_with_unrelated_changes():
    # 16-ring LiDAR and depth-camera balls: the same outcome, to the last digit, whatever the
    # order of the points and whether an unrelated box stands 2.5 m to the side (with one
    # random stream for the whole cloud, the box's cluster, searched first, shifted every later
    # draw: the coarse candidates, and so the fits, moved)
    changed = []
    for seed, sensor, holder in [(7, "lidar16", "chair"), (8, "lidar16", "stick"), (9, "rgbd", "table"),
                                 (10, "lidar16", "table"), (11, "rgbd", "chair")]:
        P, c, r = range_capture(seed, sensor, holder)
        rng = np.random.default_rng(seed)
        side = np.cross(c / np.linalg.norm(c), [0, 0, 1.0])
        variants = [P[rng.permutation(len(P))], np.vstack([P, _box(c + 2.5 * side / np.linalg.norm(side), 1.5 * r, rng)])]
        base = detect_sphere_in_cloud(P, r, beam_width_deg=0.0)
        for Q in variants:
            d = detect_sphere_in_cloud(Q, r, beam_width_deg=0.0)
            same = d.found == base.found and (not d.found or np.allclose(d.center_sonar_m, base.center_sonar_m,
                                                                          rtol=0, atol=1e-9))
            if not same:
                changed.append((seed, sensor, holder))
    assert not changed


def test_longest_attached_arc_bridges_one_missed_sector():
    arc = lambda s: longest_attached_arc(np.array([ch == "#" for ch in s]))  # noqa: E731
    assert arc("................") == 0
    assert arc("...#........#...") == 1  # two hands on the sides
    assert arc("#..............#") == 2  # across the wrap
    assert arc("...##.###.......") == 6  # shoulders under a head, one sector missed
    assert arc("..#.#.#.#.#.#.#.") == 13


def test_a_held_ball_beats_the_carriers_head_by_their_outlines():
    # depth camera, a ball held out by a person: the ball and the top of the person (head on
    # shoulders) are both round and of the ball's size, with evidence under CLEAR_WINNER apart
    # (it was "two candidates"); the person's outline runs on into the body over a long arc,
    # the ball's is held by a hand over two sectors
    for seed in (316, 349):
        P, c, r = range_capture(seed, "rgbd", "hand")
        det = detect_sphere_in_cloud(P, r, beam_width_deg=0.0)
        assert det.found, det.reason
        assert np.linalg.norm(det.center_sonar_m - c) < 0.005
        assert det.extras["resolved_by"].startswith("outline:")
        assert det.extras["other_candidates"]  # the session-level choice can still look again
