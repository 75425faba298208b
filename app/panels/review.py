"""Review panel: the capture list (flagged and worst first), navigation, accept/reject,
undo/redo, sonar corrections.

Residuals are :meth:`app.state.WorkbenchState.residual_px`: the distance in pixels between the
image detection and the sonar centre projected through the current calibration, computed as
the solver computes its per-capture residual, so every panel shows the same number. Each cell
is coloured good / doubtful / bad by :func:`calib_core.diagnose.wording.verdict` (thresholds
stated under the table).
"""

from __future__ import annotations

import numpy as np

from app.common import client_tag, guarded, notify
from calib_core.diagnose import wording
from calib_core.detect.reasons import entry_note, entry_score, score_text
from calib_core.errors import SessionError
from calib_core.markup import escape_md
from calib_core.pipeline import refit_sonar

ALL = "all sensors"


NBSP = "\u00a0"
COLOURS = {"good": "#1a9a3a", "doubtful": "#c98a00", "bad": "#d62728", "none": "#9a9a9a"}


def dot(verdict: str) -> str:
    """A coloured disc (a plain glyph: it shows without an emoji font)."""
    return f'<span style="color:{COLOURS[verdict]}">●</span>'


DOTS = {k: dot(k) for k in ("good", "doubtful", "bad")}


def cell(c: dict | None) -> str:
    """One review-table cell: verdict dot, status, score, residual (never wrapped mid-value)."""
    if c is None:
        return "-"
    flagged = c.get("flag") is not None and c["status"] != "rejected"
    if c["status"] in ("rejected", "missing") or not c["found"]:
        mark = dot("none") if c["status"] in ("rejected", "missing") else DOTS["bad"]
    else:
        mark = DOTS[wording.verdict(c["score"], c["residual_px"], flagged)]
    parts = [c["status"]]
    if not c["found"] and c["status"] not in ("rejected", "missing"):
        parts.append(f"(not found: {escape_md(c.get('reason') or 'no sphere')})")
    elif c.get("score_text") or c.get("score") is not None:
        parts.append(c.get("score_text") or f"{c['score']:.2f}")
    if c["residual_px"] is not None:
        parts.append(f"· {c['residual_px']:.2f} px")
    if flagged:
        parts.append(f"⚠ {c['flag'].cause}")
    tail = f" ({escape_md(c['reason'])})" if c.get("reason") and c["found"] else ""  # the detector's words
    return mark + NBSP + NBSP.join(str(p).replace(" ", NBSP) for p in parts) + tail


class ReviewPanel:
    def __init__(self, wb):
        self.wb = wb
        gui = wb.server.gui
        g = guarded(wb.server)
        with wb.tab_review:
            self.capture = gui.add_dropdown("Capture", ("-",), initial_value="-")
            self.prev = gui.add_button("Previous")
            self.next = gui.add_button("Next")
            self.sensor = gui.add_dropdown("Apply to", (ALL,), initial_value=ALL)
            self.accept = gui.add_button("Accept", color="green")
            self.reject = gui.add_button("Reject", color="red")
            self.undo = gui.add_button("Undo", hint="Undo the session's latest change (kept in detections.yaml)")
            self.redo = gui.add_button("Redo", hint="Redo the latest undone change")
            self.details = gui.add_markdown("")
            with gui.add_folder("Correct the sonar centre", expand_by_default=False):
                self.pick = gui.add_button("Pick sonar centre in 3D",
                                           hint="Then click on the sphere's points in the 3D view; refits near it")
                self.handle_on = gui.add_checkbox("Drag handle at sonar centre", False,
                                                  hint="Drag the handle to the sphere; refits near it on release")
            self.detect = gui.add_button("Detect again (automatic entries)")
            self.table = gui.add_markdown("")
        self.capture.on_update(g(self._on_capture))
        self.prev.on_click(g(lambda e: self.wb.state.step(-1, self.order())))
        self.next.on_click(g(lambda e: self.wb.state.step(+1, self.order())))
        self.accept.on_click(g(lambda e: self._set(e, "accepted")))
        self.reject.on_click(g(lambda e: self._set(e, "rejected")))
        self.undo.on_click(g(self._undo))
        self.redo.on_click(g(self._redo))
        self.pick.on_click(g(self._start_pick))
        self.detect.on_click(g(lambda e: self.wb.start_detection(None, redetect_auto=True)))
        self.handle_on.on_update(lambda e: wb.refresher.mark("handle"))
        self.handle = None
        self.picking = wb.state.modes.picking  # client ids whose next 3D click picks the sonar centre
        self._dragging = False
        self._order: list[str] = []
        for kind in ("detections", "calibration", "selection"):
            wb.refresher.on(kind, self.refresh)
        wb.refresher.on("handle", self.refresh_handle)
        wb.refresher.on("flags", self.refresh)
        wb.state.bus.subscribe("focus", self.on_focus)

    # ---- data ------------------------------------------------------------
    def rows(self) -> list[dict]:
        """One row per capture: per sensor status/score/residual; worst first."""
        st = self.wb.state
        s = st.session
        rows = []
        for cap in s.captures:
            row = {"id": cap.id, "sensors": {}, "missing": False, "residual": None, "score": 1.0, "rejected": False}
            for sensor in st.sensors(cap.id):
                e = st.entry(cap.id, sensor) or {}
                status = e.get("status", "missing") if e else "missing"
                res = st.residual_px(cap.id, sensor) if sensor != "sonar" else None
                if res is not None:
                    row["residual"] = max(row["residual"] or 0.0, res)
                flag = st.flag_for(cap.id, sensor)
                row["sensors"][sensor] = {"status": status, "score": entry_score(e), "score_text": score_text(e),
                                          "residual_px": res,
                                          "found": e.get("center") is not None, "reason": entry_note(e) or None,
                                          "flag": flag}
                if status == "rejected":
                    row["rejected"] = True
                elif e.get("center") is None:
                    row["missing"] = True
                if entry_score(e) is not None:
                    row["score"] = min(row["score"], entry_score(e))
                row["flagged"] = row.get("flagged", False) or (flag is not None and status != "rejected")
            rows.append(row)
        rows.sort(key=lambda r: (r["rejected"], not r.get("flagged"), not r["missing"],
                                 -(r["residual"] if r["residual"] is not None else -1.0), r["score"]))
        return rows

    def order(self) -> list[str]:
        return self._order or [c.id for c in self.wb.state.session.captures]

    # ---- actions -----------------------------------------------------------
    def _sensors(self):
        v = self.sensor.value
        return None if v == ALL else [v]

    def _set(self, event, status: str) -> None:
        st = self.wb.state
        cid = st.selected
        sensors = self._sensors()
        if sensors and sensors[0] not in st.sensors(cid):
            raise SessionError(st.require().manifest_path, f"capture {cid} has no {sensors[0]}")
        st.set_status(cid, status, client_tag(event), sensors)
        notify(self.wb.server, event.client, f"{cid} {status}", f"{', '.join(sensors or ['all sensors'])}; saved",
               color="green", seconds=3)

    def _undo(self, event) -> None:
        ch = self.wb.state.undo(client_tag(event))
        where = ", ".join(f"{c}/{s}" for c, s, _p, _n in ch.items)
        notify(self.wb.server, event.client, "Undone", f"{ch.action} on {where}", color="blue", seconds=3)

    def _redo(self, event) -> None:
        ch = self.wb.state.redo(client_tag(event))
        where = ", ".join(f"{c}/{s}" for c, s, _p, _n in ch.items)
        notify(self.wb.server, event.client, "Redone", f"{ch.action} on {where}", color="blue", seconds=3)

    def on_focus(self, client=None, cid=None, sensor=None, flag=None) -> None:
        """A flag was followed: make Accept/Reject act on the implicated sensor (a moved target: all)."""
        if flag is None:
            return
        self.sensor.value = ALL if sensor in (None, "capture") else sensor
        if sensor == "sonar" and not self.handle_on.value:
            self.handle_on.value = True  # drag the handle to the sphere the image points at

    def _on_capture(self, event) -> None:
        if self.capture.value in {c.id for c in self.wb.state.session.captures}:
            self.wb.state.select(self.capture.value)

    def _start_pick(self, event) -> None:
        client = event.client
        if client is None:
            return
        notify(self.wb.server, client, "Pick the sonar centre", "Click on the sphere's points in the 3D view",
               color="blue", seconds=5)

        @guarded(self.wb.server, "Pick failed")
        def on_pick(ev) -> None:
            client.scene.remove_click_callback(on_pick)
            self.picking.discard(client.client_id)
            entry = self.pick_sonar(ev.ray_origin, ev.ray_direction, client_tag(ev))
            c = entry["center"]
            notify(self.wb.server, client, f"{self.wb.state.selected} sonar corrected",
                   f"{'refit' if entry.get('refit') else 'picked point'} at ({c[0]:.3f}, {c[1]:.3f}, {c[2]:.3f}) m",
                   color="green", seconds=4)

        if client.client_id not in self.picking:
            self.picking.add(client.client_id)  # this client's next click in 3D picks (image boards ignore it)
            client.scene.on_click()(on_pick)

    def pick_sonar(self, ray_origin, ray_direction, client: str) -> dict:
        """Pick the cloud point nearest the click ray (first along it) and refit the sonar centre."""
        st = self.wb.state
        cid = st.selected
        P = st.cloud(cid).points_m
        o = np.asarray(ray_origin, float)
        d = np.asarray(ray_direction, float)
        d = d / np.linalg.norm(d)
        t = (P - o) @ d
        dist = np.linalg.norm(P - o - t[:, None] * d, axis=1)
        tol = 0.5 * st.session.sphere_radius_m
        near = np.flatnonzero((t > 0) & (dist < tol))
        if near.size:
            i = near[np.argmin(t[near])]
        else:
            i = int(np.argmin(np.where(t > 0, dist, np.inf)))
            if not np.isfinite(dist[i]) or dist[i] > 3 * st.session.sphere_radius_m:
                raise SessionError(st.session.capture(cid).cloud_path, "no cloud point near the click; click on the sphere")
        entry = refit_sonar(st.data, cid, P[i])
        st.correct(cid, "sonar", entry, client, action="pick")
        return st.entry(cid, "sonar")

    # ---- handle ------------------------------------------------------------------
    def refresh_handle(self) -> None:
        st = self.wb.state
        e = (st.entry(st.selected, "sonar") or {}) if st.session is not None else {}
        if not self.handle_on.value or e.get("center") is None:
            if self.handle is not None:
                self.handle.remove()
                self.handle = None
            return
        if self._dragging:
            return
        pos = np.asarray(e["center"], float)
        if self.handle is None:
            self.handle = self.wb.server.scene.add_transform_controls(
                "/sonar_handle", scale=0.3, disable_rotations=True, position=pos, depth_test=False)
            self.handle.on_update(self._on_drag)
        else:
            self.handle.position = pos

    def _on_drag(self, event) -> None:
        if event.phase == "start":
            self._dragging = True
            return
        if event.phase != "end":
            return
        self._dragging = False
        st = self.wb.state
        cid = st.selected
        try:
            entry = refit_sonar(st.data, cid, np.asarray(event.target.position, float))
            st.correct(cid, "sonar", entry, client_tag(event), action="drag")
        except Exception as e:  # reported in the page
            from app.common import error_text

            notify(self.wb.server, event.client, "Drag correction failed", error_text(e))

    # ---- display -----------------------------------------------------------------
    def rebuild(self) -> None:
        s = self.wb.state.session
        ids = tuple(c.id for c in s.captures)
        self.capture.options = ids
        self.sensor.options = (ALL, "sonar", *s.cameras)
        self.sensor.value = ALL

    def refresh(self) -> None:
        st = self.wb.state
        if st.session is None:
            return
        rows = self.rows()
        self._order = [r["id"] for r in rows]
        sel = st.selected
        if self.capture.value != sel:
            self.capture.value = sel
        cams = list(st.session.cameras)
        lines = [f"| {'▶' if r['id'] == sel else ''} | {escape_md(r['id'])} | "
                 + " | ".join(cell(r["sensors"].get(x)) for x in ["sonar", *cams]) + " |" for r in rows]
        head = "| | capture | sonar | " + " | ".join(escape_md(c) for c in cams) + " |\n|---|---|---|" + "---|" * len(cams) + "\n"
        self.table.content = ("**Captures (worst first)**\n\n" + head + "\n".join(lines)
                              + f"\n\n{DOTS['good']} good · {DOTS['doubtful']} doubtful · {DOTS['bad']} bad · "
                              + f"{dot('none')} rejected/none. {wording.THRESHOLDS_NOTE}. "
                              + f"Score: the detector's (0-1). {wording.RESIDUAL_LABEL}.")
        self.details.content = self._details(sel)
        self.refresh_handle()

    def _details(self, cid: str) -> str:
        st = self.wb.state
        out = [f"**{escape_md(cid)}**"]
        for sensor in st.sensors(cid):
            e = st.entry(cid, sensor) or {}
            c = e.get("center")
            where = "no centre" if c is None else "(" + ", ".join(f"{v:.4g}" for v in c) + ")"
            why = f" ({escape_md(e['reason'])})" if e.get("reason") else ""
            hist = e.get("history") or []
            last = f"; last change {escape_md(hist[-1].get('time'))} by {escape_md(hist[-1].get('client'))}" if hist else ""
            out.append(f"- {escape_md(sensor)}: {e.get('status', 'missing')} {where}{why}{last}")
        f = st.flag_for(cid)
        if f is not None:
            out.append(f"\n⚠ {escape_md(f.text)}")
        return "\n".join(out)
