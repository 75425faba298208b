"""Sonar sphere detection against a small, independent beam simulator.

The simulator below samples each beam's cone with many sub-rays and keeps the nearest hit
(sphere, chain, planes, posts, boxes), placed along the beam's centre line: it does not use
the closed-form cone model of calib_core.detect.sonar.fit, so it checks it.
Sonar frame here: x forward, y left, z up; 256 beams over a 90 deg vertical fan, panned.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from calib_core.detect.sonar.detect import detect_sphere_in_cloud
from calib_core.detect.sonar.beam import estimate_beam_width_deg
from calib_core.detect.sonar.fit import (
    _resid_fn,
    cone_first_return_range_m,
    fit_sphere,
)

R_TRUE = 0.11
H = np.radians(0.5)


# ---- independent brute-force beam simulator -------------------------------------------
def _cone_rays(dirs, h, rings=(6, 12, 72)):
    a = np.where(np.abs(dirs[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    u = np.cross(dirs, a)
    u /= np.linalg.norm(u, axis=1)[:, None]
    v = np.cross(dirs, u)
    out = [dirs[:, None, :]]
    for i, k in enumerate(rings):
        ang = h * (i + 1) / len(rings)
        az = np.arange(k) * 2 * np.pi / k + 0.3 * i
        off = np.cos(az)[None, :, None] * u[:, None, :] + np.sin(az)[None, :, None] * v[:, None, :]
        out.append(np.cos(ang) * dirs[:, None, :] + np.sin(ang) * off)
    return np.concatenate(out, axis=1)


def _hit_sphere(R, c, r):
    b = R @ c
    disc = b * b - (c @ c - r * r)
    with np.errstate(invalid="ignore"):
        t = b - np.sqrt(disc)
    return np.where((disc >= 0) & (t > 0), t, np.inf)


def _hit_plane(R, n, d0):
    with np.errstate(divide="ignore", invalid="ignore"):
        t = d0 / (R @ np.asarray(n, float))
    return np.where(np.isfinite(t) & (t > 0), t, np.inf)


def _hit_vcyl(R, x0, y0, rad, zlo, zhi):
    dx, dy = R[..., 0], R[..., 1]
    A = dx * dx + dy * dy
    B = -2 * (dx * x0 + dy * y0)
    C = x0 * x0 + y0 * y0 - rad * rad
    disc = B * B - 4 * A * C
    with np.errstate(invalid="ignore", divide="ignore"):
        t = (-B - np.sqrt(disc)) / (2 * A)
    z = t * R[..., 2]
    return np.where((disc >= 0) & (t > 0) & (z >= zlo) & (z <= zhi), t, np.inf)


def _hit_box(R, lo, hi):
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = np.asarray(lo) / R, np.asarray(hi) / R
    tn = np.nanmax(np.minimum(t1, t2), axis=-1)
    tf = np.nanmin(np.maximum(t1, t2), axis=-1)
    return np.where((tn <= tf) & (tn > 0), tn, np.inf)


def _beam_dirs(az_deg, el_deg):
    A, E = np.meshgrid(np.radians(az_deg), np.radians(el_deg), indexing="ij")
    A, E = A.ravel(), E.ravel()
    return np.c_[np.cos(E) * np.cos(A), np.cos(E) * np.sin(A), np.sin(E)]


def simulate(spheres=(), planes=(), posts=(), boxes=(), chain=True, noise_m=0.004,
             n_spurious=0, seed=0, az_step=0.5, az_range=(-45, 45), max_range=12.0, h=H):
    """Cloud (N,3) of a panned 256-beam fan; first return inside each 1 deg cone."""
    rng = np.random.default_rng(seed)
    el = -45 + (90 / 255) * np.arange(256)
    az = np.arange(az_range[0] + rng.uniform(0, az_step), az_range[1], az_step)
    D = _beam_dirs(az, el)
    t = np.full(len(D), np.inf)
    for n, d0 in planes:  # planes and clutter: centre ray (their blooming does not matter here)
        t = np.minimum(t, _hit_plane(D, n, d0))
    for (x0, y0, rad, zlo, zhi) in posts:
        t = np.minimum(t, _hit_vcyl(D, x0, y0, rad, zlo, zhi))
    for lo, hi in boxes:
        t = np.minimum(t, _hit_box(D, lo, hi))
    for c, r in spheres:
        c = np.asarray(c, float)
        cn = np.linalg.norm(c)
        near = np.nonzero(D @ (c / cn) > np.cos(np.arcsin(r / cn) + 3 * h))[0]
        rays = _cone_rays(D[near], h)
        tt = _hit_sphere(rays, c, r)
        if chain:
            tt = np.minimum(tt, _hit_vcyl(rays, c[0], c[1], 0.006, c[2] + 0.98 * r, c[2] + 3))
        t[near] = np.minimum(t[near], tt.min(axis=1))
        if chain:
            far = _hit_vcyl(_cone_rays(D, h, rings=(8,)), c[0], c[1], 0.006, c[2] + 0.98 * r,
                            c[2] + 3).min(axis=1)
            t = np.minimum(t, far)
    ok = t < max_range
    P = D[ok] * (t[ok] + rng.normal(0, noise_m, ok.sum()))[:, None]
    if n_spurious:
        Ds = D[rng.integers(0, len(D), n_spurious)]
        P = np.vstack([P, Ds * rng.uniform(0.5, 8, n_spurious)[:, None]])
    return P


def random_center(rng, lo=1.0, hi=3.5):
    return np.array([rng.uniform(lo, hi), rng.uniform(-1, 1), rng.uniform(-0.6, 0.6)])


SEABED = ((0, 0, 1.0), -1.5)
WALL = ((1.0, 0, 0), 5.0)
SIDE = ((0, 1.0, 0), 3.0)


# ---- the model -----------------------------------------------------------------------------
def test_closed_form_cone_model_matches_sampled_cones():
    c, r = np.array([2.0, 0.3, -0.2]), R_TRUE
    D = _beam_dirs(np.linspace(5, 12, 120), np.linspace(-10, 5, 120))
    brute = _hit_sphere(_cone_rays(D, H, rings=(12, 24, 48, 360)), c, r).min(axis=1)
    model = cone_first_return_range_m(D, c, r, H)
    hit = np.isfinite(brute)
    assert hit.sum() > 1000
    assert np.array_equal(hit, np.isfinite(model))
    assert np.max(np.abs(brute[hit] - model[hit])) < 1e-4
    # blooming: beams outside the true silhouette return too
    cn = np.linalg.norm(c)
    outside = np.arccos(np.clip(D @ (c / cn), -1, 1)) > np.arcsin(r / cn)
    assert np.isfinite(model[outside]).any()


@pytest.mark.parametrize("free", [False, True])
def test_cone_jacobian_matches_finite_differences(free):
    c = np.array([2.0, 0.2, 0.1])
    P = simulate([(c, R_TRUE)], chain=False, az_range=(0, 10), seed=3)
    R = np.linalg.norm(P, axis=1)
    D = P / R[:, None]
    x = np.r_[c - 0.002, 0.12] if free else c + 0.003
    f, jac = _resid_fn("cone", P, R, D, H, R_TRUE)
    Jn = np.column_stack([(f(x + e) - f(x - e)) / 2e-7 for e in np.eye(len(x)) * 1e-7])
    assert np.median(np.abs(jac(x) - Jn)) < 1e-6
    assert np.quantile(np.abs(jac(x) - Jn), 0.99) < 1e-4


# ---- accuracy ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def open_water_scenes():
    """Six scenes: sphere on a chain, 1-3.5 m, spurious returns; half with seabed / walls."""
    out = []
    for seed in range(6):
        rng = np.random.default_rng(100 + seed)
        c = random_center(rng)
        planes = [SEABED, WALL] if seed % 2 else []
        out.append((c, simulate([(c, R_TRUE)], planes=planes, n_spurious=1500, seed=seed)))
    return out


def test_cone_model_accuracy_and_baseline_bias(open_water_scenes):
    errs = {m: [] for m in ("cone-model", "known-radius", "free-radius")}
    for c, P in open_water_scenes:
        for m in errs:
            det = detect_sphere_in_cloud(P, R_TRUE, beam_width_deg=1.0, method=m)
            assert det.found, (m, det.reason)
            assert det.method == m
            errs[m].append(det.center_sonar_m - c)
            if m == "cone-model":
                assert 0.8 < det.score <= 1.0
                assert abs(det.diameter_m - 2 * R_TRUE) < 0.005
                assert det.apparent_diameter_m > 2 * R_TRUE + 0.02  # blooming is visible
                assert det.n_inliers == int(det.inlier_mask.sum())
                assert det.inlier_mask.shape == (len(P),)
    e = {m: np.linalg.norm(np.array(v), axis=1) for m, v in errs.items()}
    assert e["cone-model"].max() < 2.5e-3, e["cone-model"]
    # the naive fits are pulled 1-5 cm, along the line of sight
    assert e["known-radius"].min() > 6e-3 and e["free-radius"].min() > 1e-2
    assert np.all(e["cone-model"] < 0.3 * e["known-radius"])
    for (c, _), d in zip(open_water_scenes, errs["known-radius"]):
        assert d @ c / np.linalg.norm(c) < -5e-3  # towards the sonar


def test_covariance_agrees_with_monte_carlo_spread():
    c = np.array([2.2, 0.3, -0.1])
    rng = np.random.default_rng(7)
    clean = simulate([(c, R_TRUE)], chain=False, noise_m=0.0, az_range=(0, 16), seed=1)
    R0 = np.linalg.norm(clean, axis=1)
    D = clean / R0[:, None]
    est, covs = [], []
    for _ in range(40):
        P = D * (R0 + rng.normal(0, 0.005, len(R0)))[:, None]
        f = fit_sphere(P, c + 0.01, R_TRUE, model="cone", half_angle_rad=H)
        assert f.ok
        est.append(f.center_m)
        covs.append(f.cov_center_m2)
    emp = np.cov(np.array(est).T)
    pred = np.mean(covs, axis=0)
    ratio = np.trace(emp) / np.trace(pred)
    assert 0.6 < ratio < 1.6, ratio
    # per axis too (the range axis is much tighter than the cross axes)
    sd_ratio = np.sqrt(np.diag(emp) / np.diag(pred))
    assert np.all((sd_ratio > 0.5) & (sd_ratio < 1.8)), sd_ratio
    assert np.linalg.norm(np.mean(est, axis=0) - c) < 1e-3


def test_chain_and_spurious_returns_are_not_inliers():
    rng = np.random.default_rng(3)
    c = random_center(rng, 1.2, 2.0)
    P = simulate([(c, R_TRUE)], n_spurious=4000, seed=11, noise_m=0.003)
    det = detect_sphere_in_cloud(P, R_TRUE)
    assert det.found, det.reason
    assert np.linalg.norm(det.center_sonar_m - c) < 2e-3
    inl = P[det.inlier_mask]
    # no chain point (well above the sphere's top) and no far spurious return among inliers
    assert np.all(inl[:, 2] < c[2] + R_TRUE + 0.02)
    assert np.all(np.linalg.norm(inl - c, axis=1) < R_TRUE + 0.05)
    # the naive fit is pulled upwards by the chain and towards the sonar by blooming
    naive = detect_sphere_in_cloud(P, R_TRUE, method="known-radius")
    assert np.linalg.norm(naive.center_sonar_m - c) > 3 * np.linalg.norm(det.center_sonar_m - c)


def test_seabed_walls_and_clutter_scene():
    rng = np.random.default_rng(21)
    c = random_center(rng, 1.5, 3.0)
    posts = [(3.5, -1.2, 0.1, -1.5, 1.5)]  # a piling
    boxes = [((2.5, 1.2, -1.5), (3.1, 1.8, -0.9))]  # a crate on the seabed
    P = simulate([(c, R_TRUE)], planes=[SEABED, WALL, SIDE], posts=posts, boxes=boxes,
                 n_spurious=3000, seed=4)
    det = detect_sphere_in_cloud(P, R_TRUE)
    assert det.found, det.reason
    assert np.linalg.norm(det.center_sonar_m - c) < 3e-3
    assert det.extras["planes_removed"] >= 2
    # the same scene without the sphere: nothing trustworthy
    P0 = simulate([], planes=[SEABED, WALL, SIDE], posts=posts, boxes=boxes, n_spurious=3000,
                  seed=4)
    miss = detect_sphere_in_cloud(P0, R_TRUE)
    assert not miss.found and "no sphere-like" in miss.reason


# ---- refusals ----------------------------------------------------------------------------
def test_empty_and_tiny_clouds_are_refused_with_a_reason():
    for pts, word in [(np.zeros((0, 3)), "empty"), (np.ones((5, 3)), "too few points")]:
        det = detect_sphere_in_cloud(pts, R_TRUE)
        assert not det.found and word in det.reason
        assert det.center_sonar_m is None
        assert "reason" in det.to_entry()
    with pytest.raises(ValueError):
        detect_sphere_in_cloud(np.ones((50, 3)), R_TRUE, method="hough")


def test_noise_only_and_plane_only_clouds_are_refused():
    rng = np.random.default_rng(0)
    noise = rng.uniform([0.5, -3, -3], [8, 3, 3], (5000, 3))
    assert not detect_sphere_in_cloud(noise, R_TRUE).found
    plane = simulate([], planes=[SEABED], seed=2)
    det = detect_sphere_in_cloud(plane, R_TRUE)
    assert not det.found and det.reason


def test_two_spheres_are_ambiguous_unless_a_seed_is_given():
    c1, c2 = np.array([2.0, -0.5, 0.0]), np.array([2.5, 0.6, -0.2])
    P = simulate([(c1, R_TRUE), (c2, R_TRUE)], n_spurious=500, seed=5)
    det = detect_sphere_in_cloud(P, R_TRUE)
    assert not det.found and "two candidates" in det.reason
    # an operator's pick on the second sphere's surface
    seeded = detect_sphere_in_cloud(P, R_TRUE, seed_center_m=c2 - [R_TRUE, 0, 0])
    assert seeded.found, seeded.reason
    assert np.linalg.norm(seeded.center_sonar_m - c2) < 3e-3
    # a pick where nothing is
    far = detect_sphere_in_cloud(P, R_TRUE, seed_center_m=[6.0, -2.0, 2.0])
    assert not far.found and far.reason


def test_a_decoy_of_another_size_is_ignored_and_a_wrong_diameter_is_reported():
    c, decoy = np.array([2.0, -0.4, 0.1]), np.array([2.6, 0.7, -0.3])
    P = simulate([(c, R_TRUE), (decoy, 0.17)], n_spurious=500, seed=6)
    det = detect_sphere_in_cloud(P, R_TRUE)
    assert det.found, det.reason
    assert np.linalg.norm(det.center_sonar_m - c) < 3e-3
    for d in det.extras.get("ignored_other_sizes_m", []):  # (if it got that far)
        assert abs(d - 0.34) < 0.01
    # session.yaml says 0.22 m but the sphere is 0.26 m: refused, and the reason says so
    P2 = simulate([(c, 0.13)], n_spurious=500, seed=7)
    det2 = detect_sphere_in_cloud(P2, R_TRUE)
    assert not det2.found and "another size" in det2.reason and "0.220 m" in det2.reason
    assert f"{det2.extras['candidate_diameter_m']:.3f} m across" in det2.reason
    assert abs(det2.extras["candidate_diameter_m"] - 0.26) < 0.006
    # ... unless the operator picks it: then it is fitted with the diameter it shows
    picked = detect_sphere_in_cloud(P2, R_TRUE, seed_center_m=det2.extras["candidate_center"])
    assert picked.found and "warning" in picked.extras
    assert f"{picked.diameter_m:.3f} m across" in picked.extras["warning"]
    assert abs(picked.diameter_m - 0.26) < 0.006
    assert np.linalg.norm(picked.center_sonar_m - c) < 3e-3


def test_entry_is_plain_yaml():
    c = np.array([1.8, 0.2, 0.0])
    det = detect_sphere_in_cloud(simulate([(c, R_TRUE)], seed=8).tolist(), R_TRUE)
    assert det.found
    entry = det.to_entry()
    text = yaml.safe_dump(entry)
    back = yaml.safe_load(text)
    assert back["status"] == "auto" and len(back["center"]) == 3 and len(back["cov_m2"]) == 9
    assert np.all(np.linalg.eigvalsh(det.cov_sonar_m2) > 0)


def test_effective_beam_width_is_estimated_from_a_session():
    rng = np.random.default_rng(31)
    centers = [random_center(rng, 1.2, 3.0) for _ in range(4)]
    for true_deg in (1.0, 0.8):
        clouds = [simulate([(c, R_TRUE)], seed=40 + i, az_range=(-30, 30), n_spurious=200,
                           h=np.radians(true_deg) / 2) for i, c in enumerate(centers)]
        est = estimate_beam_width_deg(clouds, R_TRUE, nominal_deg=1.0)
        assert est.n_captures == 4 and not est.reason
        assert abs(est.beam_width_deg - true_deg) < 0.06, (true_deg, est)
        # and the detection with the estimated width is unbiased
        dets = [detect_sphere_in_cloud(P, R_TRUE, est.beam_width_deg) for P in clouds]
        err = np.array([d.center_sonar_m - c for d, c in zip(dets, centers)])
        assert np.linalg.norm(err.mean(axis=0)) < 1.5e-3
    few = estimate_beam_width_deg(clouds[:2], R_TRUE)
    assert few.beam_width_deg == 1.0 and few.reason


def test_coarse_to_fine_width_search_matches_the_full_grid():
    from calib_core.detect.sonar.beam import beam_crop, estimate_from_crops

    rng = np.random.default_rng(32)
    centers = [random_center(rng, 1.2, 3.0) for _ in range(4)]
    for true_deg in (0.9, 0.0):
        clouds = [simulate([(c, R_TRUE)], seed=50 + i, az_range=(-30, 30), n_spurious=200,
                           h=np.radians(true_deg) / 2) for i, c in enumerate(centers)]
        crops = [beam_crop(P, R_TRUE, 1.0) for P in clouds]
        grid = estimate_from_crops(crops, R_TRUE, 1.0, search="grid")
        fast = estimate_from_crops(crops, R_TRUE, 1.0)
        assert len(fast.factors) < len(grid.factors)  # fewer widths scanned
        assert abs(fast.beam_width_deg - grid.beam_width_deg) < 0.02, (true_deg, grid, fast)
        assert abs(fast.beam_width_deg - true_deg) < 0.06
