"""The candidate search's beam-width-independent part (calib_core.detect.sonar.search.prepare_search),
computed once and shared by a cloud's detections at two beam widths (the beam width estimate's
crop at the nominal width, then the final one at the estimated width), gives exactly the
detections computed without it."""

from __future__ import annotations

import numpy as np
import pytest

from calib_core.detect.sonar import search
from calib_core.detect.sonar.detect import detect_sphere_in_cloud
from calib_core.detect.sonar.search import prepare_search

R = 0.1


def _scene_cloud(seed: int) -> np.ndarray:
    """A sonar scan of a ball resting on a wide table top (a plane too small for the cloud-wide
    search: the ball's cluster removes it itself, drawing from its own random stream), a crate
    and a floor."""
    from calib_core.synth.range.capture import sensor_config
    from calib_core.synth.scene import Box, Material, Rect, Scene, Sphere
    from calib_core.synth.sonar_sim import simulate_scan

    rng = np.random.default_rng(seed)
    c = np.array([rng.uniform(1.4, 2.0), rng.uniform(-0.3, 0.3), rng.uniform(-0.1, 0.1)])
    top, floor_z = c[2] - 0.98 * R, -1.0
    grey = Material((0.5, 0.5, 0.5), 0.8)
    table = Box((c[0] + 0.1, c[1], top - 0.02), (4 * R, 4 * R, 0.02), material=grey)
    crate = Box((c[0] + 0.8, c[1] + 0.9, floor_z + 0.2), (0.25, 0.2, 0.2), material=grey)
    scene = Scene((Rect((0, 0, floor_z), (0, 0, 1)), table, crate, Sphere(tuple(c), R, Material((0.6, 0.6, 0.6), 0.9))))
    return simulate_scan(scene, np.eye(4), sensor_config("sonar", rng), rng).points_m


def _same(a, b) -> None:
    """Two detections agree in every field (arrays exactly)."""
    assert a.found == b.found and a.reason == b.reason and a.method == b.method
    assert a.to_entry() == b.to_entry()
    for name in ("center_sonar_m", "cov_sonar_m2", "inlier_mask"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            np.testing.assert_array_equal(x, y, err_msg=name)
    assert a.extras == b.extras


@pytest.mark.parametrize("seed", [0, 1])
def test_shared_search_gives_the_unshared_detections(seed, monkeypatch):
    P = _scene_cloud(seed)
    planes_cut = []
    real = search._without_local_planes
    monkeypatch.setattr(search, "_without_local_planes",
                        lambda X, *a: planes_cut.append(len(X) - len(out := real(X, *a))) or out)
    prepared = prepare_search(P, R)
    assert any(n > 0 for n in planes_cut), "the scene must exercise a cluster's own plane search"
    for h in np.radians([0.5, 0.0, 0.435]):  # the candidates themselves, exactly
        got, info = search.find_candidates(P, R, h, max_candidates=16, prepared=prepared)
        ref, info0 = search.find_candidates(P, R, h, max_candidates=16)
        assert repr(info) == repr(info0) and len(got) == len(ref) > 0  # (repr: NaN noise without planes)
        for k, k0 in zip(got, ref):
            np.testing.assert_array_equal(k.center_m, k0.center_m)
            assert (k.radius_m, k.support, k.purity, k.quality) == (k0.radius_m, k0.support, k0.purity, k0.quality)
    for width in (1.0, 0.0, 0.87, 1.0):  # the same search used again and again, in any order
        shared = detect_sphere_in_cloud(P, R, width, prepared=prepared)
        alone = detect_sphere_in_cloud(P, R, width)
        _same(shared, alone)
    assert alone.found, alone.reason


def test_shared_search_is_left_unchanged_and_refuses_other_inputs():
    P = _scene_cloud(2)
    prepared = prepare_search(P, R)
    states = [dict(st) for _, _, st in prepared.clusters]
    before = [X.copy() for _, X, _ in prepared.clusters]
    detect_sphere_in_cloud(P, R, 1.0, prepared=prepared)
    assert [st for _, _, st in prepared.clusters] == states
    for (_, X, _), X0 in zip(prepared.clusters, before):
        np.testing.assert_array_equal(X, X0)
        assert not X.flags.writeable
    assert P.flags.writeable  # the caller's cloud stays as it was
    with pytest.raises(ValueError):
        detect_sphere_in_cloud(P, 1.5 * R, 1.0, prepared=prepared)  # another radius
    with pytest.raises(ValueError):
        detect_sphere_in_cloud(P[:-1], R, 1.0, prepared=prepared)  # another cloud
    with pytest.raises(ValueError):
        detect_sphere_in_cloud(P, R, 1.0, rng_seed=3, prepared=prepared)  # another key
    with pytest.raises(ValueError):
        detect_sphere_in_cloud(P, R, 1.0, seed_center_m=P[0], prepared=prepared)  # a pick's crop
