"""Critical values of the gate's F ratio when the noise has heavy tails (Student-t, 3 dof).

The gate (:mod:`calib_core.solve.gate`) compares a capture's deleted statistic with the noise
level of the others, ``F = (t_i / 2) / v_(i)``, against F(2, dof): exact for Gaussian noise.
Detectors' residuals have heavier tails; with Student-t components of 3 dof (unit variance) the
same ratio exceeds F's ``1 - ALPHA / n`` quantile for ~2 % of good captures, so the gate would
drop more good captures than the issue allows (1 %). From ``TAIL_FROM`` captures on, where a
moved target stands far above either value, the gate therefore also requires ``F`` to exceed the
``1 - TAIL_LEVEL`` quantile of the ratio under such tails: at most ``TAIL_LEVEL`` of good
captures dropped even then.

That ratio has no closed form; ``T3_Q99`` holds its 99 % quantile for dof 1..64, by Monte Carlo
(``python -m calib_core.solve.tail_reference`` prints the table again; the tests re-derive a few
entries). Beyond 64 dof the value at 64 is used (the quantile falls with the dof, so this errs
towards keeping captures).
"""

from __future__ import annotations

import math

import numpy as np

TAIL_NU = 3  # Student-t dof of the heavy-tail reference (the heaviest law of the gate's Monte Carlo)
TAIL_LEVEL = 0.01  # share of good captures the gate may drop under that reference
TAIL_FROM = 15  # captures from which the reference applies (at 12 it cost moved-target catching: 98.5 % with t5)
TAIL_MAX_DOF = 64
TAIL_DRAWS = 400_000

# 99 % quantile of (e_1^2 + e_2^2) / 2 / (sum of d further e_k^2 / d), e iid Student-t(3) of unit
# variance, for d = 1..64 (index d - 1); TAIL_DRAWS draws, seed d.
T3_Q99 = np.array([
    8758, 223.8, 81.19, 50.59, 39.73, 32.51, 28.8, 26.1,
    24.39, 22.82, 21.93, 21.14, 20.05, 19.48, 18.82, 18.33,
    18.07, 17.39, 17.32, 16.8, 16.54, 16.77, 15.93, 16.07,
    15.72, 15.49, 15.16, 15.12, 15.38, 15.22, 15.3, 14.69,
    14.75, 14.91, 14.75, 14.58, 14.55, 14.28, 14.08, 14.37,
    14.49, 13.95, 13.93, 13.85, 13.81, 13.51, 14.09, 13.73,
    13.48, 13.38, 13.58, 13.49, 13.53, 13.43, 13.42, 13.44,
    13.4, 13.13, 13.16, 13.46, 13.11, 13.05, 13.06, 13.02,
])


def t3_ratio_quantile(dof: int, level: float = TAIL_LEVEL, draws: int = TAIL_DRAWS, nu: int = TAIL_NU) -> float:
    """``1 - level`` quantile of the gate's F ratio with ``dof`` in the denominator when every
    component is Student-t with ``nu`` dof (unit variance), by Monte Carlo with seed ``dof``."""
    rng = np.random.default_rng(dof)
    out = []
    for start in range(0, draws, 50_000):
        m = min(50_000, draws - start)
        e = rng.standard_t(nu, (m, 2 + dof)) / math.sqrt(nu / (nu - 2))
        e2 = e * e
        out.append(0.5 * (e2[:, 0] + e2[:, 1]) / (e2[:, 2:].sum(axis=1) / dof))
    return float(np.quantile(np.concatenate(out), 1.0 - level))


def tail_critical(dof: np.ndarray) -> np.ndarray:
    """The heavy-tail reference's critical value, element-wise (inf where dof < 1)."""
    dof = np.asarray(dof, float)
    out = np.full(dof.shape, np.inf)
    ok = dof >= 1
    idx = np.clip(np.floor(dof[ok]).astype(int), 1, TAIL_MAX_DOF) - 1
    out[ok] = T3_Q99[idx]
    return out


def _print_table() -> None:
    vals = [t3_ratio_quantile(d) for d in range(1, TAIL_MAX_DOF + 1)]
    for k in range(0, len(vals), 8):
        print("    " + ", ".join(f"{v:.4g}" for v in vals[k:k + 8]) + ",")


if __name__ == "__main__":
    _print_table()
