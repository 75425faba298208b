"""Human-readable rows (strings) from a calibration result dict, for terminal and HTML reports.

Pure formatting: no printing. Units in the output: degrees and millimetres.
"""

from __future__ import annotations

import math

import numpy as np

from calib_core.solve.model import log_so3


def _f(v, fmt: str, none: str = "-") -> str:
    return none if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, fmt)


def pose_rows(cal: dict) -> tuple[list[str], list[list[str]]]:
    """(columns, rows): per camera translation (mm), rotation vector (deg), |t|, 1/3-sigma."""
    cols = ["camera", "solution", "t (mm) x y z", "rotvec (deg) x y z", "|t| mm", "1-sigma rot deg", "1-sigma t mm",
            "3-sigma rot deg", "3-sigma t mm", "RMS px", "captures"]
    rows = []
    for cam, c in cal["cameras"].items():
        T = np.asarray(c["T_cam_sonar"], float)
        t = 1000 * T[:3, 3]
        rv = np.degrees(log_so3(T[:3, :3]))
        s1, s3 = c["sigma_1"], c["sigma_3"]
        rows.append([cam, c.get("solution", ""), " ".join(f"{v:.1f}" for v in t), " ".join(f"{v:.2f}" for v in rv),
                     f"{np.linalg.norm(t):.1f}", " ".join(f"{v:.3f}" for v in s1["rotation_deg"]),
                     " ".join(f"{v:.1f}" for v in s1["translation_mm"]), " ".join(f"{v:.3f}" for v in s3["rotation_deg"]),
                     " ".join(f"{v:.1f}" for v in s3["translation_mm"]), _f(c["rms_reprojection_px"], ".2f"),
                     str(len(c["captures_used"]))])
    return cols, rows


def residual_rows(cal: dict, cam: str) -> tuple[list[str], list[list[str]]]:
    """(columns, rows): per capture residual px, Mahalanobis, leave-one-out, flags."""
    cols = ["capture", "used", "residual px", "du dv px", "Mahalanobis", "LOO px", "LOO Mahal.", "LOO shift deg/mm", "flags"]
    rows = []
    for r in cal["cameras"][cam].get("residuals", []):
        lo = r.get("loo") or {}
        rows.append([r["capture"], "yes" if r["used"] else "NO", _f(r["residual_norm_px"], ".2f"),
                     " ".join(_f(v, "+.2f") for v in r["residual_px"]), _f(r["mahalanobis"], ".2f"),
                     _f(lo.get("residual_px"), ".2f"), _f(lo.get("mahalanobis"), ".2f"),
                     f"{_f(lo.get('shift_deg'), '.3f')} / {_f(lo.get('shift_mm'), '.1f')}" if lo else "-",
                     ", ".join(f["kind"] for f in r.get("flags", [])) or ""])
    for cid, why in (cal["cameras"][cam].get("skipped") or {}).items():
        rows.append([cid, "skipped", "-", "-", "-", "-", "-", "-", why])
    return cols, rows


def table_i_rows(cal: dict) -> tuple[list[str], list[list[str]]] | None:
    """The paper's Table I as (columns, rows), lengths in mm; None without two cameras."""
    tab = cal.get("table_i")
    if not tab:
        return None
    a, b = tab["cameras"]
    keys = [f"{a}-sonar", f"{b}-sonar", f"{a}-{b}"]
    p = tab["pairs"]
    mm = lambda v: _f(None if v is None else 1000 * v, ".2f")  # noqa: E731
    pct = lambda v: _f(v, "+.2f", "-") + ("%" if v is not None else "")  # noqa: E731
    deg = lambda v: _f(None if v is None else math.degrees(v), ".2f") + ("°" if v is not None else "")  # noqa: E731
    rows = [
        ["Estimated length |t| (mm)"] + [mm(p[k]["estimated_m"]) for k in keys],
        ["  1-sigma (mm)"] + [mm(p[k].get("estimated_sigma_m")) for k in keys],
        ["Measured length (mm)"] + [mm(p[k]["measured_m"]) for k in keys],
        ["Error"] + [pct(p[k]["error_pct"]) for k in keys],
        ["Assoc. length |t-hat| (mm)"] + [mm(p[k].get("assoc_m")) for k in keys],
        ["Error"] + [pct(p[k].get("assoc_error_pct")) for k in keys],
        ["Error length |t - t-hat| (mm)"] + [mm(p[k].get("error_length_m")) for k in keys],
        ["Incl. angle (t, t-hat)"] + [deg(p[k].get("included_angle_rad")) for k in keys],
    ]
    return [""] + keys, rows


def scale_line(cal: dict) -> str:
    """The one phrase for the range scale (CLI, report, workbench)."""
    s = cal.get("range_scale") or {}
    note = s.get("note") or "not estimated"
    if s.get("estimated") and isinstance(s.get("value"), (int, float)):
        # the value and what to do with it first; the evidence (often a paragraph) after it
        return (f"range scale {s['value']:.5f} ± {_f(s.get('sigma'), '.5f')} (1-sigma; sound speed in the cloud "
                f"{100 * (s['value'] - 1):+.2f} % off; from {s.get('source') or '-'}): divide cloud points "
                f"by it before applying T_cam_sonar. How it was estimated: {note}")
    value = s.get("value", 1.0)
    head = "range scale held at 1" if value in (None, 1, 1.0) else f"range scale {value:g}"
    if note.startswith("not observable") or note.startswith("too weakly"):
        return f"{head}: the scale is {note}"
    if head == "range scale held at 1":  # say "held at 1" once
        if note.startswith("held at 1"):
            return f"range scale {note}"
        if note.startswith("kept at 1: "):
            note = note[len("kept at 1: "):]
    return f"{head}: {note}"


def consistency_lines(cal: dict) -> list[str]:
    """The one consistency statistic (:mod:`calib_core.solve.consistency`): one line for the final
    solve, or one per camera when the cameras were solved apart."""
    from calib_core.solve.consistency import consistency_phrase

    if cal.get("consistency"):
        return [consistency_phrase(cal["consistency"])]
    return [consistency_phrase(c["consistency"]) for c in cal.get("cameras", {}).values() if c.get("consistency")]
