"""Fused view: a capture's cloud coloured by the camera images (paper Figs. 4 and 5).

calib_core.fusion.colour_cloud_multi does the work (z-buffer occlusion so back surfaces
do not take the front's colour); this panel picks the capture, shows the result and
hides that capture's plain cloud while the fused one is shown.
"""

from __future__ import annotations

import numpy as np

from app.common import guarded, notify
from calib_core import fusion
from calib_core.errors import SessionError
from calib_core.markup import escape_md

UNCOLOURED = (90, 90, 90)
FUSED_POINT_SIZE_M = 0.02


class FusedPanel:
    def __init__(self, wb):
        self.wb = wb
        gui = wb.server.gui
        with wb.tab_fused:
            gui.add_markdown("Colour a capture's sonar cloud from the camera images with the current calibration. "
                             "Works on any capture, also one without the target (e.g. a flange scene).")
            self.capture = gui.add_dropdown("Fuse capture", ("-",), initial_value="-")
            self.occlusion = gui.add_checkbox("Occlusion (z-buffer)", True,
                                              hint="Points hidden behind a nearer surface stay uncoloured")
            self.tolerance = gui.add_slider("Depth tolerance (m)", min=0.01, max=0.3, step=0.01, initial_value=0.05)
            self.run = gui.add_button("Colour cloud")
            self.show = gui.add_checkbox("Show fused cloud", False)
            self.info = gui.add_markdown("")
        self.run.on_click(guarded(wb.server, "Fusion failed")(self._run))
        self.show.on_update(guarded(wb.server)(lambda e: self._visibility()))
        self.node = None
        self.fused_id: str | None = None
        wb.refresher.on("selection", self.follow_selection)

    def rebuild(self) -> None:
        s = self.wb.state.session
        if self.node is not None:
            self.node.remove()
            self.node = None
        self.fused_id = None
        self.capture.options = tuple(c.id for c in s.captures)
        self.show.value = False
        self.info.content = ""
        self.wb.state.bus.publish("fused", cid=None)

    def colour(self, cid: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
        """(points (N,3) cloud frame, colours (N,3) uint8, coloured (N,) bool, cameras used)."""
        st = self.wb.state
        views, s_used = [], None
        for cam in st.session.cameras:
            cal = st.T_cam_sonar(cam)
            img = st.image(cid, cam)
            if cal is None or img is None:
                continue
            T, s = cal
            s_used = s
            views.append(fusion.CameraView(cam, img, st.camera(cam), T))
        if not views:
            raise SessionError(st.session.manifest_path,
                               f"capture {cid}: no calibrated camera with an image (run Solve first)")
        P = st.cloud(cid).points_m
        colours, coloured, _idx = fusion.colour_cloud_multi(P / s_used, views, occlusion=self.occlusion.value,
                                                            depth_tolerance_m=float(self.tolerance.value),
                                                            fallback=UNCOLOURED)
        return P, colours, coloured, [v.name for v in views]

    def _run(self, event) -> None:
        cid = self.capture.value
        P, colours, coloured, cams = self.colour(cid)
        sc = self.wb.server.scene
        if self.node is not None:
            self.node.remove()
        self.node = sc.add_point_cloud("/fused", P.astype(np.float32), colours, point_size=FUSED_POINT_SIZE_M,
                                       precision="float32", point_shape="circle")
        self.fused_id = cid
        text = (f"{int(coloured.sum())} of {len(P)} points coloured from {', '.join(cams)}"
                f" ({100 * coloured.mean():.0f} %); grey points are not seen by any camera.")
        self.info.content = f"**{escape_md(cid)}**: {escape_md(text)}"
        self.show.value = True
        self._visibility()
        notify(self.wb.server, event.client, "Fused cloud ready", f"{cid}: {text}", color="green", seconds=4)

    def _visibility(self) -> None:
        """One cloud on screen: the fused one replaces the plain clouds while it is shown."""
        if self.node is not None:
            self.node.visible = bool(self.show.value)
        self.wb.state.bus.publish("fused", cid=self.fused_id if (self.show.value and self.node is not None) else None)

    def follow_selection(self) -> None:
        st = self.wb.state
        if st.selected is not None and self.capture.value != st.selected and st.selected in self.capture.options:
            self.capture.value = st.selected
