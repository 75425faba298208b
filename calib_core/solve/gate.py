"""Outlier gate: is a capture inconsistent with the others, judged by the noise the data shows?

The test (the geodesists' outlier test with an unknown variance factor, Pope's tau test in its
externally studentised F form): at the maximum-likelihood pose fitted on the current set,
every capture ``i`` gets its *deleted* residual statistic

    t_i = r_i^T (S_i - G_i C G_i^T)^-1 r_i     (i in the fit: its leave-one-out residual,
                                                exact for the linearised model)
    t_i = r_i^T (S_i + G_i C G_i^T)^-1 r_i     (i out of the fit: the prediction's residual)

where ``S_i`` is the stated covariance of its residual, ``G_i`` the prediction's Jacobian and
``C`` the pose covariance from the stated covariances. The noise level is not assumed: it is
estimated from the *other* captures, ``v_(i) = (chi2 - t_i) / (dof - 2)``, so

    F_i = (t_i / 2) / v_(i)  ~  F(2, dof_(i))

whatever the stated sigmas are (a common factor on every covariance cancels). A capture is
left out when ``F_i`` exceeds the ``1 - ALPHA / n`` quantile (Bonferroni over the n captures):
with Gaussian noise, the chance that any good capture of a camera is dropped is at most
``ALPHA`` (so at most ``ALPHA / n`` per good capture). From ``TAIL_FROM`` captures on, ``F`` must
also exceed the critical value of the same ratio under heavy tails (Student-t, 3 dof, at most 1 %
of good captures; :mod:`calib_core.solve.tail_reference`). Captures are removed one at a time
(worst first, refitting after each) and re-admitted when they pass again. :func:`gate_rule`
says the rule in one sentence for every shell.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib_core.solve.model import CameraData, per_camera_stats, prediction_jacobian
from calib_core.solve.tail_reference import TAIL_FROM, TAIL_LEVEL, TAIL_NU, tail_critical

ALPHA = 0.01  # family-wise false-alarm rate of the gate per camera (stated in the reports)
N_PARAMS = 6


@dataclass
class GateResult:
    """Per row: deleted statistic ``t`` (chi-square(2) units of the stated noise), ``F`` ratio,
    its critical value ``crit`` and dof; ``variance_factor`` of the fit set (chi2 / dof)."""

    t: np.ndarray
    F: np.ndarray
    crit: np.ndarray
    dof: np.ndarray
    variance_factor: float

    @property
    def ratio(self) -> np.ndarray:
        """F / its critical value: > 1 means inconsistent with the others."""
        return self.F / self.crit


def gate_rule(n: int) -> str:
    """The drop rule for a camera with ``n`` captures, in one sentence (CLI, workbench, report)."""
    rule = f"false-alarm rate {100 * ALPHA:g} % per camera with Gaussian noise"
    if n >= TAIL_FROM:
        rule += (f", and at most {100 * TAIL_LEVEL:g} % of good captures with heavy tails "
                 f"(Student-t, {TAIL_NU} dof; {TAIL_FROM} or more captures)")
    return rule


def drop_critical(dof: np.ndarray, n: int, alpha: float = ALPHA) -> np.ndarray:
    """The drop test's critical value: F's (see :func:`f_critical`), and from TAIL_FROM captures
    on at least the heavy-tail reference's (:mod:`calib_core.solve.tail_reference`)."""
    crit = f_critical(dof, n, alpha)
    return np.maximum(crit, tail_critical(dof)) if n >= TAIL_FROM else crit


def f_critical(dof: np.ndarray, n: int, alpha: float = ALPHA) -> np.ndarray:
    """(1 - alpha/n) quantile of F(2, dof), element-wise (inf where dof < 1)."""
    from scipy.special import fdtri  # scipy.stats takes seconds to import

    dof = np.asarray(dof, float)
    out = np.full(dof.shape, np.inf)
    ok = dof >= 1
    out[ok] = fdtri(2.0, dof[ok], 1.0 - alpha / max(n, 1))
    return out


def gate_test(cd: CameraData, T_cam_sonar: np.ndarray, cov6: np.ndarray, inl: np.ndarray,
              alpha: float = ALPHA) -> GateResult:
    """Deleted-residual F statistics of every row at a pose fitted on ``inl`` (``cov6`` from the
    stated covariances, not inflated). Rows behind the camera get F = inf."""
    _, r, S, m2, depth = per_camera_stats(cd, T_cam_sonar)
    G = prediction_jacobian(cd, T_cam_sonar, np.arange(len(cd)))
    P = G @ cov6 @ np.swapaxes(G, 1, 2)
    S_in = S - P
    # guard: a row that alone fixes a direction has leverage 1 (no deleted residual to speak of)
    bad = np.linalg.eigvalsh(0.5 * (S_in + np.swapaxes(S_in, 1, 2)))[:, 0] <= 1e-6 * np.trace(S, axis1=1, axis2=2)
    S_in[bad] = S[bad]
    Sd = np.where(inl[:, None, None], S_in, S + P)
    t = np.einsum("ni,ni->n", r, np.linalg.solve(Sd, r[..., None])[..., 0])
    chi2 = float(np.sum(m2[inl]))
    dof_fit = 2 * int(inl.sum()) - N_PARAMS
    dof = np.where(inl, dof_fit - 2, dof_fit).astype(float)
    rest = np.where(inl, chi2 - t, chi2)
    v = np.where(dof >= 1, rest / np.maximum(dof, 1), np.nan)
    F = (t / 2) / np.maximum(v, 1e-300)
    F[depth <= 0] = np.inf
    return GateResult(t, F, drop_critical(dof, len(cd), alpha), dof, chi2 / dof_fit if dof_fit > 0 else float("nan"))


def next_set(res: GateResult, inl: np.ndarray, min_keep: int, readmit: bool = True) -> np.ndarray | None:
    """One gate step: drop the worst failing row in the set, else (when ``readmit``) re-admit the
    best passing row outside it, else None (the set is final)."""
    ratio = np.where(np.isfinite(res.ratio), res.ratio, np.inf)
    ratio = np.nan_to_num(ratio, nan=np.inf)
    fail_in = np.flatnonzero(inl & (ratio > 1.0))
    if len(fail_in) and inl.sum() > min_keep:
        new = inl.copy()
        new[fail_in[np.argmax(ratio[fail_in])]] = False
        return new
    pass_out = np.flatnonzero(~inl & (ratio <= 1.0))
    if len(pass_out) and readmit:
        new = inl.copy()
        new[pass_out[np.argmin(ratio[pass_out])]] = True
        return new
    return None
