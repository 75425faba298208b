"""Operator-readable detection problems, phrased once for the report, the CLI and the workbench.

Detectors put a ``reason`` into every entry they could not fill ("no round outline",
"sphere cut by the image border", "outline 40 % hidden or too faint at (u, v)", "two round
objects: (u, v) and (u, v)", ...). These helpers turn entries and residuals into the short
lines the shells show, and group reasons by kind (numbers and places dropped) for counts.
"""

from __future__ import annotations

import math
import re
from collections import Counter

# a detection whose reprojection misses it by more than this is shown as a problem (px)
RESIDUAL_PROBLEM_PX = 5.0
# a cloud whose points lie a median this far from the sensor (m) is not a calibration scan in
# metres: a lab or harbour scene in millimetres lies 500-20000 "m" away
MM_CLOUD_MEDIAN_M = 250.0

# An image entry from the look at the sonar-predicted place and size (calib_core.detect.image.predicted)
# has no probability: no ``score``, but the share of its outline seen (discounted by the outline's
# spread) under this key, shown with OUTLINE_SEEN_LABEL wherever a score is shown ...
OUTLINE_SEEN_KEY = "outline_seen"
OUTLINE_SEEN_LABEL = "outline seen"
# ... and, under this key (the value: the look's size prior, relative), a mark that its size (its
# range) follows the prediction's (the look searches circles of the predicted size; slope ~1 in
# bench_predicted_look.py --range-bias): such a range repeats the sonar's scale and is left out
# of the apparent-size scale
RANGE_PRIOR_KEY = "range_prior_rel_sigma"


def stereo_refusal_reason(off_px: float, source: str) -> str:
    """Why a plain detection was refused by another camera's registration carried by the stereo
    transform (calib_core.stereo.vouch)."""
    return f"round outline {off_px:.0f} px from where camera {source} and the stereo transform put the sphere"


def crossing_edges_reason(along_share: float, centre_uv_px) -> str:
    """Why a round outline was refused because the image edges at it cross it rather than run
    along it (calib_core.detect.image.tangent): a lattice's struts or a net's threads strung
    into a circle. ``along_share`` 0-1; ``centre_uv_px`` the outline's centre (px)."""
    u, v = centre_uv_px
    return f"edges cross the outline at ({u:.0f}, {v:.0f}): only {100 * along_share:.0f} % run along it"


def reason_kind(reason: str) -> str:
    """A reason without its numbers and places: "outline 40 % hidden ... at (3, 4)" ->
    "outline % hidden ..."; "two round objects: (..) and (..)" -> "two round objects"."""
    prefix, r = "", reason
    m = re.match(r"^(image|sonar): (.*)$", reason)
    if m:  # the solver's "image: <detector reason>"
        prefix, r = m.group(1) + ": ", m.group(2)
    r = r.split(" at (")[0].split(":")[0]
    r = re.sub(r"\(?-?\d+(\.\d+)?\)?", "", r)
    return prefix + (re.sub(r"\s+", " ", r).strip() or reason)


def entry_problem(sensor: str, entry) -> str | None:
    """"k1: sphere cut by the image border" for an entry without a centre, else None."""
    if not isinstance(entry, dict):
        return None
    if entry.get("status") == "rejected":
        return f"{sensor}: rejected by the operator"
    if entry.get("center") is None:
        return f"{sensor}: {entry.get('reason') or 'not found'}"
    return None


def entry_note(entry) -> str:
    """The reason column of a detection table: why an entry has no centre, or how a found one was
    singled out among look-alikes ("chosen by static scenery: ..."), else the detector's remark."""
    if not isinstance(entry, dict):
        return ""
    if entry.get("center") is None:
        return entry.get("reason") or ""
    if entry.get("resolved_by"):
        return f"chosen by {entry['resolved_by']}"
    return entry.get("reason") or ""


def entry_score(entry) -> float | None:
    """The entry's probability of being right (``score``), or None when it has none (a look at
    the predicted place, a click, a missing entry)."""
    v = entry.get("score") if isinstance(entry, dict) else None
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None


def score_text(entry) -> str:
    """The score column of a detection table: "0.93" (a probability); "outline seen 62 %" for a
    look at the predicted place, which has no probability; "" when neither is known."""
    p = entry_score(entry)
    if p is not None:
        return f"{p:.2f}"
    seen = entry.get(OUTLINE_SEEN_KEY) if isinstance(entry, dict) else None
    if isinstance(seen, (int, float)) and not isinstance(seen, bool):
        return f"{OUTLINE_SEEN_LABEL} {100 * float(seen):.0f} %"
    return ""


def score_phrase(entry) -> str:
    """"score 0.93", "outline seen 62 %" (a look at the predicted place) or "" (see score_text)."""
    text = score_text(entry)
    return f"score {text}" if entry_score(entry) is not None else text


def range_is_measured(entry) -> bool:
    """Whether an image entry's ``range_m`` is the apparent size's own measure (not one that
    follows another sensor's prediction, see RANGE_PRIOR_KEY)."""
    return isinstance(entry, dict) and not entry.get(RANGE_PRIOR_KEY)


def residual_problem(sensor: str, residual_px) -> str | None:
    """"k1: detection 389 px from the calibrated reprojection" when it is large, else None."""
    if residual_px is None:
        return None
    r = math.hypot(*residual_px)
    if r <= RESIDUAL_PROBLEM_PX:
        return None
    return f"{sensor}: detection {r:.0f} px from the calibrated reprojection (wrong object or moved target?)"


def count_reasons(reasons) -> str:
    """"no round outline: 2, sphere cut by the image border: 1" (most common first)."""
    c = Counter(reason_kind(r) for r in reasons if r)
    return ", ".join(f"{k}: {n}" for k, n in c.most_common())


def cloud_units_reason(points_sensor_m, sphere_diameter_m: float) -> str | None:
    """Why a cloud probably is not in metres, or None: its points lie a median of more than
    MM_CLOUD_MEDIAN_M from the sensor while the sphere is a few metres at most (a cloud
    written in millimetres, as some depth-camera and CAD tools do)."""
    import numpy as np

    P = np.asarray(points_sensor_m, float).reshape(-1, 3)
    if len(P) == 0 or not sphere_diameter_m < 5.0:
        return None
    d = float(np.median(np.linalg.norm(P[:: max(1, len(P) // 20000)], axis=1)))
    if not d > MM_CLOUD_MEDIAN_M:
        return None
    return (f"the cloud's points lie a median {d:.0f} m from the sensor: is it in millimetres? "
            f"Clouds must be in metres (divide by 1000)")
