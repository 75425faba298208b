"""Target-motion panel (Session tab): for a session made by ``sonarcal import``, whether the
sphere stayed still during each scan (the ``target_motion`` block), one row per capture and camera."""

from __future__ import annotations

from html import escape

from calib_core.ingest.motion import motion_summary_rows
from calib_core.report.motion import HEADER


def motion_markdown(session) -> str:
    """Markdown for the panel; cells escaped (viser renders raw HTML in markdown)."""
    tm = (getattr(session, "raw", None) or {}).get("target_motion") if session is not None else None
    if not isinstance(tm, dict) or not tm.get("captures"):
        return "**Target motion**: no track (the session was not made by `sonarcal import`)."
    rows = motion_summary_rows(tm)

    def cell(c) -> str:
        return escape(str(c)).replace("|", "&#124;")

    moved = [c for c, e in tm["captures"].items() if e.get("moved")]
    head = ("**Target motion during the scans**: " + (f"moved in {cell(', '.join(moved))}" if moved
                                                       else "still in every scan") + "\n\n")
    table = "| " + " | ".join(HEADER) + " |\n|" + "---|" * len(HEADER) + "\n"
    table += "".join("| " + " | ".join(cell(c) for c in r) + " |\n" for r in rows)
    return head + table


class MotionPanel:
    def __init__(self, wb):
        self.wb = wb
        with wb.tab_session:
            self.md = wb.server.gui.add_markdown(motion_markdown(None))
        wb.refresher.on("session", self.refresh)

    def refresh(self) -> None:
        self.md.content = motion_markdown(self.wb.state.session)
