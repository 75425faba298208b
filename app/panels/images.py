"""Image panels: per camera, the selected capture's image with its overlays.

Each overlay (calib_core.fusion): the detected ellipse and centre, the reprojected sonar
sphere centre and the reprojected sonar cloud as a segmentation mask (adjustable radius
and opacity). It is shown twice: in the GUI panel, and in the 3D scene on a board inside
the camera's frustum that reports clicks; a click on the board corrects the image
detection (refit near the click, or the click itself).

The board lies in the camera's image plane at a chosen depth, ignoring lens distortion
(a display approximation: pixels are read from the board, so clicks are exact).
"""

from __future__ import annotations

from collections import OrderedDict

import cv2
import numpy as np

from app.common import client_tag, guarded, notify, pose_wxyz_position
from app.panels.scene3d import camera_pose
from calib_core import fusion
from calib_core.pipeline import CLICK_SIGMA_IMAGE_PX, refit_image

MASK_RGB = (0, 255, 0)
BOARD_MAX_WIDTH = 1280
PANEL_MAX_WIDTH = 640


def click_message(cid: str, cam: str, entry: dict, refit_asked: bool) -> tuple[str, str, str]:
    """(title, body, colour) of the notice after an image click: a failed refit is said plainly."""
    c = entry["center"]
    at = f"({c[0]:.1f}, {c[1]:.1f}) px"
    if entry.get("refit"):
        return f"{cid} {cam} corrected", f"refit near the click: centre at {at}; saved", "green"
    if refit_asked:
        why = entry.get("refit_reason") or "no sphere outline near the click"
        return (f"{cid} {cam}: refit failed", f"{why}. The clicked pixel {at} is stored as the centre "
                f"(uncertainty {CLICK_SIGMA_IMAGE_PX:.0f} px); click again or Undo", "yellow")
    return f"{cid} {cam} corrected", f"clicked centre at {at}; saved", "green"


def downscale(img: np.ndarray, max_width: int) -> np.ndarray:
    if img.shape[1] <= max_width:
        return img
    f = max_width / img.shape[1]
    return cv2.resize(img, (max_width, max(1, int(round(img.shape[0] * f)))), interpolation=cv2.INTER_AREA)


class ImagePanels:
    def __init__(self, wb):
        self.wb = wb
        gui = wb.server.gui
        with wb.tab_review:
            self.folder = gui.add_folder("Images", order=1000)
        with self.folder:
            self.show_mask = gui.add_checkbox("Reprojected cloud mask", True)
            self.mask_radius = gui.add_slider("Mask radius (px)", min=0, max=40, step=1, initial_value=3)
            self.mask_opacity = gui.add_slider("Mask opacity", min=0.0, max=1.0, step=0.05, initial_value=0.45)
            self.refit = gui.add_checkbox("Refit near a click", True,
                                          hint="Off: the clicked pixel itself becomes the corrected centre")
            self.board_depth = gui.add_slider("Image board distance (m)", min=0.1, max=3.0, step=0.05, initial_value=0.3)
        for h in (self.show_mask, self.mask_radius, self.mask_opacity, self.board_depth):
            h.on_update(lambda _e: wb.refresher.mark("overlay"))
        self.panels: dict = {}  # cam -> (gui image, view button)
        self.boards: dict = {}
        self._masks: OrderedDict = OrderedDict()
        self._bases: OrderedDict = OrderedDict()
        self._shown: dict = {}
        self.viewing = wb.state.modes.viewing  # client id -> (camera, eye) after "View through"
        self.focus_cam: str | None = None  # while someone looks through a camera, other boards hide
        for kind in ("selection", "detections", "calibration", "overlay", "flags"):
            wb.refresher.on(kind, self.refresh, heavy=True)  # decodes and sends images: after the review table
        wb.refresher.on("calibration", self.follow_views)
        wb.state.bus.subscribe("focus", self.on_focus)

    # ---- building ----------------------------------------------------------
    def rebuild(self) -> None:
        for img, btn in self.panels.values():
            img.remove()
            btn.remove()
        self.panels.clear()
        self._masks.clear()
        self._bases.clear()
        self._shown.clear()
        for board in self.boards.values():
            board.remove()
        self.boards.clear()
        gui = self.wb.server.gui
        blank = np.full((90, 160, 3), 40, np.uint8)
        with self.folder:
            for cam in self.wb.state.session.cameras:
                img = gui.add_image(blank, label=cam, format="jpeg", jpeg_quality=85)
                btn = gui.add_button(f"View through {cam}",
                                     hint="Look through the camera at its image board; click the sphere centre to correct it")
                btn.on_click(guarded(self.wb.server)(lambda e, cam=cam: self.view_through(e.client, cam)))
                self.panels[cam] = (img, btn)

    # ---- rendering -----------------------------------------------------------
    def mask(self, cid: str, cam: str, radius_px: float):
        """Reprojected-cloud segmentation mask (H,W) bool, cached per calibration and radius."""
        st = self.wb.state
        cal = st.T_cam_sonar(cam)
        if cal is None:
            return None
        key = (cid, cam, st.cal_version, float(radius_px))
        if key in self._masks:
            return self._masks[key]
        T, s = cal
        model = st.camera(cam)
        uv, _depth, valid = fusion.project_cloud(st.cloud(cid).points_m / s, T, model)
        m = fusion.segmentation_mask(model, uv, radius_px, valid)
        self._masks[key] = m
        while len(self._masks) > 8:
            self._masks.popitem(last=False)
        return m

    def reprojected_centre(self, cid: str, cam: str):
        """Where the sonar says the sphere is in ``cam``'s image: through the current calibration,
        else through the consensus pose of a flag on this capture (None when neither)."""
        uv = self.wb.state.reprojected_uv(cid, cam)
        if uv is None:
            f = self.wb.state.flag_for(cid, cam)
            if f is not None and f.camera == cam and f.predicted_uv_px is not None:
                return np.asarray(f.predicted_uv_px, float)
        return uv

    def render(self, cid: str, cam: str) -> np.ndarray | None:
        """The full-resolution overlay image of one camera for one capture (None: no image)."""
        st = self.wb.state
        img = st.image(cid, cam)
        if img is None:
            return None
        base = img
        if self.show_mask.value and float(self.mask_opacity.value) > 0:
            m = self.mask(cid, cam, float(self.mask_radius.value))
            if m is not None:
                base = fusion.overlay(img, m, MASK_RGB, float(self.mask_opacity.value))
        e = st.entry(cid, cam) or {}
        centre = e.get("center") if e.get("status") != "rejected" else None
        return fusion.draw_detection(base, centre, e.get("ellipse_px"), self.reprojected_centre(cid, cam))

    def _base(self, cid: str, cam: str):
        """(display-size image with the mask overlay, scale factor display/raw), cached; None: no image.

        The mask is tinted at display size (its raw-size mask shrunk with area averaging), which
        is what the screen shows anyway and keeps corrections fast on 1080p frames.
        """
        st = self.wb.state
        show, r, a = bool(self.show_mask.value), float(self.mask_radius.value), float(self.mask_opacity.value)
        key = (cid, cam, st.cal_version, show, r, a)
        if key in self._bases:
            return self._bases[key]
        img = st.image(cid, cam)
        if img is None:
            return None
        small = downscale(img, BOARD_MAX_WIDTH)
        if show and a > 0:
            m = self.mask(cid, cam, r)
            if m is not None:
                if small.shape[:2] != m.shape:
                    m = cv2.resize(m.astype(np.uint8) * 255, (small.shape[1], small.shape[0]),
                                   interpolation=cv2.INTER_AREA) > 64
                small = fusion.overlay(small, m, MASK_RGB, a)
        self._bases[key] = (small, small.shape[1] / img.shape[1])
        while len(self._bases) > 6:
            self._bases.popitem(last=False)
        return self._bases[key]

    def display_image(self, cid: str, cam: str) -> np.ndarray | None:
        """What the board and the panel show: the cached base plus the markers (display size)."""
        base = self._base(cid, cam)
        if base is None:
            return None
        small, f = base
        e = self.wb.state.entry(cid, cam) or {}

        def px(uv):  # raw pixel -> display pixel (pixel centres at integers in both)
            return None if uv is None else (np.asarray(uv, float) + 0.5) * f - 0.5

        ell = e.get("ellipse_px")
        if ell is not None and len(ell) == 5:
            ell = [*px(ell[:2]), ell[2] * f, ell[3] * f, ell[4]]
        centre = e.get("center") if e.get("status") != "rejected" else None
        return fusion.draw_detection(small, px(centre), ell, px(self.reprojected_centre(cid, cam)))

    def board_geometry(self, cam: str) -> tuple[np.ndarray, float, float]:
        """(T_cam_board 4x4, render width m, render height m) of a camera's image board."""
        model = self.wb.state.camera(cam)
        d = float(self.board_depth.value)
        W, H = model.width_px, model.height_px
        T = np.eye(4)
        T[:3, 3] = [d * ((W - 1) / 2 - model.cx) / model.fx, d * ((H - 1) / 2 - model.cy) / model.fy, d]
        return T, d * W / model.fx, d * H / model.fy

    def refresh(self) -> None:
        st = self.wb.state
        if st.session is None or not self.panels:
            return
        cid = st.selected
        sc = self.wb.server.scene
        for cam, (panel, _btn) in self.panels.items():
            e = {k: v for k, v in (st.entry(cid, cam) or {}).items() if k != "history"}
            son = (st.entry(cid, "sonar") or {}).get("center")
            pred = self.reprojected_centre(cid, cam)
            key = (cid, st.cal_version, bool(self.show_mask.value), float(self.mask_radius.value),
                   float(self.mask_opacity.value), float(self.board_depth.value), repr(e), repr(son),
                   None if pred is None else tuple(np.round(pred, 2)), self.focus_cam)
            if self._shown.get(cam) == key:
                continue  # nothing this camera shows has changed
            self._shown[cam] = key
            out = self.display_image(cid, cam)
            board = self.boards.get(cam)
            if out is None:
                panel.visible = False
                if board is not None:
                    board.visible = False
                continue
            panel.label = f"{cam}: {cid}"
            panel.image = downscale(out, PANEL_MAX_WIDTH)
            panel.visible = True
            T, rw, rh = self.board_geometry(cam)
            wxyz, pos = pose_wxyz_position(T)
            small = out
            if board is None:
                board = sc.add_image(f"/cams/{cam}/board", small, rw, rh, format="jpeg", jpeg_quality=90,
                                     wxyz=wxyz, position=pos, cast_shadow=False, receive_shadow=False)
                board.on_click(guarded(self.wb.server, "Correction failed")(lambda e, cam=cam: self.on_board_click(e, cam)))
                self.boards[cam] = board
            else:
                board.image = small
                board.render_width, board.render_height = rw, rh
                board.position = pos
            board.visible = self.focus_cam in (None, cam)

    # ---- interaction ----------------------------------------------------------
    def pixel_from_ray(self, cam: str, ray_origin, ray_direction):
        """Raw pixel (u, v) where a world ray meets camera ``cam``'s image board, or None."""
        model = self.wb.state.camera(cam)
        T_cam_board, rw, rh = self.board_geometry(cam)
        T_world_board = camera_pose(self.wb.state, cam) @ T_cam_board
        R, t = T_world_board[:3, :3], T_world_board[:3, 3]
        o = R.T @ (np.asarray(ray_origin, float) - t)
        d = R.T @ np.asarray(ray_direction, float)
        if abs(d[2]) < 1e-12:
            return None
        hit = o - (o[2] / d[2]) * d
        u = (hit[0] / rw + 0.5) * model.width_px - 0.5
        v = (hit[1] / rh + 0.5) * model.height_px - 0.5
        if not (-0.5 <= u <= model.width_px - 0.5 and -0.5 <= v <= model.height_px - 0.5):
            return None
        return float(u), float(v)

    def clicked_camera(self, client_id, board_cam: str) -> str:
        """The camera a click corrects: the one the client looks through, else the clicked board's."""
        viewing = self.viewing.get(client_id)
        return viewing[0] if viewing is not None else board_cam

    def on_board_click(self, event, cam: str) -> None:
        if event.client_id in self.wb.state.modes.picking:
            return  # this click picks the sonar centre in 3D (the scene-wide handler)
        cam = self.clicked_camera(event.client_id, cam)
        uv = self.pixel_from_ray(cam, event.ray_origin, event.ray_direction)
        if uv is None:
            raise ValueError(f"the click missed {cam}'s image")
        cid = self.wb.state.selected
        entry = self.correct_click(cid, cam, uv, client_tag(event))
        title, body, colour = click_message(cid, cam, entry, bool(self.refit.value))
        notify(self.wb.server, event.client, title, body, color=colour, seconds=6)

    def expected_radius_px(self, cid: str, cam: str) -> float | None:
        """Apparent sphere radius (px) to refit with: from the calibration and the sonar centre,
        else the current detection's, else None (the detector's own range)."""
        st = self.wb.state
        cal, son = st.T_cam_sonar(cam), (st.entry(cid, "sonar") or {}).get("center")
        if cal is not None and son is not None:
            T, s = cal
            z = float((T[:3, :3] @ (np.asarray(son, float) / s) + T[:3, 3])[2])
            if z > 0:
                return st.camera(cam).fx * st.session.sphere_radius_m / z
        r = (st.entry(cid, cam) or {}).get("radius_px")
        return float(r) if isinstance(r, (int, float)) and r > 0 else None

    def correct_click(self, cid: str, cam: str, uv, client: str) -> dict:
        """Correct camera ``cam``'s detection in capture ``cid`` from a click at raw pixel ``uv``."""
        st = self.wb.state
        if self.refit.value:
            entry = refit_image(st.data, cid, cam, uv, self.expected_radius_px(cid, cam))
            entry["refit_asked"] = True
        else:
            s2 = CLICK_SIGMA_IMAGE_PX ** 2
            entry = {"center": [float(uv[0]), float(uv[1])], "cov_px2": [s2, 0.0, 0.0, s2],
                     "method": "operator-click", "refit": False, "refit_asked": False}
        st.correct(cid, cam, entry, client, action="click")
        st.bus.publish("corrected", cid=cid, sensor=cam)
        return st.entry(cid, cam)

    def view_through(self, client, cam: str) -> None:
        """Put ``client``'s viewpoint in front of ``cam``'s image board, filling the view."""
        T_cam_board, rw, rh = self.board_geometry(cam)
        T_world_cam = camera_pose(self.wb.state, cam)
        R = T_world_cam[:3, :3]
        centre = T_world_cam[:3, :3] @ T_cam_board[:3, 3] + T_world_cam[:3, 3]
        d = T_cam_board[2, 3]
        eye = centre - R[:, 2] * d
        aspect = float(client.camera.aspect or 1.0)
        half = max(rh, rw / max(aspect, 1e-3)) / (2 * d) * 1.06  # fit both ways, 6 % margin
        with client.atomic():
            client.camera.up_direction = -R[:, 1]
            client.camera.position = eye
            client.camera.look_at = centre
            client.camera.fov = float(2 * np.arctan(half))
        self.viewing[client.client_id] = (cam, eye)
        if self.focus_cam != cam:
            self.focus_cam = cam  # other cameras' boards would stand in front of this one
            for other, board in self.boards.items():
                board.visible = other == cam

    def on_focus(self, client=None, cid=None, sensor=None, flag=None) -> None:
        """A flag (or "Frame the selected capture") asks ``client`` to look at ``sensor``."""
        if client is None:
            return
        cam = flag.camera if flag is not None and sensor != "sonar" else None
        if cam is not None:
            self.wb.refresher.mark("overlay")  # the selected capture's image (predicted position marked) first,
            self.wb.refresher.wait_idle(10)  # drawn by the refresh thread (the one that draws boards)
            self.view_through(client, cam)
        else:
            self.viewing.pop(client.client_id, None)
            self.focus_cam = None
            self.wb.refresher.mark("overlay")

    def follow_views(self) -> None:
        """Clients still looking through a camera keep doing so when its pose changes (a new solve)."""
        clients = self.wb.server.get_clients()
        for cid, (cam, eye) in list(self.viewing.items()):
            client = clients.get(cid)
            if client is None:
                del self.viewing[cid]
            elif np.allclose(client.camera.position, eye, atol=1e-3):
                self.view_through(client, cam)
            else:
                del self.viewing[cid]  # the operator has moved away: leave the view alone
