"""Why a capture does not fit: image detection wrong, sonar detection wrong, or target moved.

For a capture outside a camera's consensus (:mod:`calib_core.diagnose.consistency`):

- image wrong: the image detector, started at the pixel where the consensus pose projects the
  sonar centre, finds the sphere there (or, when it is partly hidden and the detector gives up,
  a good part of a round outline of the expected size is there: :mod:`.outline`), and it is
  not the detected one;
- sonar wrong: the sonar detector, started where the image detection puts the sphere (its
  ray at the range its apparent size gives, mapped into the sonar frame), finds a sphere
  there, and it is not the detected one;
- moved: neither explains the other.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib_core.diagnose import wording
from calib_core.diagnose.consistency import check_camera
from calib_core.diagnose.outline import find_outline
from calib_core.geometry import invert_T
from calib_core.solve.consensus import NO_CONSENSUS


@dataclass
class Flag:
    """One diagnosed problem.

    capture, sensor: what is implicated (sensor "sonar", a camera, or "capture" for moved).
    cause: "image", "sonar" or "moved"; camera: the camera whose consensus flagged it.
    miss_px: the capture's residual at the consensus pose; predicted_uv_px: where the sonar
    says the sphere is in ``camera``'s image; predicted_sonar_m: where the image says it is
    in the sonar frame; suggestion: the detector's entry at the predicted place, if it found one.
    """

    capture: str
    sensor: str
    cause: str
    camera: str
    miss_px: float
    predicted_uv_px: list | None = None
    predicted_sonar_m: list | None = None
    gap: float | None = None
    suggestion: dict | None = field(default=None, repr=False)

    @property
    def title(self) -> str:
        return wording.title(self.cause, self.capture, self.sensor)

    @property
    def text(self) -> str:
        return wording.explain(self.cause, self.capture, self.sensor, self.miss_px, self.gap)


def _project(model, T_cam_sonar, X) -> tuple[np.ndarray, float]:
    P = T_cam_sonar[:3, :3] @ np.asarray(X, float) + T_cam_sonar[:3, 3]
    return model.project(P[None])[0], float(P[2])


def _image_explains(data, cid, cam, T, son, img) -> Flag | None:
    from calib_core.io.images import load_image

    model = data.camera(cam)
    uv, z = _project(model, T, son["center"])
    if z <= 0 or not (0 <= uv[0] < model.width_px and 0 <= uv[1] < model.height_px):
        return None
    r_px = model.fx * data.session.sphere_radius_m / z
    found = _detector_at(data, cid, cam, uv, r_px)  # the image detector, started at the predicted place
    if found is None:  # a partly hidden sphere defeats the detector: look for part of its outline
        o = find_outline(load_image(data.session.capture(cid).image_paths[cam]), uv, r_px, search=0.25)
        if not o.found:
            return None
        found = {"center": [float(v) for v in o.center_uv_px], "radius_px": float(o.radius_px),
                 "outline_support": round(o.support, 3), "method": "outline"}
    gap = float(np.linalg.norm(np.asarray(found["center"], float) - np.asarray(img["center"], float)))
    if gap <= 1.5 * r_px:
        return None  # what is there is (part of) the detected sphere: the image is not what is wrong
    return Flag(cid, cam, "image", cam, 0.0, [float(v) for v in uv], None, gap, found)


def _detector_at(data, cid, cam, uv, r_px) -> dict | None:
    """The image detector's entry when it finds a sphere within half a radius of ``uv``, else None."""
    from calib_core.pipeline import detect_image_entry

    e = detect_image_entry(data, cid, cam, hint_uv_px=uv, hint_radius_px=r_px)
    if e.get("center") is None or np.linalg.norm(np.asarray(e["center"], float) - uv) > 0.5 * r_px:
        return None
    return e


def _sonar_explains(data, cid, cam, T, son, img) -> Flag | None:
    from calib_core.pipeline import detect_sonar_entry

    rng = img.get("range_m")
    if not rng:
        return None
    P_cam = data.camera(cam).rays(np.asarray([img["center"]], float))[0] * float(rng)
    X = invert_T(T)[:3, :3] @ P_cam + invert_T(T)[:3, 3]
    e = detect_sonar_entry(data, cid, seed_center_m=X)
    if e.get("center") is None:
        return None
    found = np.asarray(e["center"], float)
    gap = float(np.linalg.norm(found - np.asarray(son["center"], float)))
    tol = max(0.08 * float(rng), data.session.sphere_diameter_m)  # range from size is good to a few %
    if np.linalg.norm(found - X) <= tol and gap > data.session.sphere_diameter_m:
        return Flag(cid, "sonar", "sonar", cam, 0.0, None, [float(v) for v in X], gap, e)
    return None


def explain_capture(data, detections: dict, cid: str, cam: str, T_cam_sonar: np.ndarray, miss_px: float) -> Flag:
    """The cause of one capture's misfit in camera ``cam`` at the consensus pose."""
    d = detections.get(cid, {})
    son, img = d.get("sonar") or {}, d.get(cam) or {}
    for test in (_image_explains, _sonar_explains):
        f = test(data, cid, cam, T_cam_sonar, son, img)
        if f is not None:
            f.miss_px = miss_px
            return f
    uv, _z = _project(data.camera(cam), T_cam_sonar, son["center"])
    return Flag(cid, "capture", "moved", cam, miss_px, [float(v) for v in uv])


def diagnose_session(session_or_data, detections: dict, notes: list | None = None) -> list[Flag]:
    """Flags for every capture that does not fit (image and sonar flags per camera; a capture's
    'moved' or 'sonar' flag once, from the first camera that raised it). ``notes``, when given,
    receives the solver's plain words when a camera's captures show no clear consensus
    (:func:`calib_core.solve.consensus.no_consensus_phrase`)."""
    from calib_core.pipeline import as_data

    data = as_data(session_or_data)
    flags: list[Flag] = []
    seen: set = set()
    for cam in data.session.cameras:
        cons = check_camera(data.session, detections, cam)
        if cons is None:
            continue
        if notes is not None and not cons.clear:
            notes += [w for w in cons.warnings if NO_CONSENSUS in w]
        for cid in cons.outliers:
            if (cid, "capture") in seen or (cid, "sonar") in seen:
                continue
            f = explain_capture(data, detections, cid, cam, cons.T_cam_sonar, cons.residual_px[cid])
            if (f.capture, f.sensor) not in seen:
                seen.add((f.capture, f.sensor))
                flags.append(f)
    return flags
