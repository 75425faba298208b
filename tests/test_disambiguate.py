"""Choosing the target among image candidates with the sonar's centres (3D-3D RANSAC)."""

from __future__ import annotations

import numpy as np

from calib_core.camera import CameraModel
from calib_core.disambiguate.image import resolve_candidates
from calib_core.geometry import T_from_rotvec, transform_points

CAM = CameraModel(1920, 1080, [[1100, 0, 960], [0, 1100, 540], [0, 0, 1]], [-0.2, 0.08, 0.001, -0.001, 0.0])
T_CAM_SONAR = T_from_rotvec([1.2, -1.1, 1.3], [0.35, -0.8, 0.05])


def _scene(rng, n=8, n_ambiguous=5, range_noise=0.02):
    """Sphere centres in view; ambiguous captures get a decoy candidate elsewhere in the image."""
    centers_cam = np.column_stack([rng.uniform(-1, 1, n), rng.uniform(-0.5, 0.5, n), rng.uniform(1.5, 4.0, n)])
    centers_sonar = transform_points(np.linalg.inv(T_CAM_SONAR), centers_cam)
    uv = CAM.project(centers_cam)
    rng_m = np.linalg.norm(centers_cam, axis=1) * (1 + range_noise * rng.standard_normal(n))
    cands, truth = {}, {}
    for i in range(n):
        true = [uv[i, 0], uv[i, 1], rng_m[i]]
        cid = f"p{i:02d}"
        if i < n_ambiguous:  # a decoy: another place and another apparent range
            decoy = [rng.uniform(100, 1800), rng.uniform(100, 1000), rng.uniform(1.0, 5.0)]
            k = int(rng.integers(2))
            cands[cid] = np.array([true, decoy] if k == 0 else [decoy, true])
            truth[cid] = k
        else:
            cands[cid] = np.array([true])
    return {f"p{i:02d}": centers_sonar[i] for i in range(n)}, cands, truth


def test_picks_the_candidate_that_fits_one_rig_transform():
    rng = np.random.default_rng(3)
    right = wrong = 0
    for _ in range(20):
        centers, cands, truth = _scene(rng)
        chosen = resolve_candidates(CAM, centers, cands, seed=int(rng.integers(1 << 30))).chosen
        for cid, k in chosen.items():
            right += k == truth[cid]
            wrong += k != truth[cid]
    assert wrong == 0
    assert right >= 0.8 * 20 * 5  # most ambiguous captures are decided


def test_even_with_only_two_unambiguous_captures():
    rng = np.random.default_rng(8)
    centers, cands, truth = _scene(rng, n=8, n_ambiguous=6)
    chosen = resolve_candidates(CAM, centers, cands).chosen
    assert chosen and all(chosen[c] == truth[c] for c in chosen)


def test_leaves_undecidable_cases_to_the_operator():
    rng = np.random.default_rng(1)
    centers, cands, _ = _scene(rng, n=3, n_ambiguous=2)  # too few captures
    assert resolve_candidates(CAM, centers, cands).chosen == {}
    centers, cands, _ = _scene(rng, n=8, n_ambiguous=0)  # nothing ambiguous
    assert resolve_candidates(CAM, centers, cands).chosen == {}
    # sonar centres unrelated to the images: nothing is decided confidently
    centers, cands, _ = _scene(rng, n=8, n_ambiguous=4)
    shuffled = dict(zip(centers, rng.permutation(list(centers.values()))))
    chosen = resolve_candidates(CAM, shuffled, cands).chosen
    assert len(chosen) <= 1


def test_predicts_where_a_wrong_single_detection_should_have_been():
    rng = np.random.default_rng(5)
    centers, cands, truth = _scene(rng, n=8, n_ambiguous=3, range_noise=0.01)
    wrong = "p06"  # an unambiguous but wrong detection (the decoy only)
    true_uv = cands[wrong][0, :2].copy()
    cands[wrong] = np.array([[200.0, 150.0, 1.2]])
    res = resolve_candidates(CAM, centers, cands)
    assert wrong in res.predicted_uvr and wrong not in res.chosen
    assert np.hypot(*(np.array(res.predicted_uvr[wrong][:2]) - true_uv)) < 40  # rough, but a place to look


def test_predicts_where_to_look_for_an_image_that_found_nothing():
    rng = np.random.default_rng(9)
    centers, cands, _ = _scene(rng, n=8, n_ambiguous=0, range_noise=0.01)
    lost = "p03"
    true_uv = cands.pop(lost)[0, :2]
    res = resolve_candidates(CAM, centers, cands, predict_for=[lost])
    assert np.hypot(*(np.array(res.predicted_uvr[lost][:2]) - true_uv)) < 40
    assert set(res.predicted_uvr) == {lost}  # the good single detections are left alone
