"""Plan panel: where to put the sphere next, whether the target precision is met, and coverage.

All numbers and pictures come from calib_core.plan (the same as ``sonarcal plan``); this panel
holds the operator's target and choices, re-plans whenever detections or the calibration
change (captures added, accepted, corrected or rejected), shows the suggestions as ghost
spheres with their predicted 1-sigma in the 3D view and as rings on each camera's image.
"""

from __future__ import annotations

import html

import numpy as np

from app.common import notify
from calib_core.errors import SessionError
from calib_core.plan.coverage import coverage, suggestions_on_image
from calib_core.plan.report import compact_rows, plan_lines, status_line
from calib_core.plan.select import DEFAULT_CRITERION
from calib_core.plan.session_plan import field_from_session, plan_session
from calib_core.plan.target import Target

GHOST_RGB = (230, 90, 0)
CRITERIA = {"worst axis vs target": "worst", "D-optimal": "d"}
DEFAULT_LABEL = next(k for k, v in CRITERIA.items() if v == DEFAULT_CRITERION)


def markdown_table(cols: list[str], rows: list[list[str]]) -> str:
    esc = lambda v: html.escape(str(v)).replace("|", "\\|")  # noqa: E731
    return "\n".join(["| " + " | ".join(map(esc, cols)) + " |", "|" + "---|" * len(cols)]
                     + ["| " + " | ".join(map(esc, r)) + " |" for r in rows])


class PlanPanel:
    def __init__(self, wb, tab):
        self.wb = wb
        gui = wb.server.gui
        with tab:
            gui.add_markdown("Where the next sphere capture helps most, from the solver's own uncertainty model; "
                             "'enough' when every camera meets the target.")
            self.rot = gui.add_number("Target rotation 1-sigma (deg)", 0.1, min=0.001, max=20.0, step=0.01)
            self.trans = gui.add_number("Target translation 1-sigma (mm)", 5.0, min=0.1, max=1000.0, step=0.5)
            self.criterion = gui.add_dropdown("Criterion", tuple(CRITERIA), initial_value=DEFAULT_LABEL)
            self.count = gui.add_slider("Suggestions", min=1, max=5, step=1, initial_value=3)
            self.show = gui.add_checkbox("Show suggestions in the 3D view", True)
            self.status = gui.add_markdown("")
            self.table = gui.add_markdown("")
            self.details = gui.add_markdown("")
            self.cam_folder = gui.add_folder("Where to put it, per camera")
            self.cov_folder = gui.add_folder("Coverage")
        for h in (self.rot, self.trans, self.criterion, self.count, self.show):
            h.on_update(lambda _e: wb.refresher.mark("plan"))
        for kind in ("detections", "calibration", "plan"):
            wb.refresher.on(kind, self.refresh, heavy=True)  # loads every cloud, solves, draws images
        wb.refresher.on("selection", self.redraw_images, heavy=True)  # the shown image follows the selected capture
        wb.refresher.on("session", self.rebuild)
        self.images: dict = {}
        self.nodes: list = []
        self.field = None
        self.last = None  # the last SessionPlan (tests)

    def rebuild(self) -> None:
        for h in self.images.values():
            h.remove()
        self.images.clear()
        self.field = None
        self._clear_ghosts()

    def _clear_ghosts(self) -> None:
        for n in self.nodes:
            n.remove()
        self.nodes.clear()

    def _image(self, key: str, folder, img: np.ndarray, label: str) -> None:
        if key in self.images:
            self.images[key].image = img
        else:
            with folder:
                self.images[key] = self.wb.server.gui.add_image(img, label=label, format="png")

    def target(self) -> Target:
        return Target(max(float(self.rot.value), 1e-6), max(float(self.trans.value), 1e-6))

    def refresh(self) -> None:
        st = self.wb.state
        if st.session is None:
            return
        session, dets, cal = st.snapshot()
        try:
            if self.field is None:
                self.field = field_from_session(session, lambda cid: st.cloud(cid).points_m)
            sp = plan_session(session, dets, cal, self.target(), None, int(self.count.value),
                              CRITERIA[self.criterion.value], field=self.field)
        except SessionError as e:
            self.status.content = f"**Cannot plan yet**: {html.escape(e.problem)}"
            self.table.content = self.details.content = ""
            self._clear_ghosts()
            self.last = None
            return
        if sp.plan.met and not (self.last is not None and self.last.plan.met):
            notify(self.wb.server, None, "Enough captures", status_line(sp.plan), color="green", seconds=12.0)
        self.last = sp
        head, rest = status_line(sp.plan).split(": ", 1)
        self.status.content = f"**{html.escape(head.capitalize())}**: {html.escape(rest)}"
        cols, rows = compact_rows(sp.plan)
        self.table.content = markdown_table(cols, rows) if rows else ""
        self.details.content = "  \n".join(html.escape(x) for x in plan_lines(sp)[1:])
        self._ghosts(sp, session.sphere_radius_m)
        self.redraw_images()

    def _ghosts(self, sp, radius_m: float) -> None:
        self._clear_ghosts()
        if not self.show.value:
            return
        sc = self.wb.server.scene
        for k, s in enumerate(sp.plan.suggestions, 1):
            self.nodes.append(sc.add_icosphere(f"/plan/next{k}", radius=radius_m, color=GHOST_RGB, opacity=0.35,
                                               position=tuple(s.X_sonar_m)))
            self.nodes.append(sc.add_label(f"/plan/next{k}_label", f"next {k}",
                                           position=tuple(s.X_sonar_m + [0, 0, 1.5 * radius_m])))

    def redraw_images(self) -> None:
        """Rings on the selected capture's image per camera, and the coverage pictures, of the last plan."""
        sp, st = self.last, self.wb.state
        if sp is None or st.session is None:
            return
        models = {c: st.camera(c) for c in sp.cameras}
        sel = st.selected
        for c in sp.cameras:
            img = st.image(sel, c) if sel is not None else None
            if img is None:
                m = models[c]
                img = np.full((m.height_px, m.width_px, 3), 60, np.uint8)
            self._image(f"cam:{c}", self.cam_folder, suggestions_on_image(np.asarray(img), c, sp.plan), c)
        for key, (img, _num) in coverage(sp, models).items():
            self._image(f"cov:{key}", self.cov_folder, img, key)
