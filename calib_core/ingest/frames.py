"""Camera frames recorded during scans: detect the sphere in each (the track) and keep the
frame nearest the scan's middle, or (``median`` > 1, target still) the pixel-wise median of
the ``median`` frames nearest it. Holds at most ``median`` frames per camera and open scan."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib_core.camera import CameraModel
from calib_core.detect.image.detect import detect_sphere_in_image, prepare_background
from calib_core.ingest.motion import NS, Track, capture_motion
from calib_core.ingest.scans import ScanWindow


@dataclass
class _Open:
    tracks: dict[str, Track] = field(default_factory=dict)
    best: dict[str, list[tuple[int, int, np.ndarray]]] = field(default_factory=dict)  # cam -> [(|dt|, index, frame)]


class FrameKeeper:
    """Feed frames with :meth:`add`; :meth:`take` returns a scan's kept frames and motion entry."""

    def __init__(self, cams: dict[str, CameraModel], sphere_radius_m: float, windows: list[ScanWindow],
                 t0_ns: int, tol_px: float, tol_m: float, median: int = 1):
        self.cams, self.radius, self.windows, self.t0 = cams, sphere_radius_m, windows, t0_ns
        self.median = max(1, int(median))
        self.tol_px, self.tol_m = tol_px, tol_m
        self.backgrounds: dict[str, object] = {}
        self._open: dict[int, _Open] = {}

    def set_background(self, cam: str, background_rgb: np.ndarray) -> None:
        self.backgrounds[cam] = prepare_background(background_rgb)

    def add(self, cam: str, scan: int, t_ns: int, image_rgb: np.ndarray) -> None:
        model = self.cams[cam]
        if image_rgb.shape[:2] != (model.height_px, model.width_px):
            raise ValueError(f"frame is {image_rgb.shape[1]}x{image_rgb.shape[0]} but the camera info says "
                             f"{model.width_px}x{model.height_px}")
        st = self._open.setdefault(scan, _Open())
        tr = st.tracks.setdefault(cam, Track())
        prev = next((uv for uv in reversed(tr.uv_px) if uv is not None), None)
        prev_r = next((r for r in reversed(tr.radius_px) if r is not None), None)
        det = detect_sphere_in_image(image_rgb, model, self.radius, background=self.backgrounds.get(cam),
                                     hint_uv_px=prev, hint_radius_px=prev_r)
        tr.add((t_ns - self.t0) / NS, det)
        near = st.best.setdefault(cam, [])
        dt = abs(t_ns - self.windows[scan].mid_ns)
        if len(near) < self.median or dt < near[-1][0]:
            near.append((dt, len(tr.t_s) - 1, image_rgb.copy()))
            near.sort(key=lambda x: x[:2])
            del near[self.median:]

    def take(self, scan: int) -> tuple[dict[str, np.ndarray], dict | None]:
        """(camera -> kept frame, target_motion entry) of a finished scan; forgets the scan."""
        st = self._open.pop(scan, None)
        if st is None:
            return {}, None
        kept = {cam: near[0][1] for cam, near in st.best.items()}
        entry = capture_motion(st.tracks, kept, self.cams, self.tol_px, self.tol_m)
        images = {}
        for cam, near in st.best.items():
            ent = entry["cameras"][cam]
            ent["image_time_s"] = st.tracks[cam].t_s[near[0][1]]
            if len(near) > 1 and not entry["moved"]:
                images[cam] = np.median(np.stack([f for _, _, f in near]), axis=0).round().astype(np.uint8)
                ent["image"] = f"median of {len(near)} frames"
            else:
                images[cam] = near[0][2]
                ent["image"] = "mid-scan frame"
        return images, entry
