"""Is the stereo transform as certain as stated? Its own variance factor, from the data.

The range scale of a joint solve is fixed metrically by the stereo baseline, so the scale's F
test (:mod:`calib_core.solve.scale`) leans on the stereo transform's covariance: the test assumes
every stated covariance right up to one common factor. When the stereo transform is worse than
stated (an assumed default of 0.05 deg / 1 mm against a checkerboard calibration 2-5 mm off),
a baseline-length error reads as a scale error and the test finds one that is not there (synthetic
underwater seed 7: scale 1.0068 +- 0.0019, p = 0.00054, for a true 1.0; its stereo |t| 4.7 mm
short; BENCHMARKS.md "Twenty-fourth round").

Five of the stereo transform's six degrees of freedom are seen by the images and the sonar
(everything but the baseline's length, which trades against the scale). With the scale free,
the prior residuals of the stereo block and their redundancy (the leverage-corrected number of
degrees of freedom, as in variance-component estimation) give the block's own variance factor:

    f = sum(prior residual^2) / sum(1 - h_ii)   over the prior rows

iterated with the prior re-weighted by 1 / f (Foerstner's variance-component estimate). The
widened covariance is then used for both models of the test and for the reported covariances.

Two groups, not one: the F test assumes every stated covariance right up to ONE common factor, so
what must agree is the stereo block's factor relative to the detections' own (the same ratio over
the observation rows: images, sonar, ranges). Detections stated conservatively (the rendered
sessions' mean squared Mahalanobis per dof is about 0.5) with a stereo block stated honestly leave
the stereo relatively over-confident by their factor, which the one-group estimate, judging the
block against 1, did not see. So ``f`` is the ratio of the two groups' factors (a two-group
variance-component estimate with the observations as the reference group; leverages and the
solution depend on the ratio of the weights only). Detections stated over-confidently (a factor
above 1, common on real photographs) leave an honest stereo block relatively too wide, and the
scale loses the baseline's information (2 % found in 86-95 % of trials instead of 100 %,
BENCHMARKS.md, session 25): the block may then be narrowed relative to them, down to
:func:`floor_factor`, so that once the fit's variance factor is applied to every covariance it
still counts with at least its stated covariance. A few degrees of freedom cannot vouch for a
stereo calibration better than the file states.
"""

from __future__ import annotations

import numpy as np

from calib_core.solve.refine import Link, RefineResult, RigProblem, jacobian, refine, weights_for

MAX_ITER = 4
# The detections' own factor is read with a prior of this many degrees of freedom at 1 (shrunk
# towards 1 where the data have few): with 4 captures of two cameras it rests on ~3 dof, read as
# low as 0.14, and 1 / that widened an exact stereo transform up to 9.5x (review6's
# bench_stereo_factor_cases.py), throwing away the baseline's hold on the scale.
OBS_PRIOR_DOF = 4.0
# The shells say the stereo covariance was widened from this factor on (its sigma 1.4x): an exact
# stereo transform reads 1.0-1.9 from the noise alone (bench_stereo_factor_cases.py, 4-9 captures),
# and a warning in a third of sound sessions would teach users to skip warnings.
PHRASE_MIN_FACTOR = 2.0
# the block's factor is re-estimated until it changes by less than this (relative)
TOL = 0.05


def prior_rows(problem: RigProblem) -> slice:
    """Rows of the whitened residual vector that hold the stereo priors."""
    start = sum(2 * len(g.ids) * len(g.cams) for g in problem.groups)
    return slice(start, start + 6 * len(problem.free_links))


def group_factors(problem: RigProblem, res: RefineResult) -> dict:
    """The stereo priors' and the observations' variance factors at ``res``: {"prior": (chi2,
    redundancy), "obs": (chi2, redundancy)}, redundancy the sum of 1 - leverage over the group's rows.
    With the stated covariances as they are, whatever loss the fit used: a robust loss's weights
    (below 1 for every capture with Cauchy's) would read as detections stated conservatively."""
    Ws, _ = weights_for(problem, res.state, None, 2.5)
    J = jacobian(problem, res.state, Ws)
    h = np.einsum("ij,jk,ik->i", J, np.linalg.pinv(J.T @ J), J)
    r = problem.whitened(res.state, Ws)
    prior = np.zeros(len(r), bool)
    prior[prior_rows(problem)] = True
    return {k: (float(r[m] @ r[m]), float(np.sum(1.0 - h[m]))) for k, m in (("prior", prior), ("obs", ~prior))}


def block_factor(problem: RigProblem, res: RefineResult, relative: bool = True) -> tuple[float, float, float, float]:
    """(factor, chi2, redundancy, the observations' factor) of the stereo priors at ``res``
    (factor 1 without free links).

    ``relative``: the factor relative to the observations' own (the two-group estimate, see the
    module doc); False: against 1 (the one-group estimate before)."""
    if not problem.free_links:
        return 1.0, 0.0, 0.0, 1.0
    g = group_factors(problem, res)
    chi2, redundancy = g["prior"]
    chi2_obs, red_obs = g["obs"]
    f_obs = (chi2_obs + OBS_PRIOR_DOF) / (red_obs + OBS_PRIOR_DOF) if chi2_obs > 0.0 else 1.0
    if redundancy <= 0.5:
        return 1.0, chi2, redundancy, f_obs
    f = chi2 / redundancy
    return (f / f_obs if relative else f), chi2, redundancy, f_obs


def floor_factor(obs_factor: float) -> float:
    """The least factor on the stereo covariance: 1 / the detections' own factor. The solver applies
    the detections' factor to every covariance (the variance factor of the fit), so the stereo block
    then counts with at least its stated covariance: it may be narrowed relative to detections that
    are over-confident (their factor > 1), never below what the file states in absolute terms."""
    return 1.0 / obs_factor if obs_factor > 0.0 else 1.0


def widened(problem: RigProblem, factor: float, estimate_scale: bool | None = None) -> RigProblem:
    """The problem with every free stereo link's covariance multiplied by ``factor``."""
    links = {n: (Link(L.T_cam_ref, L.cov * factor) if L.cov is not None else L) for n, L in problem.links.items()}
    es = problem.estimate_scale if estimate_scale is None else estimate_scale
    return RigProblem(problem.cams, problem.masks, links, estimate_scale=es, use_ranges=len(problem.range_rows) > 0)


def stereo_factor(prob_free: RigProblem, state, robust: str | None = None, relative: bool = True):
    """(factor, what to report, the scale-free problem widened by it, its fit). The factor is at
    least :func:`floor_factor` of the detections' own (1 with ``relative`` False).

    ``prob_free``: the joint problem with the scale free; ``state``: a starting state. The fit
    returned is that of the problem returned (the scale test reuses it). ``relative``: see
    :func:`block_factor`."""
    total, info = 1.0, {"factor": 1.0, "chi2": 0.0, "redundancy": 0.0, "obs_factor": 1.0}
    prob, res = prob_free, refine(prob_free, state, robust=robust)
    if not prob_free.free_links:  # nothing to judge (stereo transforms held exactly)
        return total, info, prob, res
    for it in range(MAX_ITER):
        f, chi2, red, f_obs = block_factor(prob, res, relative)
        if it == 0:  # as first seen, with the stereo as stated
            info.update(chi2=chi2, redundancy=red, obs_factor=f_obs if relative else 1.0)
        new = max(floor_factor(f_obs) if relative else 1.0, total * f)
        if abs(new - total) <= TOL * total:
            break
        total = new
        prob = widened(prob_free, total)
        res = refine(prob, res.state, robust=robust)
    info["factor"] = total
    return total, info, prob, res


def stereo_factor_phrase(info: dict, assumed: bool) -> str:
    """"joint solve: ..." when the stereo transform's covariance was widened, else "": less certain
    than stated when its own residuals say so; otherwise (its residuals within its sigma, the
    detections' further within theirs) widened to match the detections' conservative covariances."""
    f = float((info or {}).get("factor") or 1.0)
    if f < PHRASE_MIN_FACTOR:  # recorded in calibration.json all the same
        return ""
    how = "assumed" if assumed else "stated"
    chi2, red = float(info.get("chi2", 0.0)), float(info.get("redundancy", 0.0))
    own = chi2 / red if red > 0 else f
    f_obs = float(info.get("obs_factor") or 1.0)
    numbers = (f"the stereo transform's residuals {own ** 0.5:.1f}x its {how} sigma, the detections' "
               f"{f_obs ** 0.5:.1f}x theirs; chi2 {chi2:.1f} on {red:.1f} dof")
    used = "the reported uncertainties" if info.get("scale_held") else \
        "the range scale's test and the reported uncertainties"
    if own > 1.0:
        return (f"joint solve: the images and the sonar show the stereo transform less certain than {how} "
                f"({numbers}): its covariance was widened by a factor {f:.2f} for {used}")
    return (f"joint solve: the detections' covariances are conservative ({numbers}): the stereo transform's "
            f"covariance was widened by a factor {f:.2f} to match them (one common factor for every covariance), "
            f"for {used}")
