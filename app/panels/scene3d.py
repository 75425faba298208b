"""3D view: the sonar frame, clouds, detected centres, camera frustums, rays, ground truth.

The world frame is the sonar frame as the clouds are written (metres). A calibration
with a range scale ``s`` (cloud range = true range * s, as calib_core.solve.model) maps
cloud points ``X`` to the camera by ``T_cam_sonar (X / s)``, so a camera whose centre is
``c`` in the true sonar frame sits at ``s c`` in this frame. Projection and colouring use
calib_core; the only arithmetic here is placing nodes and drawing rays for display.
"""

from __future__ import annotations

import cv2
import numpy as np

from app.common import guarded, pose_wxyz_position
from calib_core.camera import vertical_fov_rad

STATUS_RGB = {"auto": (240, 200, 0), "accepted": (30, 190, 60), "corrected": (40, 120, 255), "rejected": (220, 40, 40)}
CAM_RGB = [(255, 120, 0), (0, 170, 170), (150, 60, 220), (120, 120, 0)]
GT_RGB = (230, 0, 230)
FRUSTUM_MAX_FOV = np.radians(170.0)  # a frustum cannot show 180 deg or more (wide fisheyes)
PALETTE = np.array([(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75),
                    (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207)], np.uint8)


def colormap(values: np.ndarray) -> np.ndarray:
    """(N,) values -> (N,3) RGB uint8 with OpenCV's turbo map (robust 2-98 % stretch)."""
    v = np.asarray(values, float)
    if v.size == 0:
        return np.zeros((0, 3), np.uint8)
    lo, hi = np.percentile(v, [2, 98])
    t = np.clip((v - lo) / max(hi - lo, 1e-12), 0, 1)
    bgr = cv2.applyColorMap(np.round(t * 255).astype(np.uint8).reshape(-1, 1), cv2.COLORMAP_TURBO)
    return bgr.reshape(-1, 3)[:, ::-1].copy()


def camera_pose_in_cloud_frame(T_cam_sonar: np.ndarray, range_scale: float) -> np.ndarray:
    """4x4 pose of the camera in the cloud (world) frame for display (see module doc)."""
    R, t = T_cam_sonar[:3, :3], T_cam_sonar[:3, 3]
    T = np.eye(4)
    T[:3, :3] = R.T
    T[:3, 3] = (-R.T @ t) * range_scale
    return T


def camera_pose(state, cam: str) -> np.ndarray:
    """World pose of a camera node: the calibration's, or an uncalibrated stand-in."""
    cal = state.T_cam_sonar(cam)
    if cal is not None:
        return camera_pose_in_cloud_frame(*cal)
    # uncalibrated: beside the sonar, looking along its +x (x forward, y left, z up), image down = -z
    T = np.eye(4)
    T[:3, :3] = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    T[1, 3] = -0.4 * (1 + list(state.session.cameras).index(cam))
    return T


class Scene3D:
    def __init__(self, wb):
        self.wb = wb
        gui = wb.server.gui
        with wb.tab_view:
            self.colour_by = gui.add_dropdown("Colour clouds by", ("range", "intensity", "capture"), initial_value="range")
            self.point_size = gui.add_slider("Point size (m)", min=0.002, max=0.08, step=0.001, initial_value=0.02)
            self.only_selected = gui.add_checkbox("Only the selected capture's cloud", True)
            self.show_centres = gui.add_checkbox("Detected centres", True)
            self.show_rays = gui.add_checkbox("Rays and residuals", True)
            self.show_cams = gui.add_checkbox("Camera frustums", True)
            self.show_gt = gui.add_checkbox("Ground truth (magenta)", True, hint="Shown when the session has ground_truth.yaml")
            self.frame_btn = gui.add_button("Frame the selected capture", hint="Move your view to the selected capture")
            self.cloud_folder = gui.add_folder("Clouds per capture", expand_by_default=False)
        self.cloud_toggles: dict = {}
        self.cloud_nodes: dict = {}
        self.cloud_colour_key: dict = {}
        self.frustums: dict = {}
        self.cam_frames: dict = {}
        self.hidden: set = set()  # captures whose plain cloud is hidden (shown fused instead)
        for h in (self.colour_by, self.point_size, self.only_selected):
            h.on_update(lambda _e: wb.refresher.mark("clouds"))
        for h in (self.show_centres, self.show_rays, self.show_cams, self.show_gt):
            h.on_update(lambda _e: wb.refresher.mark("detections", "calibration"))
        self.frame_btn.on_click(guarded(wb.server)(lambda e: self._frame(e.client)))
        wb.state.bus.subscribe("focus", self.on_focus)
        wb.state.bus.subscribe("fused", self.on_fused)
        r = wb.refresher
        r.on("selection", self.refresh_clouds, heavy=True)  # loads and sends clouds: after the review table
        r.on("clouds", self.refresh_clouds, heavy=True)
        for kind in ("detections", "calibration", "selection"):
            r.on(kind, self.refresh_markers)
        for kind in ("calibration", "selection"):
            r.on(kind, self.refresh_cameras)

    # ---- session ---------------------------------------------------------
    def rebuild(self) -> None:
        sc = self.wb.server.scene
        for node in list(self.cloud_nodes.values()) + list(self.cloud_toggles.values()):
            node.remove()
        for h in list(self.frustums.values()) + list(self.cam_frames.values()):
            h.remove()
        self.cam_frames.clear()
        self.cloud_nodes.clear(), self.cloud_toggles.clear(), self.frustums.clear(), self.cloud_colour_key.clear()
        for name in ("/centres", "/selected_sphere", "/rays", "/residuals", "/gt"):
            try:
                sc.remove_by_name(name)
            except Exception:
                pass
        sc.add_frame("/sonar", axes_length=0.25, axes_radius=0.008)
        sc.add_label("/sonar/label", "sonar")
        s = self.wb.state.session
        with self.cloud_folder:
            for cap in s.captures:
                cb = self.wb.server.gui.add_checkbox(f"cloud {cap.id}", False)
                cb.on_update(lambda _e: self.wb.refresher.mark("clouds"))
                self.cloud_toggles[cap.id] = cb

    def _frame(self, client) -> None:
        self.wb.state.bus.publish("focus", client=client, cid=self.wb.state.selected, sensor=None, flag=None)

    def on_focus(self, client=None, cid=None, sensor=None, flag=None) -> None:
        """Frame the capture for a sonar flag (or "Frame the selected capture"); mark where the
        image says the sphere is (cyan) when a flag knows it."""
        sc = self.wb.server.scene
        where = getattr(flag, "predicted_sonar_m", None)
        if where is not None:
            sc.add_icosphere("/flag_predicted", radius=self.wb.state.session.sphere_radius_m, color=(0, 200, 230),
                             wireframe=True, opacity=0.8, position=np.asarray(where, float))
        else:
            try:
                sc.remove_by_name("/flag_predicted")
            except Exception:  # nothing marked
                pass
        if client is not None and (sensor in (None, "sonar") or flag is None):
            self.home_view(client)

    def on_fused(self, cid=None) -> None:
        """While a fused cloud is shown, the plain clouds step aside (one cloud on screen)."""
        self.hidden = {c.id for c in self.wb.state.session.captures} if cid is not None else set()
        self.wb.refresher.mark("clouds")

    def home_view(self, client) -> None:
        """Frame the cameras and the selected capture (its sonar centre, else its cloud), seen from
        behind the cameras, a little above and aside: the image boards face the viewer."""
        st = self.wb.state
        if st.session is None or st.selected is None or client is None:
            return
        son = (st.entry(st.selected, "sonar") or {}).get("center")
        target = np.asarray(son, float) if son is not None else np.median(st.cloud(st.selected).points_m, axis=0)
        poses = [camera_pose(st, cam) for cam in st.session.cameras]
        cams = np.mean([T[:3, 3] for T in poses], axis=0)
        axis = np.mean([T[:3, 2] for T in poses], axis=0)
        axis = axis / max(np.linalg.norm(axis), 1e-9)
        dist = max(1.0, float(np.linalg.norm(target - cams)))
        up = np.array([0.0, 0.0, 1.0])
        side = np.cross(axis, up)
        side = side / np.linalg.norm(side) if np.linalg.norm(side) > 1e-6 else np.array([0.0, 1.0, 0.0])
        with client.atomic():
            client.camera.up_direction = tuple(up)
            client.camera.position = cams - 0.9 * dist * axis + 0.35 * dist * up + 0.25 * dist * side
            client.camera.look_at = 0.5 * (cams + target)

    # ---- clouds --------------------------------------------------------------
    def _colours(self, cid: str, cloud, mode: str) -> np.ndarray:
        if mode == "intensity" and cloud.intensity is not None:
            return colormap(cloud.intensity)
        if mode == "capture":
            ids = [c.id for c in self.wb.state.session.captures]
            return np.tile(PALETTE[ids.index(cid) % len(PALETTE)], (len(cloud), 1))
        return colormap(np.linalg.norm(cloud.points_m, axis=1))

    def refresh_clouds(self) -> None:
        st = self.wb.state
        if st.session is None:
            return
        sc = self.wb.server.scene
        mode, size = self.colour_by.value, float(self.point_size.value)
        for cap in st.session.captures:
            want = cap.id == st.selected if self.only_selected.value else self.cloud_toggles[cap.id].value
            want = want and cap.id not in self.hidden
            node = self.cloud_nodes.get(cap.id)
            if not want:
                if node is not None:
                    node.visible = False
                continue
            if node is None or self.cloud_colour_key.get(cap.id) != mode:
                cloud = st.cloud(cap.id)
                colours = self._colours(cap.id, cloud, mode)
                if node is None:
                    node = sc.add_point_cloud(f"/clouds/{cap.id}", cloud.points_m.astype(np.float32), colours,
                                              point_size=size, precision="float32", point_shape="circle")
                    self.cloud_nodes[cap.id] = node
                else:
                    node.colors = colours
                self.cloud_colour_key[cap.id] = mode
            node.point_size = size
            node.visible = True

    # ---- centres, rays, ground truth -----------------------------------------
    def refresh_markers(self) -> None:
        st = self.wb.state
        if st.session is None:
            return
        sc = self.wb.server.scene
        with st.lock:
            dets = {cid: dict(v) for cid, v in st.detections.items()}
            sel = st.selected
            gt = st.ground_truth
        centres, colours = [], []
        for cap in st.session.captures:
            e = dets.get(cap.id, {}).get("sonar") or {}
            if e.get("center") is not None:
                centres.append(e["center"])
                colours.append(STATUS_RGB.get(e.get("status", "auto"), (200, 200, 200)))
        if centres:
            sc.add_point_cloud("/centres", np.asarray(centres, np.float32), np.asarray(colours, np.uint8),
                               point_size=0.04, precision="float32", point_shape="circle", visible=self.show_centres.value)
        e = dets.get(sel, {}).get("sonar") or {}
        if e.get("center") is not None:
            sc.add_icosphere("/selected_sphere", radius=st.session.sphere_radius_m,
                             color=STATUS_RGB.get(e.get("status", "auto")), wireframe=True, opacity=0.6,
                             position=np.asarray(e["center"], float), visible=self.show_centres.value)
        else:
            sc.add_icosphere("/selected_sphere", radius=0.01, visible=False)
        self._rays(dets)
        self._ground_truth(gt)

    def _rays(self, dets: dict) -> None:
        sc = self.wb.server.scene
        st = self.wb.state
        rays, res = [], []
        for cam in st.session.cameras:
            cal = st.T_cam_sonar(cam)
            if cal is None:
                continue
            T_world_cam = camera_pose_in_cloud_frame(*cal)
            uv, X = [], []
            for cap in st.session.captures:
                d = dets.get(cap.id, {})
                img, son = d.get(cam) or {}, d.get("sonar") or {}
                if img.get("center") is None or son.get("center") is None or "rejected" in (img.get("status"), son.get("status")):
                    continue
                uv.append(img["center"])
                X.append(son["center"])
            if not uv:
                continue
            o = T_world_cam[:3, 3]
            W = st.camera(cam).rays(np.asarray(uv, float)) @ T_world_cam[:3, :3].T  # unit rays, world frame
            for w, x in zip(W, np.asarray(X, float)):
                along = float(w @ (x - o))
                p = o + max(along, 0.0) * w  # closest point of the ray to the sonar centre
                rays.append([o, o + max(along, 0.1) * 1.15 * w])
                res.append([p, x])
        if rays:
            sc.add_line_segments("/rays", np.asarray(rays, np.float32), (120, 120, 255), thickness=1.5,
                                 thickness_units="screen",
                                 visible=self.show_rays.value)
            sc.add_line_segments("/residuals", np.asarray(res, np.float32), (255, 0, 0), thickness=3.0,
                                 thickness_units="screen",
                                 visible=self.show_rays.value)
        else:
            for name in ("/rays", "/residuals"):
                try:
                    sc.remove_by_name(name)
                except Exception:
                    pass

    def _ground_truth(self, gt: dict | None) -> None:
        sc = self.wb.server.scene
        if not gt:
            return
        s = float(gt.get("range_scale", 1.0) or 1.0)
        pts = [np.asarray(c["center_sonar_m"], float) * s for c in (gt.get("captures") or {}).values()
               if c.get("center_sonar_m") is not None]
        if pts:
            sc.add_point_cloud("/gt/centres", np.asarray(pts, np.float32), GT_RGB, point_size=0.03,
                               precision="float32", point_shape="diamond", visible=self.show_gt.value)
        for cam, c in (gt.get("cameras") or {}).items():
            T = np.asarray(c["T_cam_sonar"], float)
            T_w = camera_pose_in_cloud_frame(T, s)
            wxyz, pos = pose_wxyz_position(T_w)
            model = self.wb.state.camera(cam) if cam in self.wb.state.session.cameras else None
            fov = min(vertical_fov_rad(model), FRUSTUM_MAX_FOV) if model else 0.8
            aspect = model.width_px / model.height_px if model else 1.5
            sc.add_camera_frustum(f"/gt/{cam}", fov=fov, aspect=aspect, scale=0.12, color=GT_RGB, wxyz=wxyz,
                                  thickness=2.0, thickness_units="screen",
                                  position=pos, visible=self.show_gt.value)

    # ---- cameras ---------------------------------------------------------------
    def camera_pose(self, cam: str) -> np.ndarray:
        return camera_pose(self.wb.state, cam)

    def refresh_cameras(self) -> None:
        st = self.wb.state
        if st.session is None:
            return
        sc = self.wb.server.scene
        for k, cam in enumerate(st.session.cameras):
            model = st.camera(cam)
            wxyz, pos = pose_wxyz_position(self.camera_pose(cam))
            frame = self.cam_frames.get(cam)
            if frame is None:  # created once: its children (frustum, image board) follow its pose
                frame = self.cam_frames[cam] = sc.add_frame(f"/cams/{cam}", show_axes=False)
            frame.wxyz, frame.position, frame.visible = wxyz, pos, self.show_cams.value
            calibrated = st.T_cam_sonar(cam) is not None
            self.frustums[cam] = sc.add_camera_frustum(
                f"/cams/{cam}/frustum", fov=min(vertical_fov_rad(model), FRUSTUM_MAX_FOV),
                aspect=model.width_px / model.height_px, scale=0.15, thickness=2.0, thickness_units="screen",
                color=CAM_RGB[k % len(CAM_RGB)] if calibrated else (150, 150, 150))
            sc.add_label(f"/cams/{cam}/label", cam if calibrated else f"{cam} (uncalibrated)")
