"""Report section: did the target stay still during each scan (``target_motion`` of an import)."""

from __future__ import annotations

from html import escape

from calib_core.ingest.motion import motion_summary_rows
from calib_core.report.svg import bar_chart

HEADER = ["capture", "camera", "frames with sphere", "motion px", "motion across view", "target"]


def motion_section(session) -> str:
    """HTML for the session's ``target_motion`` block; empty when the session has none."""
    tm = (session.raw or {}).get("target_motion")
    if not isinstance(tm, dict) or not tm.get("captures"):
        return ""
    rows = motion_summary_rows(tm)
    caps = tm["captures"]
    labels = list(caps)
    worst = [max([m.get("motion_px") or 0.0 for m in (e.get("cameras") or {}).values()] or [0.0]) for e in caps.values()]
    moved = [bool(e.get("moved")) for e in caps.values()]
    chart = bar_chart("Sphere motion during each scan (largest over cameras)", labels, worst, "px", moved,
                      {"tolerance": float(tm.get("tolerance_px") or 0)})
    table = "<table><tr>" + "".join(f"<th>{escape(h)}</th>" for h in HEADER) + "</tr>"
    for r in rows:
        cls = " class='bad'" if r[-1] == "MOVED" else ""
        table += f"<tr{cls}>" + "".join(f"<td>{escape(str(c))}</td>" for c in r) + "</tr>"
    table += "</table>"
    flagged = [c for c, m in zip(labels, moved) if m]
    note = (f"<p class='bad'>Target moved during scan: {escape(', '.join(flagged))}. Its image and cloud may not "
            "show the sphere at the same place; check it or leave it out.</p>" if flagged else
            "<p class='ok'>The target stayed within tolerance in every scan.</p>")
    return ("<h2>Target motion during the scans</h2><p class='muted'>The sphere was tracked through the frames "
            "recorded during each scan; motion is measured from the kept (mid-scan) frame, in pixels and across "
            "the line of sight at the distance the known diameter implies.</p>" + note + chart + table)
