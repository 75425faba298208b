"""Review panel: the capture list (worst first), navigation, accept/reject/undo, sonar corrections.

Residuals are the distance in pixels between the image detection and the sonar centre
reprojected through the current calibration (calib_core.fusion.project_cloud), the same
numbers the overlays show.
"""

from __future__ import annotations

import numpy as np

from app.common import client_tag, guarded, notify
from calib_core.errors import SessionError
from calib_core.markup import escape_md
from calib_core.pipeline import refit_sonar

ALL = "all sensors"


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
            self.undo = gui.add_button("Undo")
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
        self.pick.on_click(g(self._start_pick))
        self.detect.on_click(g(lambda e: self.wb.start_detection(None, redetect_auto=True)))
        self.handle_on.on_update(lambda e: wb.refresher.mark("handle"))
        self.handle = None
        self.picking: set = set()  # client ids whose next 3D click picks the sonar centre
        self._dragging = False
        self._order: list[str] = []
        for kind in ("detections", "calibration", "selection"):
            wb.refresher.on(kind, self.refresh)
        wb.refresher.on("handle", self.refresh_handle)

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
                res = None
                if sensor != "sonar" and e.get("center") is not None and status != "rejected":
                    uv = self.wb.images.reprojected_centre(cap.id, sensor)
                    if uv is not None:
                        res = float(np.linalg.norm(np.asarray(e["center"], float) - uv))
                        row["residual"] = max(row["residual"] or 0.0, res)
                row["sensors"][sensor] = {"status": status, "score": e.get("score"), "residual_px": res,
                                          "found": e.get("center") is not None}
                if status == "rejected":
                    row["rejected"] = True
                elif e.get("center") is None:
                    row["missing"] = True
                if e.get("score") is not None:
                    row["score"] = min(row["score"], float(e["score"]))
            rows.append(row)
        rows.sort(key=lambda r: (r["rejected"], not r["missing"], -(r["residual"] if r["residual"] is not None else -1.0),
                                 r["score"]))
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
        head = "| | capture | sonar | " + " | ".join(escape_md(c) for c in cams) + " |\n|---|---|---|" + "---|" * len(cams) + "\n"
        lines = []
        for r in rows:
            cells = []
            for sensor in ["sonar", *cams]:
                c = r["sensors"].get(sensor)
                if c is None:
                    cells.append("-")
                    continue
                txt = c["status"]
                if not c["found"] and c["status"] not in ("rejected", "missing"):
                    txt += " (not found)"
                elif c["score"] is not None:
                    txt += f" {c['score']:.2f}"
                if c["residual_px"] is not None:
                    txt += f" · {c['residual_px']:.1f} px"
                cells.append(escape_md(txt))
            mark = "▶" if r["id"] == sel else ""
            lines.append(f"| {mark} | {escape_md(r['id'])} | " + " | ".join(cells) + " |")
        self.table.content = "**Captures (worst first)**\n\n" + head + "\n".join(lines)
        self.details.content = self._details(sel)
        self.refresh_handle()

    def _details(self, cid: str) -> str:
        st = self.wb.state
        out = [f"**{escape_md(cid)}**"]
        for sensor in st.sensors(cid):
            e = st.entry(cid, sensor) or {}
            c = e.get("center")
            where = "no centre" if c is None else "(" + ", ".join(f"{v:.4g}" for v in c) + ")"
            why = f" ({e['reason']})" if e.get("reason") else ""
            hist = e.get("history") or []
            last = f"; last change {hist[-1]['time']} by {hist[-1]['client']}" if hist else ""
            out.append("- " + escape_md(f"{sensor}: {e.get('status', 'missing')} {where}{why}{last}"))
        return "\n".join(out)
