"""Did the target stay still during a scan? Track the sphere through the frames recorded then.

Per capture and camera, the sphere is detected in every frame of the scan; the frame nearest
the middle of the scan is the one kept. Motion is measured from that frame's centre:
``motion_px`` is the largest pixel distance of any other frame's centre; ``motion_m`` the
largest distance in metres, across the line of sight (at the distance the known diameter
implies) and along it (``motion_along_m``): the change of that distance between the frames, less
ALONG_SIGMAS times its stated sigma, so only what the detector's own range precision vouches for
counts. A drift along the line of sight barely moves the image centre; the apparent radius in
pixels is no measure of it (an off-axis sphere's outline grows with its angle from the axis), the
exact cone fit's distance is. A capture is flagged as moved when either figure exceeds its
tolerance in any camera. The track is written to ``session.yaml`` under ``target_motion`` (see
docs/architecture.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib_core.camera import CameraModel

TOLERANCE_PX = 3.0
TOLERANCE_M = 0.02
ALONG_SIGMAS = 3.0  # a change of distance counts only beyond this many sigmas of the difference
NS = 1_000_000_000


@dataclass
class Track:
    """The sphere seen by one camera through one scan (times in s from the bag's start)."""

    t_s: list[float] = field(default_factory=list)
    uv_px: list[list[float] | None] = field(default_factory=list)
    radius_px: list[float | None] = field(default_factory=list)
    range_m: list[float | None] = field(default_factory=list)
    range_sigma_m: list[float | None] = field(default_factory=list)

    def add(self, t_s: float, det) -> None:
        self.t_s.append(round(float(t_s), 4))
        ok = det is not None and det.found
        self.uv_px.append([round(float(v), 3) for v in det.center_uv_px] if ok else None)
        self.radius_px.append(round(float(det.radius_px), 3) if ok and det.radius_px else None)
        self.range_m.append(round(float(det.range_m), 4) if ok and det.range_m else None)
        sig = (getattr(det, "extras", None) or {}).get("range_sigma_m") if ok else None
        self.range_sigma_m.append(round(float(sig), 5) if sig else None)


def motion_of(track: Track, kept: int, cam: CameraModel) -> dict:
    """Motion figures of one track relative to frame ``kept`` (the frame written to the session)."""
    found = [i for i, uv in enumerate(track.uv_px) if uv is not None]
    out = {"frames": len(track.t_s), "found": len(found), "kept": int(kept), "motion_px": None, "motion_m": None,
           "motion_along_m": None}
    if kept not in found or len(found) < 2:
        return out
    uv = np.array([track.uv_px[i] for i in found])
    ref = np.array(track.uv_px[kept])
    out["motion_px"] = round(float(np.max(np.linalg.norm(uv - ref, axis=1))), 3)
    rng = track.range_m[kept]
    xy = cam.normalize(np.vstack([ref[None], uv]))
    if rng and np.isfinite(xy).all():
        rays = np.column_stack([xy, np.ones(len(xy))])
        rays /= np.linalg.norm(rays, axis=1, keepdims=True)
        lateral = np.linalg.norm(rays[1:] - rays[0][None], axis=1) * rng
        along = along_sight_m(track, found, kept)
        out["motion_along_m"] = round(float(np.max(along)), 4)
        out["motion_m"] = round(float(np.max(np.hypot(lateral, along))), 4)
    return out


def along_sight_m(track: Track, frames: list[int], kept: int) -> np.ndarray:
    """Per frame in ``frames``: how far its distance (the detection's ``range_m``) differs from the
    kept frame's beyond ALONG_SIGMAS sigmas of the difference; 0 where a frame has no stated
    range or sigma (its change is then not vouched for)."""
    sig = track.range_sigma_m + [None] * (len(track.range_m) - len(track.range_sigma_m))
    r0, s0 = track.range_m[kept], sig[kept]
    out = np.zeros(len(frames))
    if not (r0 and s0):
        return out
    for k, i in enumerate(frames):
        r, s = track.range_m[i], sig[i]
        if r and s:
            out[k] = max(0.0, abs(r - r0) - ALONG_SIGMAS * float(np.hypot(s, s0)))
    return out


def is_moved(per_camera: dict, tol_px: float, tol_m: float) -> bool:
    for m in per_camera.values():
        if (m.get("motion_px") or 0) > tol_px or (m.get("motion_m") or 0) > tol_m:
            return True
    return False


def capture_motion(tracks: dict[str, Track], kept: dict[str, int], cams: dict[str, CameraModel],
                   tol_px: float, tol_m: float) -> dict:
    """The ``target_motion.captures.<id>`` entry: moved flag, per-camera figures and track."""
    per_cam = {}
    for name, tr in tracks.items():
        m = motion_of(tr, kept[name], cams[name])
        m.update({"t_s": tr.t_s, "uv_px": tr.uv_px, "radius_px": tr.radius_px, "range_m": tr.range_m,
                  "range_sigma_m": tr.range_sigma_m})
        per_cam[name] = m
    return {"moved": is_moved(per_cam, tol_px, tol_m), "cameras": per_cam}


def motion_summary_rows(target_motion: dict) -> list[list[str]]:
    """Rows (capture, camera, frames found, motion px, motion m, verdict) for reports and the workbench."""
    rows = []
    tol_px, tol_m = target_motion.get("tolerance_px"), target_motion.get("tolerance_m")
    for cid, ent in (target_motion.get("captures") or {}).items():
        for cam, m in (ent.get("cameras") or {}).items():
            px, mm = m.get("motion_px"), m.get("motion_m")
            rows.append([str(cid), str(cam), f"{m.get('found', 0)}/{m.get('frames', 0)}",
                         "-" if px is None else f"{px:.1f}", "-" if mm is None else f"{mm * 1000:.0f} mm",
                         "MOVED" if ent.get("moved") else "still"])
    if rows:
        rows.append(["", "", "", f"tolerance {tol_px} px", f"{(tol_m or 0) * 1000:.0f} mm", ""])
    return rows
