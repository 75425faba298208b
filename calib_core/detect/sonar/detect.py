"""Find the calibration sphere in a sonar point cloud (sonar frame, metres).

Main entry: :func:`detect_sphere_in_cloud`.

Beam-width (blooming) model. The sonar sits at the origin of the cloud's frame; each beam
has a centre-line direction ``d`` (the direction of its point from the origin) and a cone of
half-angle ``h = beam_width / 2``; it reports the FIRST return inside its cone, placed along
``d``. For a sphere (centre ``c``, radius ``r``) the range to the sphere along a direction at
angle ``phi`` from ``c/|c|`` is ``rho(phi) = |c| cos(phi) - sqrt(r^2 - |c|^2 sin^2(phi))``
(the near root of ``|t u - c| = r``), which grows with ``phi`` up to the limb
``phi_t = asin(r/|c|)``. The cone of a beam at angle ``theta`` from ``c/|c|`` contains the
directions whose angle to ``c/|c|`` lies in ``[max(theta - h, 0), theta + h]``, so its first
return is at ``rho(max(theta - h, 0))`` while ``theta - h <= phi_t`` and there is none beyond.
Beams whose centre line misses the sphere but whose cone grazes it therefore report points
outside the true silhouette, nearer than the surface along their centre line: the cloud looks
bigger and closer. Fitting ``c`` with this model removes that bias; the naive fits (Euclidean
distance to a sphere of known or free radius) are kept as baselines.

The same detector serves any range sensor whose returns start at the frame origin: with a
beam width of 0 (a LiDAR, an RGB-D camera) the cone model is the plain first-return model.

Pipeline: coarse candidates on a thinned, voxelised cloud without its large planes, ranked
and pre-screened (:mod:`.search`); the best few are re-fitted at full resolution inside
a crop with the cone model and judged (residual scale against the sensor noise measured on the
planes, coverage of the part of the disc the beams sampled, purity of the returns inside it,
whether a surface continues its outline over a long arc, diameter). A sphere may rest on or
hang from something on one side (a seat, a table, a stick, a chain) or be held in hands. The
sensor's noise is measured on the planes against range (constant for a sonar or a LiDAR,
growing with the square of the range for a depth camera) and judged at each candidate's range.
More than one acceptable candidate gives "two candidates" unless one has CLEAR_WINNER times the
other's evidence (score x agreement of the size seen with session.yaml's, given how precisely it
was measured x scatter against the sensor noise: a carried ball beats the shoulders and head of
the person behind it), or when only the leader's outline hangs free while a surface continues every
other one's over a long arc (a head on its shoulders: :func:`_free_leader`), or when one hangs free
and hides part of every other one behind it (a ball held out in front of its carrier's body:
:func:`_in_front`); a sphere of another
size is reported, not used. Every refusal says why, in words an operator can act on.
The effective beam width (down to 0) is estimated per session with
:func:`calib_core.detect.sonar.beam.estimate_beam_width_deg`.

Approximations: circular uniform beam cone (no beam pattern, side lobes or multipath). The
covariance is the fit's (range noise) plus an isotropic model-error floor of
``MODEL_FLOOR_BEAM_FRACTION`` of the beam footprint (range x beam width), set so that the centre
errors on synthetic sonar sessions and single captures have a mean squared Mahalanobis distance
of ~1 per axis (`benchmarks/bench_range_cov.py --floors`; re-derived on the simulator whose
beam's sub-rays average on its axis: 0.02 had been sized on a tilted one and stated twice the
error in sd). Real beams will need more, which the
solver's chi-square inflation then supplies. The fit's covariance does not let returns grazing the
limb pin the centre (:func:`calib_core.detect.sonar.fit._cov_jacobian`), and the final cone fit is
averaged with the one without a footprint, weighed by the capture's own returns
(:func:`calib_core.detect.sonar.cov.footprint_averaged`): a footprint the session's width scan
read but the ball does not show no longer biases the centre (`benchmarks/bench_range_cov.py`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from calib_core.detect.sonar.cov import footprint_averaged
from calib_core.detect.sonar.fit import FitResult, angle_to_axis_rad, cone_residuals, fit_sphere
from calib_core.detect.sonar.outline import (
    attached_sectors,
    attached_span,
    free_outline_mask,
    longest_attached_arc,
    roughness_m,
)
from calib_core.detect.sonar.search import (
    Candidate,
    PreparedSearch,
    disc_coverage,
    find_candidates,
    crop_ball,
    noise_at,
    start_center,
)
from calib_core.detect.sonar.streams import lowest_hashes
from calib_core.detect.types import SonarDetection

METHODS = ("cone-model", "known-radius", "free-radius")
MIN_POINTS = 20
QUICK_POINTS = 150  # points of a candidate's crop for the first look
JUDGE_POINTS = 600  # points of a candidate's crop used to judge it (the final fit uses all)
MAX_JUDGED = 16  # candidates pre-screened (cheap), best coarse quality first
MAX_FULL = 5  # of those, judged at full resolution
RING_PROBLEM = "part of a larger surface"
MAX_SIGMA_REL = 0.15  # residual scale above this fraction of the radius: not this sphere
# ... however noisy the sensor: with returns scattered over a third of the radius a sphere's
# relief is not measured (a far stereo depth patch of a wall passes for anything)
NOISY_SIGMA_CAP_REL = 1.0 / 3.0
MIN_INLIERS = 12
MIN_COVERAGE = 0.7
MIN_COVERAGE_SEEDED = 0.4
MIN_PURITY = 0.6
MAX_RING_SECTORS = 10  # of 16 around the outline continued by a surface: a cap of it, not a ball resting on it
# relative: a larger difference between the diameter the cone model sees and session.yaml's
# makes it "a sphere of another size" (a decoy, or a wrong diameter): reported, never used,
# unless an operator picked it (then fitted with the diameter it shows, with a warning)
DIAMETER_TOL = 0.15
ROUGH_NOISE = 1.3  # a first look scattered beyond this x the planes' noise (+2 mm) is tried from other starts
ROUGH_NOISE_CAP = 0.15  # x radius: the most a crop's local scatter may count as the sensor's noise
HOLDER_INNER = 0.7  # of the disc's angular radius: returns within it stay in the final fit whatever touches it
SIZE_GATE = 0.5  # radii from the known-radius sphere: returns further off do not measure its size
SIZE_SYSTEMATIC = 0.03  # relative: how far off a sensor may see a sphere's size (see _Judged.evidence)
DIAMETER_WARN = 0.06  # relative: above it a found sphere carries a warning
CLEAR_WINNER = 3.0  # score ratio above which the best of two same-size candidates is taken
FREE_ARC = 3  # of 16 sectors, in one run: what a hand, a stick or a chain continues of a ball's outline
BODY_ARC = 5  # of 16 (over 110 deg): a round thing on a larger body (a head on shoulders, a rock in the seabed)
MODEL_FLOOR_BEAM_FRACTION = 0.006  # 1-sigma model error per axis, as a fraction of range x beam width


@dataclass
class _Judged:
    """A candidate re-fitted at full resolution (indices into the working cloud)."""

    cand: Candidate
    idx: np.ndarray  # crop (indices into the working cloud)
    idx_j: np.ndarray  # the subset of the crop the judgement used (indices into idx)
    fit: FitResult
    radius_cone_m: float
    coverage: float
    purity: float
    score: float
    problem: str  # "" when acceptable
    radius_fit_m: float = float("nan")  # radius of ``fit``: the session's, or the one seen
    radius_sd_m: float = float("nan")  # standard deviation of radius_cone_m
    noise_m: float = float("nan")  # the sensor's range noise at the candidate (from the planes)

    def evidence(self, r: float) -> float:
        """The score weighed by how well the size seen agrees with ``r`` given how precisely it
        was measured (plus SIZE_SYSTEMATIC of it: sensors see sizes a few % off), and by how
        much more the returns scatter about the fit than the sensor's range noise there
        (``noise_m``, NaN: not known): what tells the ball from a round thing of about its size nearby (a
        person's shoulders or head, the top of a post)."""
        e = self.score
        if np.isfinite(self.radius_cone_m) and np.isfinite(self.radius_sd_m):
            z = (self.radius_cone_m - r) / np.hypot(self.radius_sd_m, SIZE_SYSTEMATIC * r)
            e *= float(np.exp(-0.5 * z * z))
        if np.isfinite(self.noise_m) and self.fit is not None and self.fit.sigma_m > 0:
            e *= min(1.0, ((self.noise_m + 0.001) / self.fit.sigma_m) ** 2)
        return e


def _max_sigma(radius: float, noise_m: float) -> float:
    """Largest residual scale (m) a sphere of ``radius`` may show (see MAX_SIGMA_REL)."""
    noisy = min(2.0 * noise_m + 0.002, NOISY_SIGMA_CAP_REL * radius) if np.isfinite(noise_m) else 0.0
    return max(MAX_SIGMA_REL * radius, noisy)


def _assess(X, R, D, fit: FitResult, radius: float, h: float, seeded: bool, noise_m: float):
    """(coverage, purity, problem) of a cone-model fit of a sphere of ``radius`` to the crop;
    ``noise_m``: the sonar's range noise measured on the planes of the cloud (or NaN)."""
    c = fit.center_m
    cn = float(np.linalg.norm(c))
    alpha = float(np.arcsin(min(radius / cn, 1.0))) + h
    theta = angle_to_axis_rad(D, c / cn)
    in_disc = theta <= alpha * 1.02
    inl = fit.inliers
    n_in = int(inl.sum())
    purity = float((inl & in_disc).sum() / max(int(in_disc.sum()), 1))
    # of the parts of the disc that any beam sampled (a sparse scan samples a few rings),
    # the share that returned from the sphere
    sampled = disc_coverage(D[in_disc], c / cn, alpha)
    coverage = disc_coverage(D[inl], c / cn, alpha) / max(sampled, 1.0 / 12)
    sig = fit.sigma_m
    rough = roughness_m(R[in_disc], D[in_disc])
    ring = attached_span(attached_sectors(R, D, c, radius, alpha, h, noise_m))
    problem = ""
    if n_in < MIN_INLIERS:
        problem = f"too few returns on the sphere ({n_in})"
    elif sig > _max_sigma(radius, noise_m):
        problem = f"returns too scattered for a sphere (sigma {sig * 1000:.0f} mm)"
    elif np.isfinite(noise_m) and sig > 2.0 * noise_m + 0.002 and sig > MAX_SIGMA_REL * radius / 3:
        problem = (f"not sphere-shaped (fit sigma {sig * 1000:.0f} mm, sensor noise "
                   f"{noise_m * 1000:.0f} mm)")
    elif not sig <= 2.0 * rough + 0.002:  # the surface is smooth but not this sphere
        problem = (f"not sphere-shaped (fit sigma {sig * 1000:.0f} mm, surface noise "
                   f"{rough * 1000:.0f} mm)")
    elif purity < MIN_PURITY:
        problem = f"not sphere-shaped (only {purity:.0%} of the returns on the sphere)"
    elif coverage < (MIN_COVERAGE_SEEDED if seeded else MIN_COVERAGE):
        problem = f"sphere only partly seen (coverage {coverage:.0%})"
    elif ring > MAX_RING_SECTORS:  # (an operator's pick overrides this one, see _judge)
        problem = f"{RING_PROBLEM} (it continues the outline over {ring}/16 of it)"
    return coverage, purity, problem


@dataclass
class _FirstLook:
    """The cheap first fit on at most QUICK_POINTS points of a crop, and (computed once, on
    demand) a free-radius fit of the same points: is it a sphere of another size?"""

    Xq: np.ndarray
    quick: FitResult
    r: float
    h: float
    noise_m: float
    _free: FitResult | None = None

    def other_size_start(self):
        """(centre, radius) of a sphere of another size seen in the first-look points, or None."""
        if self._free is None:
            self._free = fit_sphere(self.Xq, self.quick.center_m, self.r, model="cone",
                                    free_radius=True, half_angle_rad=self.h, sigma0_m=0.01,
                                    n_rounds=2)
        f, r = self._free, self.r
        if f.ok and f.sigma_m <= _max_sigma(f.radius_m, self.noise_m) and 0.6 * r <= f.radius_m <= 1.6 * r:
            return f.center_m, f.radius_m
        return None


def _crop(P: np.ndarray, cand: Candidate, r: float, h: float):
    """(start centre, crop indices into P, judged subset of the crop (indices into it))."""
    cn0 = float(np.linalg.norm(cand.center_m))
    start = start_center(cand, r)
    idx = crop_ball(P, start, 1.6 * r + cn0 * np.tan(h) + 0.05)
    # the crop in an order keyed to the points themselves (the same whatever their order in
    # the cloud or what else it holds); judged on its first JUDGE_POINTS, _finish refits on all
    idx = idx[lowest_hashes(P[idx], len(idx))]
    return start, idx, np.arange(min(len(idx), JUDGE_POINTS))


def _size_seen(X, D, fit: FitResult, r: float, h: float) -> tuple[float, float]:
    """(radius, its standard deviation) the cone model supports: free radius, robustly, on the
    returns inside the disc of the known-radius fit (its chain, stick or stand lies outside)
    that lie within SIZE_GATE radii of its surface (a block, a hand or a seat edge in front of
    part of the ball is not), NaNs if no fit."""
    cn = float(np.linalg.norm(fit.center_m))
    disc = angle_to_axis_rad(D, fit.center_m / cn) <= 1.05 * (np.arcsin(r / cn) + h)
    ra, _ = cone_residuals(fit.center_m, r, np.linalg.norm(X, axis=1), D, h)
    near = disc & (np.abs(ra) <= SIZE_GATE * r)
    if near.sum() >= MIN_INLIERS:
        disc = near
    fine = fit_sphere(X[disc], fit.center_m, r, model="cone", free_radius=True,
                      half_angle_rad=h, sigma0_m=max(fit.sigma_m, 1e-3))
    if not fine.ok:
        return float("nan"), float("nan")
    return fine.radius_m, float(np.sqrt(max(fine.cov_radius_m2, 0.0)))


def _score(coverage: float, purity: float, r_cone: float, r: float, sig: float) -> float:
    rel = (r_cone - r) / r if np.isfinite(r_cone) else 0.0
    s = coverage * purity * float(np.exp(-0.5 * (rel / 0.15) ** 2)) / (1 + (sig / (0.1 * r)) ** 2)
    return float(np.clip(s, 0, 1))


def _judge(P: np.ndarray, cand: Candidate, r: float, h: float, seeded: bool,
           noise_m: float = float("nan")) -> _Judged:
    """Full-resolution cone-model fits and tests around one coarse candidate.

    The sphere is fitted with the session radius and, robustly, with a free radius; when the
    free radius differs by more than DIAMETER_TOL (a decoy, or a wrong diameter in
    session.yaml) the candidate is judged, and later refined, with the radius it shows.
    """
    start, idx, idx_j = _crop(P, cand, r, h)
    bad = _Judged(cand, idx, idx_j, None, float("nan"), 0.0, 0.0, 0.0, "")
    if len(idx) < MIN_INLIERS:
        bad.problem = f"too few returns on the sphere ({len(idx)})"
        return bad
    X = P[idx[idx_j]]
    if not np.isfinite(noise_m):  # no plane to measure it on: the local scatter of the crop
        noise_m = _crop_noise(X, r)
        bad.noise_m = noise_m
    look = _first_look(X, start, r, h, noise_m, bad)
    if look is None:
        return bad
    fit = fit_sphere(X, look.quick.center_m, r, model="cone", half_angle_rad=h,
                     sigma0_m=max(min(look.quick.sigma_m, 0.01), 1e-3), warm=True)
    bad.fit = fit
    cn = float(np.linalg.norm(fit.center_m))
    if not fit.ok or cn <= r or np.linalg.norm(fit.center_m - start) > r:
        bad.problem = "sphere fit did not converge"
        return bad
    if fit.sigma_m > _max_sigma(r, noise_m) and look.other_size_start() is None:
        bad.problem = f"returns too scattered for a sphere (sigma {fit.sigma_m * 1000:.0f} mm)"
        return bad
    R = np.linalg.norm(X, axis=1)
    D = X / R[:, None]
    coverage, purity, problem = _assess(X, R, D, fit, r, h, seeded, noise_m)
    r_fit = r
    r_cone, sd = (float("nan"), 0.0) if problem else _size_seen(X, D, fit, r, h)
    # sparse scans (a few LiDAR rings) pin the size loosely: allow for its uncertainty
    tol = max(DIAMETER_TOL * r, 3.0 * sd) if np.isfinite(sd) else DIAMETER_TOL * r
    if problem or not abs(r_cone - r) <= tol:
        other = _as_other_size(X, R, D, look, fit, r, h, seeded, noise_m)
        if other is not None:
            fit, r_fit, r_cone, (coverage, purity, problem) = other
    if seeded and problem.startswith(RING_PROBLEM):  # the operator says it is the sphere
        problem = ""
    if not problem and not (np.isfinite(r_cone) and 0.6 * r <= r_cone <= 1.6 * r
                            and (r_fit != r or abs(r_cone - r) <= tol)):
        problem = size_problem(r_cone, r)
    return _Judged(cand, idx, idx_j, fit, float(r_cone), coverage, purity,
                   _score(coverage, purity, r_cone, r, fit.sigma_m), problem, r_fit,
                   float(sd) if r_fit == r else float("nan"), noise_m)


def _crop_noise(X: np.ndarray, r: float) -> float:
    """The sensor's range noise (m) when the cloud has no plane to measure it on (a depth
    camera's few returns of a ball far off, a room seen too close for its walls to count):
    the local range scatter of the crop's returns (:func:`roughness_m`, a median over
    neighbours, so depth edges count little), at most ROUGH_NOISE_CAP x the radius so that a
    cloud of scattered returns is not taken for a noisy sphere; NaN with too few returns."""
    R = np.linalg.norm(X, axis=1)
    if len(X) < 3 * MIN_INLIERS:
        return float("nan")
    return float(min(roughness_m(R, X / R[:, None]), ROUGH_NOISE_CAP * r))


def _first_look(X, start, r, h, noise_m, bad: _Judged) -> _FirstLook | None:
    """Cheap fit on at most QUICK_POINTS points (most clutter ends here); None (with
    ``bad.problem`` set) when the candidate is hopeless. A hopeless or rough first look is
    tried again from six nearby starts (a coarse centre pulled into the seat or table under the
    ball)."""
    Xq = X[::max(1, len(X) // QUICK_POINTS)]
    quick = fit_sphere(Xq, start, r, model="cone", half_angle_rad=h, sigma0_m=0.01, n_rounds=2)
    look = _FirstLook(Xq, quick, r, h, noise_m)
    # scattered beyond the sensor noise: perhaps a basin that takes in what holds the ball
    rough = np.isfinite(noise_m) and quick.ok and quick.sigma_m > ROUGH_NOISE * noise_m + 0.002
    if rough or _hopeless(look, start):
        look = _FirstLook(Xq, _restart(Xq, start, r, h, quick), r, h, noise_m)
    bad.fit = look.quick
    why = _hopeless(look, start)
    if why:
        bad.problem = why
        return None
    return look


def _hopeless(look: _FirstLook, start) -> str:
    """Why a first look ends the candidate ("" if it does not)."""
    q, r = look.quick, look.r
    if not q.ok or np.linalg.norm(q.center_m - start) > r:
        return "sphere fit did not converge"
    if q.sigma_m > 1.5 * _max_sigma(r, look.noise_m) and look.other_size_start() is None:
        return f"returns too scattered for a sphere (sigma {q.sigma_m * 1000:.0f} mm)"
    return ""


def _restart(Xq, start, r, h, quick: FitResult) -> FitResult:
    """The first look from six starts a quarter radius off the coarse centre; the fit whose
    returns are best explained (truncated quadratic cost at a fixed 1 cm scale, so fits that
    keep different numbers of points compare fairly)."""
    R = np.linalg.norm(Xq, axis=1)
    D = Xq / R[:, None]

    def cost(f: FitResult) -> float:
        if not f.ok or np.linalg.norm(f.center_m - start) > r:
            return np.inf
        a, b = cone_residuals(f.center_m, r, R, D, h)
        return float(np.sum(np.minimum(np.hypot(a, b) / 0.01, 3.0) ** 2))

    best, best_cost = quick, cost(quick)
    for f in _restarts(Xq, R, D, start, r, h):
        c = cost(f)
        if c < best_cost:
            best, best_cost = f, c
    if best is quick:
        return quick
    # the starts ran one robust round each: the winner gets the trimmed round too
    fine = fit_sphere(Xq, best.center_m, r, model="cone", half_angle_rad=h, sigma0_m=0.01, n_rounds=2)
    return fine if cost(fine) <= best_cost else best


def _restarts(Xq, R, D, start, r, h):
    """First looks (one robust round each) from six starts a quarter radius off the coarse
    centre, then one on only the returns inside the start's disc (a block or seat the ball
    rests on, seen below or beside it, can outnumber the ball's returns in the crop and drag
    every fit into it)."""
    for step in np.vstack([np.eye(3), -np.eye(3)]) * 0.25 * r:
        yield fit_sphere(Xq, start + step, r, model="cone", half_angle_rad=h, sigma0_m=0.01, n_rounds=1)
    sn = float(np.linalg.norm(start))
    disc = angle_to_axis_rad(D, start / sn) <= np.arcsin(min(r / sn, 1.0)) + h
    if disc.sum() >= MIN_INLIERS:
        yield fit_sphere(Xq[disc], start, r, model="cone", half_angle_rad=h, sigma0_m=0.01,
                         n_rounds=1, loss="cauchy")


def _as_other_size(X, R, D, look: _FirstLook, fit: FitResult, r, h, seeded, noise_m):
    """Perhaps a sphere of another size (a decoy, or a wrong diameter in session.yaml): free
    radius, robustly on all points, judged with the size it shows. (fit, r_fit, r_cone,
    assessment) or None."""
    start_free = look.other_size_start()
    if start_free is None:
        return None
    free = fit_sphere(X, start_free[0], start_free[1], model="cone", free_radius=True,
                      half_angle_rad=h, sigma0_m=max(min(fit.sigma_m, 0.01), 1e-3))
    tol = max(DIAMETER_TOL * r, 3.0 * np.sqrt(max(free.cov_radius_m2, 0.0)))
    if (free.ok and abs(free.radius_m - r) > tol and 0.6 * r <= free.radius_m <= 1.6 * r
            and float(np.linalg.norm(free.center_m)) > free.radius_m):
        return free, free.radius_m, free.radius_m, _assess(X, R, D, free, free.radius_m, h, seeded, noise_m)
    return None


def size_problem(r_seen: float, r: float) -> str:
    """The reason shown when the sphere's size disagrees with session.yaml's diameter."""
    if not np.isfinite(r_seen):
        return "sphere size could not be measured"
    return f"sphere seen {2 * r_seen:.2f} m across, {2 * r:.2f} m expected"


def _not_found(reason: str, method: str, **extras) -> SonarDetection:
    return SonarDetection(found=False, reason=reason, method=method, extras=dict(extras))


def detect_sphere_in_cloud(points_sonar_m: np.ndarray, sphere_radius_m: float,
                           beam_width_deg: float = 1.0, method: str = "cone-model",
                           seed_center_m=None, seed_radius_m: float = 0.3,
                           rng_seed: int = 0, prepared: PreparedSearch | None = None) -> SonarDetection:
    """Find one sphere of known radius in a sonar cloud.

    Args:
        points_sonar_m: (N,3) finite points in the sonar frame (m); the beams start at the
            frame origin.
        sphere_radius_m: the target's radius from session.yaml (m).
        beam_width_deg: full beam width (deg; BV5000: 1). The cone-model fit uses half of it.
        method: "cone-model" (beam-width aware), or the naive baselines "known-radius"
            (least squares on the distance to a sphere of the known radius) and "free-radius"
            (radius fitted too). All three share the candidate search and the tests.
        seed_center_m: optional (3,) point (m, sonar frame) an operator picked on or near the
            sphere: only points within ``seed_radius_m`` + a sphere's reach are searched, and
            the acceptable candidate nearest the pick wins.
        seed_radius_m: search radius around the seed (m).
        rng_seed: key of the thinning and RANSAC draws (:mod:`.streams`; results are
            deterministic, and each cluster's draws depend on its own returns only).
        prepared: the beam-width-independent part of the candidate search of these points
            (:func:`.search.prepare_search` with ``rng_seed``; not with a seed), e.g. shared by the
            detections of one cloud at two beam widths; the detection is the same without it.

    Returns:
        :class:`SonarDetection`; ``found=False`` with a ``reason`` when nothing trustworthy is
        found ("empty cloud", "too few points", "no sphere-like cluster", "two candidates", ...).
    """
    if method not in METHODS:
        raise ValueError(f"unknown sonar detection method {method!r}; use one of {METHODS}")
    P = np.asarray(points_sonar_m, dtype=float).reshape(-1, 3)
    r = float(sphere_radius_m)
    h = np.radians(float(beam_width_deg)) / 2.0
    seed = None if seed_center_m is None else np.asarray(seed_center_m, float).reshape(3)
    base, why = _working_points(P, seed, seed_radius_m, r, h)
    if why:
        return _not_found(why, method, n_points=len(P))
    if prepared is not None and seed is not None:
        raise ValueError("a prepared search covers the whole cloud, not the points near a seed")
    W = P if base is None else P[base]
    cands, info = find_candidates(W, r, h, rng_seed, max_candidates=MAX_JUDGED, prepared=prepared)
    if not cands:
        return _not_found("no sphere-like cluster", method, n_points=len(P),
                          n_clusters=int(info.get("n_clusters", 0)))
    if seed is not None:
        cands = _near_seed(cands, seed, seed_radius_m + 2 * r)
        if not cands:
            return _not_found("nothing sphere-like near the picked point", method, n_points=len(P))
    # the sensor's noise where each candidate is (a depth camera's grows with range)
    judged = [_judge(W, k, r, h, seed is not None, _noise_near(info, k.center_m)) for k in cands[:MAX_FULL]]
    chosen, extras = _choose(judged, r, seed, W, h)
    if chosen is None:
        reason = extras.pop("reason")
        return _not_found(reason, method, n_points=len(P), **extras)
    return _finish(P, W, base, chosen, r, h, method, len(P), info, extras)


def _working_points(P, seed, seed_radius_m: float, r: float, h: float) -> tuple[np.ndarray | None, str]:
    """(indices of the points searched, None for all of them; why nothing can be searched, or
    "") for the cloud ``P`` and an operator's pick ``seed`` (or None)."""
    if len(P) == 0:
        return None, "empty cloud"
    if len(P) < MIN_POINTS:
        return None, f"too few points ({len(P)} < {MIN_POINTS})"
    base = None if seed is None else _near_pick(P, seed, seed_radius_m, r, h)
    if base is not None and len(base) < MIN_POINTS:
        return None, f"too few points near the picked point ({len(base)})"
    return base, ""


def _near_seed(cands: list[Candidate], seed: np.ndarray, reach_m: float) -> list[Candidate]:
    """The candidates within ``reach_m`` of an operator's pick, nearest first."""
    near = sorted(cands, key=lambda k: np.linalg.norm(k.center_m - seed))
    return [k for k in near if np.linalg.norm(k.center_m - seed) < reach_m]


def _near_pick(P, seed, seed_radius_m: float, r: float, h: float) -> np.ndarray:
    """Indices of the points a sphere near an operator's pick can reach."""
    reach = float(seed_radius_m) + 2.0 * r + float(np.linalg.norm(seed)) * np.tan(h) + 0.05
    return crop_ball(P, seed, reach)


def _noise_near(info: dict, center_m) -> float:
    """The range noise the cloud's planes show at the candidate's range, never below the
    planes' overall noise (NaN without planes)."""
    at = noise_at(info["noise_model"], float(np.linalg.norm(center_m)))
    return float(np.nanmax([at, info["noise_m"]])) if np.isfinite(info["noise_m"]) else float("nan")


def _choose(judged: list[_Judged], r: float, seed, W: np.ndarray, h: float) -> tuple[_Judged | None, dict]:
    """The candidate to use and the detection's extras, or (None, extras with a ``reason``):
    the operator's pick decides when there is one; else one candidate of the session's size
    (a second one is tolerated when the first has CLEAR_WINNER times its evidence, or when
    only the first hangs free: :func:`_free_leader`)."""
    good = _dedupe([j for j in judged if not j.problem], r)
    if not good:
        best = max(judged, key=lambda j: j.score)
        why = best.problem or "no sphere-like cluster"
        at = float(np.linalg.norm(best.cand.center_m))
        return None, {"reason": f"no sphere-like cluster (best candidate, {at:.2f} m away: {why})",
                      "n_candidates": len(judged)}
    nominal = sorted((j for j in good if j.radius_fit_m == r), key=lambda j: -j.evidence(r))
    other = [j for j in good if j.radius_fit_m != r]
    if seed is not None:  # the operator's pick decides, whatever its size
        return min(good, key=lambda j: np.linalg.norm(j.fit.center_m - seed)), {}
    resolved = ""
    if len(nominal) > 1 and nominal[0].evidence(r) < CLEAR_WINNER * nominal[1].evidence(r):
        nominal, resolved = _resolve(nominal, W, r, h)
        if not resolved:
            return None, _two_candidates(nominal, r, len(good))
    if not nominal:  # sphere-like, but not of session.yaml's size: a decoy or a wrong diameter
        k = max(other, key=lambda j: j.score)
        return None, {"reason": f"only a sphere of another size: seen {2 * k.radius_cone_m:.3f} m across, "
                                f"session.yaml says {2 * r:.3f} m (check the diameter, or pick the sphere by hand)",
                      "candidate_center": [round(float(v), 4) for v in k.fit.center_m],
                      "candidate_diameter_m": round(2 * k.radius_cone_m, 3)}
    chosen, extras = nominal[0], {}
    if len(nominal) > 1:  # a clear winner: say what else was seen
        k = nominal[1]
        seen = f", seen {2 * k.radius_cone_m:.2f} m across" if np.isfinite(k.radius_cone_m) else ""
        extras["warning"] = (f"another round object at {np.linalg.norm(k.fit.center_m):.2f} m{seen} "
                             f"scored {k.score:.2f} against {chosen.score:.2f}")
        extras["other_candidates"] = _centres(nominal[1:])
    if other:
        extras["ignored_other_sizes_m"] = [round(2 * k.radius_cone_m, 4) for k in other]
    if resolved:
        extras["resolved_by"] = resolved
    return chosen, extras


def _two_candidates(nominal: list[_Judged], r: float, n_good: int) -> dict:
    """The extras of a "two candidates" refusal (with each candidate's centre and evidence)."""
    at = " and ".join(f"{np.linalg.norm(k.fit.center_m):.2f} m" for k in nominal[:3])
    pos = "; ".join(str(np.round(k.fit.center_m, 3).tolist()) for k in nominal[:3])
    return {"reason": f"two candidates: round objects of the sphere's size at {at} (centres {pos} m)",
            "n_candidates": n_good, "two_candidates": _centres(nominal),
            "candidate_evidence": [round(j.evidence(r), 4) for j in nominal]}


def _resolve(nominal: list[_Judged], W: np.ndarray, r: float, h: float) -> tuple[list[_Judged], str]:
    """(the candidates, the one to take first, and why; or why "" when none can be told apart):
    the leader hanging free while the others continue into larger surfaces (:func:`_free_leader`),
    or the one candidate in front of all the others (:func:`_in_front`)."""
    why = _free_leader(nominal, W, r, h)
    if why:
        return nominal, why
    k, why = _in_front(nominal, W, r, h)
    return ([nominal[k]] + nominal[:k] + nominal[k + 1:], why) if why else (nominal, "")


def _in_front(nominal: list[_Judged], W: np.ndarray, r: float, h: float) -> tuple[int, str]:
    """(index, why) of the candidate that hides part of every other one (their discs overlap in
    the sensor's view and each other one is at least a radius farther) while its own outline
    hangs free but for what holds it (at most FREE_ARC sectors in one run); (-1, "") if none.
    A ball held out in front of its carrier hides part of the body behind it, and what is left
    of the body round that hole (a torso's side, a shoulder) can fit a sphere of its size: a
    round thing with part of its outline hidden is not known to be round there."""
    C = [j.fit.center_m for j in nominal]
    rng_m = [float(np.linalg.norm(c)) for c in C]
    alpha = [float(np.arcsin(min(r / d, 1.0))) + h for d in rng_m]
    k = int(np.argmin(rng_m))
    for i, c in enumerate(C):
        if i == k:
            continue
        sep = float(np.arccos(np.clip(C[k] @ c / (rng_m[k] * rng_m[i]), -1.0, 1.0)))
        if sep >= alpha[k] + alpha[i] or rng_m[i] < rng_m[k] + r:
            return -1, ""
    arc = longest_attached_arc(_attached(W, nominal[k], r, h))
    if arc > FREE_ARC:
        return -1, ""
    behind = ", ".join(f"{d:.2f} m" for i, d in enumerate(rng_m) if i != k)
    return k, (f"occlusion: this round object ({rng_m[k]:.2f} m) hides part of the other"
               f"{'s' if len(C) > 2 else ''} behind it ({behind}) and hangs free but over {arc}/16 "
               f"(a ball held out in front of its carrier?)")


def _free_leader(nominal: list[_Judged], W: np.ndarray, r: float, h: float) -> str:
    """Why the candidate with the most evidence (not CLEAR_WINNER times the next) is the sphere
    after all, or "": its outline hangs free but for what holds it (at most FREE_ARC sectors in
    one run: a hand, a stick, a chain), while a surface continues every other one's over a long
    arc (at least BODY_ARC sectors: the body a head sits on, the seabed a rock is buried in).
    It only ever confirms the leader: a round thing that is part of something larger is not
    the loose ball, but a loose round thing is not always the ball."""
    arcs = [longest_attached_arc(_attached(W, j, r, h)) for j in nominal]
    if arcs[0] > FREE_ARC or min(arcs[1:]) < BODY_ARC:
        return ""
    return (f"outline: the other round object{'s' if len(arcs) > 2 else ''} "
            f"({', '.join(f'{np.linalg.norm(j.fit.center_m):.2f} m' for j in nominal[1:])}) "
            f"continue{'' if len(arcs) > 2 else 's'} into a larger surface over "
            f"{min(arcs[1:])}/16 of the outline or more (a head on its shoulders?); this one "
            f"hangs free but over {arcs[0]}/16")


def _attached(W: np.ndarray, j: _Judged, r: float, h: float) -> np.ndarray:
    """The sectors around a judged candidate's outline that something continues
    (:func:`calib_core.detect.sonar.outline.attached_sectors`, on the returns it was judged on)."""
    X = W[j.idx[j.idx_j]]
    R = np.linalg.norm(X, axis=1)
    c = j.fit.center_m
    cn = float(np.linalg.norm(c))
    # (without the fattened rim: a body continues a head's outline from its edge on, as in range5)
    return attached_sectors(R, X / R[:, None], c, r, float(np.arcsin(min(r / cn, 1.0))) + h, h, j.noise_m,
                            rim=False)


def _centres(judged: list[_Judged]) -> list[list[float]]:
    """Candidates' fitted centres (m, sonar frame) as an entry records them (for the
    session-level choice, :mod:`calib_core.disambiguate.sonar`)."""
    return [[round(float(v), 4) for v in j.fit.center_m] for j in judged]


def _dedupe(judged: list[_Judged], r: float) -> list[_Judged]:
    out: list[_Judged] = []
    for j in sorted(judged, key=lambda j: -j.score):
        if all(np.linalg.norm(j.fit.center_m - o.fit.center_m) > r for o in out):
            out.append(j)
    return out


def _finish(P, W, base, j: _Judged, r, h, method, n_all, info, extras) -> SonarDetection:
    """Method-specific final fit on the chosen candidate's crop; assemble the detection."""
    fits = _final_fits(W[j.idx], j, r, h, method, j.noise_m)
    if fits is None:
        return _not_found("sphere fit did not converge", method, n_points=n_all)
    fit, cone, apparent = fits
    mask = np.zeros(n_all, bool)
    sel = j.idx[fit.inliers]
    mask[sel if base is None else base[sel]] = True
    cn = float(np.linalg.norm(fit.center_m))
    extras.update({
        "range_m": round(cn, 4),
        "sigma_range_m": round(float(cone.sigma_m), 5),
        "coverage": round(j.coverage, 3),
        "purity": round(j.purity, 3),
        "planes_removed": int(info.get("planes_removed", 0)),
        "plane_noise_m": round(float(info["noise_m"]), 5) if np.isfinite(info["noise_m"]) else None,
    })
    _size_notes(extras, j, r, cone, method)
    return SonarDetection(
        found=True,
        center_sonar_m=np.asarray(fit.center_m, float),
        cov_sonar_m2=np.asarray(fit.cov_center_m2, float) + (MODEL_FLOOR_BEAM_FRACTION * cn * 2 * h) ** 2 * np.eye(3),
        n_inliers=int(fit.inliers.sum()),
        rms_m=float(fit.rms_m),
        score=float(j.score),
        reason="",
        apparent_diameter_m=2.0 * apparent.radius_m if apparent.ok else None,
        diameter_m=2.0 * j.radius_cone_m if np.isfinite(j.radius_cone_m) else None,
        method=method,
        inlier_mask=mask,
        extras=extras,
    )


def _away_from_holder(X, fit: FitResult, radius: float, h: float, noise_m: float,
                      free_radius: bool) -> FitResult:
    """The cone fit again without the returns near the outline in the sectors where something
    continues it over two sectors or more (a seat or a table under the ball, a hand; a thin
    chain or stick touches one and its returns are rejected anyway): a sparse scan's ring
    through a seat's edge, next to the ball's limb, drags the centre towards it (13-25 mm on
    a 16-ring LiDAR). The inner part of the disc (HOLDER_INNER of its angular radius) stays.
    Inliers are given over all of ``X``; the fit is kept when nothing touches the outline."""
    keep = free_outline_mask(X, fit.center_m, radius, h, noise_m, inner=HOLDER_INNER, min_attached=2)
    if keep is None or keep.all() or keep.sum() < 3 * MIN_INLIERS:
        return fit
    f = fit_sphere(X[keep], fit.center_m, radius, model="cone", half_angle_rad=h, free_radius=free_radius,
                   sigma0_m=max(fit.sigma_m, 1e-3), n_rounds=3, warm=True)
    if not f.ok:
        return fit
    inl = np.zeros(len(X), bool)
    inl[keep] = f.inliers
    return replace(f, inliers=inl)


def _final_fits(X, j: _Judged, r, h, method, noise_m: float = float("nan")):
    """(the method's fit, the cone-model fit, the free-radius Euclidean fit) on the crop ``X``
    of the chosen candidate, or None when a fit the method needs fails."""
    Xj = X[j.idx_j]
    cone = j.fit
    other_size = j.radius_fit_m != r
    if len(Xj) < len(X):  # refine on every point of the crop
        cone = fit_sphere(X, cone.center_m, j.radius_fit_m, model="cone", half_angle_rad=h,
                          free_radius=other_size, sigma0_m=cone.sigma_m, n_rounds=3, warm=True)
        if not cone.ok:
            return None
    if method == "cone-model":
        cone = _away_from_holder(X, cone, j.radius_fit_m, h, noise_m, other_size)
        cone = footprint_averaged(X, cone, h, other_size)
    apparent = fit_sphere(Xj, cone.center_m, r, model="euclid", free_radius=True,
                          sigma0_m=max(cone.sigma_m, 2e-3))
    if method == "cone-model":
        fit = cone
    elif method == "known-radius":
        fit = fit_sphere(X, cone.center_m, r, model="euclid", sigma0_m=max(cone.sigma_m, 2e-3))
    elif len(Xj) == len(X):
        fit = apparent
    else:
        fit = fit_sphere(X, apparent.center_m, apparent.radius_m, model="euclid",
                         free_radius=True, sigma0_m=apparent.sigma_m, n_rounds=2, warm=True)
    return (fit, cone, apparent) if fit.ok else None


def _size_notes(extras: dict, j: _Judged, r: float, cone: FitResult, method: str) -> None:
    """Warn (in ``extras``) when the sphere was seen with another size than session.yaml's."""
    other_size = j.radius_fit_m != r
    seen = f"sphere seen {2 * j.radius_cone_m:.3f} m across, session.yaml says {2 * r:.3f} m"
    size_note = ""
    if other_size:
        size_note = seen
    elif np.isfinite(j.radius_cone_m) and abs(j.radius_cone_m - r) > DIAMETER_WARN * r:
        size_note = seen + ": check the diameter or the beam width (calib_core.detect.sonar.beam.estimate_beam_width_deg)"
    if size_note:
        extras["warning"] = "; ".join(w for w in (extras.get("warning"), size_note) if w)
    if other_size and method == "cone-model":
        extras["fitted_with_diameter_m"] = round(2 * cone.radius_m, 4)
