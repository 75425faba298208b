"""One camera's range scale through the sphere's apparent size, with its outline bias.

The camera's image ranges are fitted with the pose, once with the scale held at 1 and once with
it free (the stated F test of :mod:`calib_core.solve.scale` chooses). When the session's
:class:`~calib_core.solve.outline.RangeModel` estimates the outline bias, both fits carry it
(:mod:`calib_core.solve.outline`) and the only systematic left outside the fit is the diameter's
tolerance; otherwise the ranges are taken as they are and the fixed systematic (diameter and
outline tolerance over the apparent radius) is added, as before.

When the scale is not chosen the pose of the fit without ranges is kept (no diameter systematic
in it). When it is, the covariance returned is that of the pose then the scale (the outline
bias marginalised), plus the diameter's term.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from calib_core.solve.model import CameraData
from calib_core.solve.outline import (OUTLINE_INDEX, OutlineRangeProblem, RangeModel, outline_phrase, outline_summary,
                                      with_outline)
from calib_core.solve.refine import RefineResult, RigProblem, refine
from calib_core.solve.scale import ScaleChoice, choose_scale, diameter_term


def _drop_outline(res: RefineResult) -> RefineResult:
    """The fit with the outline bias marginalised out of its covariance (pose, then scale)."""
    cov = np.delete(np.delete(res.cov, OUTLINE_INDEX, 0), OUTLINE_INDEX, 1)
    names = res.param_names[:OUTLINE_INDEX] + res.param_names[OUTLINE_INDEX + 1:]
    return dataclasses.replace(res, cov=cov, param_names=names)


def _fixed_systematic(cd, used, prob, res, mode, robust, rel):
    """The route without an outline parameter: ranges as measured, ``rel`` as a fixed systematic."""
    prob_r = RigProblem([cd], [used], use_ranges=True)
    res_r = refine(prob_r, res.state, robust=robust)
    ch = choose_scale(prob_r, res_r, RigProblem([cd], [used], estimate_scale=True, use_ranges=True), mode, robust,
                      systematic_var=rel**2)
    if not ch.estimated:  # keep the solve without ranges: no diameter systematic in the pose
        return ScaleChoice(res, prob, False, ch.observable, ch.note, ch.test), 0.0
    return ch, diameter_term(ch.problem, ch.res, rel, robust)


def _with_outline(cd, used, prob, res, mode, robust, model: RangeModel):
    """The route with the outline bias estimated (module doc)."""
    R, sig_o = model.sphere_radius_m, model.outline_sigma_px
    prob_r = OutlineRangeProblem(cd, used, R, sig_o)
    res_r = refine(prob_r, with_outline(res.state, 0.0), robust=robust)
    prob_s = OutlineRangeProblem(cd, used, R, sig_o, estimate_scale=True)
    ch = choose_scale(prob_r, res_r, prob_s, mode, robust, systematic_var=model.diameter_rel_sigma**2)
    # the outline bias as the free-scale fit sees it (held at 1 the scale would push into it)
    free = ch.res_free if ch.res_free is not None else refine(prob_s, res_r.state, robust=robust)
    o = outline_summary(prob_s, free)
    test = dict(ch.test or {}, outline_bias=o)
    note = f"{ch.note}; {outline_phrase(cd.name, o)}"
    if not ch.estimated:
        return ScaleChoice(res, prob, False, ch.observable, note, test), 0.0
    extra = diameter_term(ch.problem, ch.res, model.diameter_rel_sigma, robust)
    return ScaleChoice(_drop_outline(ch.res), ch.problem, True, True, note, test), extra


def range_scale_choice(cd: CameraData, used: np.ndarray, prob: RigProblem, res: RefineResult, mode: str,
                       robust: str | None, model: RangeModel | float):
    """(ScaleChoice, extra covariance) of one camera with image ranges on its used rows (those that have one).

    ``model``: the session's :class:`RangeModel`, or a float (the relative systematic of the
    ranges, for the route without an outline parameter)."""
    if not isinstance(model, RangeModel):
        return _fixed_systematic(cd, used, prob, res, mode, robust, float(model))
    if not model.estimates_outline:
        return _fixed_systematic(cd, used, prob, res, mode, robust, model.diameter_rel_sigma)
    return _with_outline(cd, used, prob, res, mode, robust, model)
