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
covariance is only widened (f > 1), never sharpened: a few degrees of freedom cannot vouch for a
stereo calibration better than stated. The widened covariance is then used for both models of
the test and for the reported covariances.
"""

from __future__ import annotations

import numpy as np

from calib_core.solve.refine import Link, RefineResult, RigProblem, jacobian, refine, weights_for

MAX_ITER = 4
# the block's factor is re-estimated until it changes by less than this (relative)
TOL = 0.05


def prior_rows(problem: RigProblem) -> slice:
    """Rows of the whitened residual vector that hold the stereo priors."""
    start = sum(2 * len(g.ids) * len(g.cams) for g in problem.groups)
    return slice(start, start + 6 * len(problem.free_links))


def block_factor(problem: RigProblem, res: RefineResult, robust: str | None = None) -> tuple[float, float, float]:
    """(factor, chi2, redundancy) of the stereo priors at ``res`` (factor 1 without free links)."""
    if not problem.free_links:
        return 1.0, 0.0, 0.0
    Ws, _ = weights_for(problem, res.state, robust, 2.5)
    J = jacobian(problem, res.state, Ws)
    h = np.einsum("ij,jk,ik->i", J, np.linalg.pinv(J.T @ J), J)
    rows = prior_rows(problem)
    r = problem.prior_residuals(res.state)
    redundancy = float(np.sum(1.0 - h[rows]))
    chi2 = float(r @ r)
    return (chi2 / redundancy if redundancy > 0.5 else 1.0), chi2, redundancy


def widened(problem: RigProblem, factor: float, estimate_scale: bool | None = None) -> RigProblem:
    """The problem with every free stereo link's covariance multiplied by ``factor``."""
    links = {n: (Link(L.T_cam_ref, L.cov * factor) if L.cov is not None else L) for n, L in problem.links.items()}
    es = problem.estimate_scale if estimate_scale is None else estimate_scale
    return RigProblem(problem.cams, problem.masks, links, estimate_scale=es, use_ranges=len(problem.range_rows) > 0)


def stereo_factor(prob_free: RigProblem, state, robust: str | None = None):
    """(factor >= 1, what to report, the scale-free problem widened by it, its fit).

    ``prob_free``: the joint problem with the scale free; ``state``: a starting state. The fit
    returned is that of the problem returned (the scale test reuses it)."""
    total, info = 1.0, {"factor": 1.0, "chi2": 0.0, "redundancy": 0.0}
    prob, res = prob_free, refine(prob_free, state, robust=robust)
    if not prob_free.free_links:  # nothing to judge (stereo transforms held exactly)
        return total, info, prob, res
    for it in range(MAX_ITER):
        f, chi2, red = block_factor(prob, res, robust)
        if it == 0:
            info.update(chi2=chi2, redundancy=red)  # as first seen, with the stereo as stated
        new = max(1.0, total * f)
        if abs(new - total) <= TOL * total:
            break
        total = new
        prob = widened(prob_free, total)
        res = refine(prob, res.state, robust=robust)
    info["factor"] = total
    return total, info, prob, res


def stereo_factor_phrase(info: dict, assumed: bool) -> str:
    """"joint solve: the data show the stereo transform ..." when its covariance was widened, else ""."""
    f = float((info or {}).get("factor") or 1.0)
    if f <= 1.0:
        return ""
    how = "assumed" if assumed else "stated"
    return (f"joint solve: the images and the sonar show the stereo transform less certain than {how} "
            f"(its residuals {f ** 0.5:.1f}x the {how} sigma; chi2 {info.get('chi2', 0.0):.1f} on "
            f"{info.get('redundancy', 0.0):.1f} dof): its covariance was widened by a factor {f:.2f} "
            f"for the range scale's test and the reported uncertainties")
