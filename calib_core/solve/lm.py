"""Levenberg-Marquardt for the small, dense least-squares problems of the solve.

The pose refinement (:mod:`calib_core.solve.refine`) minimises ``||f(x)||^2`` over 6 to ~20
parameters with an analytic Jacobian, dozens of times per calibration. ``scipy.optimize``
does this well but costs 0.3-0.5 s to import, a third of the budget for a ``sonarcal
calibrate`` that reuses its detections; this module is that one algorithm in numpy.

It follows MINPACK's ``lmder`` in what it computes (Marquardt's scaling by the running maximum
of the Jacobian's column norms, the same three stopping tests) but chooses the damping by
Nielsen's gain-ratio rule rather than a trust-region radius. Each step solves the damped
normal equations as a stacked least-squares problem ``[J; sqrt(lam) D] h = [-f; 0]``, so a
rank-deficient Jacobian (an unobservable parameter) gives a finite step.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

#: starting damping, relative to the scaled curvature (Marquardt's choice)
LAMBDA0 = 1e-3


@dataclass(frozen=True)
class LMResult:
    """The minimiser ``x``, its residuals ``fun`` (at ``x``), the number of function
    evaluations, and which test stopped it: "gtol", "ftol", "xtol", "zero" (a residual of
    exactly zero) or "max_nfev"."""

    x: np.ndarray
    fun: np.ndarray
    nfev: int
    status: str


def levenberg_marquardt(fun: Callable[[np.ndarray], np.ndarray], jac: Callable[[np.ndarray], np.ndarray],
                        x0: np.ndarray, xtol: float = 1e-12, ftol: float = 1e-12, gtol: float = 1e-12,
                        max_nfev: int | None = None) -> LMResult:
    """Minimise ``||fun(x)||^2`` from ``x0``; ``jac(x)`` is the (m, n) Jacobian of ``fun``.

    Stops when the largest cosine between the residual and a Jacobian column is at most
    ``gtol``; when an accepted step lowered the cost, and was predicted to, by at most ``ftol``
    of it; when the scaled step is at most ``xtol`` of the scaled ``x`` (as MINPACK); or after
    ``max_nfev`` evaluations of ``fun`` (default ``100 * (n + 1)``)."""
    x = np.array(x0, dtype=float)
    n = x.size
    max_nfev = 100 * (n + 1) if max_nfev is None else int(max_nfev)
    r = np.asarray(fun(x), dtype=float)
    J = np.asarray(jac(x), dtype=float)
    nfev = 1
    cost = float(r @ r)
    D = np.maximum(np.linalg.norm(J, axis=0), np.finfo(float).tiny)
    lam, nu = LAMBDA0, 2.0
    while True:
        if cost == 0.0:
            return LMResult(x, r, nfev, "zero")
        if _max_cosine(J, r) <= gtol:
            return LMResult(x, r, nfev, "gtol")
        if nfev >= max_nfev:
            return LMResult(x, r, nfev, "max_nfev")
        h, pred = _damped_step(J, r, D, lam)
        if np.linalg.norm(D * h) <= xtol * (np.linalg.norm(D * x) + xtol):
            return LMResult(x, r, nfev, "xtol")
        x_new = x + h
        r_new = np.asarray(fun(x_new), dtype=float)
        nfev += 1
        cost_new = float(r_new @ r_new)
        rho = (cost - cost_new) / pred if pred > 0 else -1.0
        # (MINPACK's test, on rejected trial steps too: nothing left to gain at this precision)
        small = abs(cost - cost_new) <= ftol * cost and pred <= ftol * cost and rho <= 2
        if rho <= 0:
            if small:
                return LMResult(x, r, nfev, "ftol")
            lam, nu = lam * nu, 2 * nu
            continue
        x, r, cost = x_new, r_new, cost_new
        if small:
            return LMResult(x, r, nfev, "ftol")
        J = np.asarray(jac(x), dtype=float)
        D = np.maximum(D, np.linalg.norm(J, axis=0))
        lam, nu = lam * max(1 / 3, 1 - (2 * rho - 1) ** 3), 2.0


def _max_cosine(J: np.ndarray, r: np.ndarray) -> float:
    """Largest |cos| of the angle between ``r`` and a column of ``J`` (MINPACK's gradient test;
    zero columns count as orthogonal)."""
    norms = np.linalg.norm(J, axis=0) * np.linalg.norm(r)
    g = np.abs(J.T @ r)
    ok = norms > 0
    return float(np.max(g[ok] / norms[ok])) if ok.any() else 0.0


def _damped_step(J: np.ndarray, r: np.ndarray, D: np.ndarray, lam: float) -> tuple[np.ndarray, float]:
    """The step minimising ``||J h + r||^2 + lam ||D h||^2`` and the decrease of ``||J h + r||^2``
    it predicts from ``||r||^2``."""
    A = np.vstack([J, np.sqrt(lam) * np.diag(D)])
    b = np.concatenate([-r, np.zeros(D.size)])
    h = np.linalg.lstsq(A, b, rcond=None)[0]
    lin = r + J @ h
    return h, float(r @ r - lin @ lin)
