"""The one consistency statistic of a solve, its one name and its one phrase.

``residual ratio`` = sqrt(chi2 / dof) of the final maximum-likelihood solve: the RMS of the
whitened residuals, i.e. how many times larger the residuals are than the detections' stated
(or assumed) uncertainties predict. 1 means "as stated". When it exceeds 1 the pose
covariance is multiplied by its square, so the reported uncertainty follows the data.
Every shell (CLI, report, workbench) shows this number through :func:`consistency_phrase`;
no other statistic of the same kind is printed anywhere.
"""

from __future__ import annotations

import math

NAME = "residual ratio"
WARN_RATIO = 2.0  # above this, the phrase becomes a warning with advice


def consistency(chi2: float, dof: int, scope: str) -> dict:
    """{name, scope, ratio, chi2, dof, p_value} (p: chance of a chi2 this large if the stated
    uncertainties were right); ratio None without redundancy (dof <= 0)."""
    from scipy.special import chdtrc  # scipy.stats takes seconds to import

    ok = dof > 0 and math.isfinite(chi2)
    return {"name": NAME, "scope": scope, "ratio": math.sqrt(chi2 / dof) if ok else None, "chi2": float(chi2),
            "dof": int(dof), "p_value": float(chdtrc(dof, chi2)) if ok else None}


def consistency_phrase(c: dict) -> str:
    """One line: the statistic, what it means, and advice when it is large."""
    if not c or c.get("ratio") is None:
        return f"{(c or {}).get('scope', 'solve')}: {NAME} not available (no redundant measurements)"
    r = c["ratio"]
    text = (f"{c['scope']}: {NAME} {r:.2f} (RMS residual / stated detection uncertainty; 1 = as stated; "
            f"chi2 {c['chi2']:.1f} on {c['dof']} dof)")
    if r > WARN_RATIO:
        text += ("; the pose covariance was inflated to match. Check the intrinsics, the detections and "
                 "whether the target moved")
    return text


def is_warning(c: dict) -> bool:
    return bool(c) and c.get("ratio") is not None and c["ratio"] > WARN_RATIO
