"""Flags that diagnose: which captures do not fit the others, and why.

Once enough captures have both a sonar and an image detection (:data:`MIN_CAPTURES`), a
robust pose (the solver's consensus and gate, :func:`calib_core.solve.pnp.ransac_pose`) tells which
captures disagree with the rest, before any Solve. Each disagreeing capture is then
explained (:mod:`calib_core.diagnose.causes`): the image detection is wrong, the sonar
detection is wrong, or the target moved. :mod:`calib_core.diagnose.wording` words each cause
once, for every shell.
"""

from calib_core.diagnose.causes import Flag, diagnose_session  # noqa: F401
from calib_core.diagnose.consistency import MIN_CAPTURES  # noqa: F401
