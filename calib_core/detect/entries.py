"""One automatic detection of one capture and sensor, as a ``detections.yaml`` entry.

- :class:`SessionData`: per-session caches (intrinsics, background models, the effective
  beam width) a shell keeps between calls;
- :func:`detect_image_entry` / :func:`detect_sonar_entry`: the detectors on one capture's
  files; :func:`detect_one` is what a worker process of :mod:`calib_core.parallel` runs;
- the session's effective beam width from its sphere scans (:func:`session_beam_width`, and
  in parts for the process pool: :func:`beam_capture_ids`, :func:`beam_crop_of`,
  :func:`beam_width_from_crops`).

:mod:`calib_core.pipeline` runs these over a session (and re-exports them).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib_core.camera import CameraModel
from calib_core.detections import is_operator_entry
from calib_core.detect.reasons import cloud_units_reason
from calib_core.errors import SessionError
from calib_core.session import Session


@dataclass
class SessionData:
    """Per-session caches a shell may keep between calls (intrinsics, background models)."""

    session: Session
    cameras: dict[str, CameraModel] = field(default_factory=dict)
    backgrounds: dict[str, object | None] = field(default_factory=dict)  # PreparedBackground per camera
    beam_width_deg: float | None = None  # effective beam width estimated by detect_session

    @property
    def effective_beam_width_deg(self) -> float:
        """The estimated effective beam width when there is one, else the manifest's."""
        return self.beam_width_deg or self.session.beam_width_deg or 1.0

    def adopt_beam_width(self, detections: dict) -> None:
        """Take the effective beam width an earlier detection run recorded in the sonar entries
        (their median), so refits after a reload use the same width as the first detection."""
        if self.beam_width_deg is None:
            nominal = self.session.beam_width_deg or 1.0
            widths = [e["beam_width_deg"] for d in detections.values() for s, e in d.items()
                      if s == "sonar" and isinstance(e.get("beam_width_deg"), (int, float))
                      and e.get("beam_width_nominal_deg", nominal) == nominal]
            if widths:
                self.beam_width_deg = float(np.median(widths))

    def camera(self, cam: str) -> CameraModel:
        if cam not in self.cameras:
            self.cameras[cam] = self.session.camera_model(cam)
        return self.cameras[cam]

    def background(self, cam: str):
        """Background model of a camera (median of its frames, prepared for repeated detections),
        None when it has none."""
        if cam not in self.backgrounds:
            from calib_core.detect.image.detect import background_model, prepare_background
            from calib_core.io.images import load_background_frames

            spec = self.session.cameras[cam]
            if spec.background_path is None:
                self.backgrounds[cam] = None
            else:
                start, end = spec.background_window_s
                model = self.camera(cam)
                frames = load_background_frames(spec.background_path, (model.width_px, model.height_px),
                                                root=self.session.root, start_s=start, end_s=end)
                _check_image_size(spec.background_path, frames[0], self.camera(cam))
                self.backgrounds[cam] = prepare_background(background_model(frames, how="median"))
        return self.backgrounds[cam]


def _check_image_size(path, image, cam: CameraModel) -> None:
    h, w = image.shape[:2]
    if (w, h) != (cam.width_px, cam.height_px):
        raise SessionError(path, f"image is {w} x {h} but its intrinsics say {cam.width_px} x {cam.height_px}")


def as_data(session_or_data) -> SessionData:
    return session_or_data if isinstance(session_or_data, SessionData) else SessionData(session_or_data)


def load_capture_image(data: SessionData, capture_id: str, cam: str):
    """One capture's image of camera ``cam`` (RGB uint8), checked against its intrinsics' size."""
    from calib_core.io.images import load_image

    path = data.session.capture(capture_id).image_paths[cam]
    model = data.camera(cam)
    image = load_image(path, (model.width_px, model.height_px))
    _check_image_size(path, image, model)
    return image


def detect_image_entry(data: SessionData | Session, capture_id: str, cam: str,
                       hint_uv_px=None, hint_radius_px=None, image_rgb=None) -> dict:
    """Run the image detector on one capture's image; return a detections.yaml entry (auto).
    ``image_rgb``: that image as :func:`load_capture_image` gives it, when already loaded."""
    from calib_core.detect.image.detect import detect_sphere_in_image

    data = as_data(data)
    image = load_capture_image(data, capture_id, cam) if image_rgb is None else image_rgb
    model = data.camera(cam)
    det = detect_sphere_in_image(image, model, data.session.sphere_radius_m, background=data.background(cam),
                                 hint_uv_px=hint_uv_px, hint_radius_px=hint_radius_px)
    return det.to_entry()


def detect_sonar_entry(data: SessionData | Session, capture_id: str, seed_center_m=None, points_sonar_m=None,
                       prepared=None) -> dict:
    """Run the sonar detector on one capture's cloud; return a detections.yaml entry (auto).

    Uses the session's effective beam width (estimated by :func:`detect_session`, else the
    manifest's ``sonar.beam_width_deg``) and records it in the entry. ``points_sonar_m``: the
    cloud, when loaded already; ``prepared``: its search's beam-width-independent part
    (:func:`calib_core.detect.sonar.search.prepare_search`, e.g. from the beam width estimate).
    """
    from calib_core.detect.sonar.detect import detect_sphere_in_cloud
    from calib_core.io.clouds import load_cloud

    data = as_data(data)
    s = data.session
    if points_sonar_m is None:
        points_sonar_m = load_cloud(s.capture(capture_id).cloud_path).points_m
    beam = data.effective_beam_width_deg
    det = detect_sphere_in_cloud(points_sonar_m, s.sphere_radius_m, beam_width_deg=beam, seed_center_m=seed_center_m,
                                 prepared=prepared)
    entry = det.to_entry()
    units = None if det.found else cloud_units_reason(points_sonar_m, 2 * s.sphere_radius_m)
    if units:
        entry["reason"] = f"{units} ({entry.get('reason') or 'not found'})"
    entry["beam_width_deg"] = round(float(beam), 4)
    entry["beam_width_nominal_deg"] = float(s.beam_width_deg or 1.0)
    return entry


def estimate_session_beam_width(data: SessionData, clouds: dict[str, np.ndarray], detections: dict,
                                prepared: dict | None = None) -> float | None:
    """Effective beam width (deg) from all sphere scans of the session, or None when it cannot
    be estimated (fewer than 3 spheres found). Operator-validated sonar centres are used as given.
    ``prepared``: {capture_id: the cloud's prepared search} (:func:`prepared_searches`), optional.

    Why: blooming depends on the angle out to which a strong target still returns, which is
    the nominal width only approximately (it depends on target strength and threshold).
    """
    from calib_core.detect.sonar.beam import estimate_beam_width_deg

    ids = list(clouds)
    nominal = data.session.beam_width_deg or 1.0
    est = estimate_beam_width_deg([clouds[c] for c in ids], data.session.sphere_radius_m, nominal_deg=nominal,
                                  centers_sonar_m=[_operator_center(detections, c) for c in ids],
                                  prepared=[(prepared or {}).get(c) for c in ids])
    return None if est.reason else float(est.beam_width_deg)


def _operator_center(detections: dict, cid: str):
    e = detections.get(cid, {}).get("sonar")
    return np.asarray(e["center"], float) if is_operator_entry(e) and e.get("center") else None


def beam_capture_ids(capture_ids: list[str]) -> list[str]:
    """The captures the beam-width estimate looks at (spread over the session, at most its maximum)."""
    from calib_core.detect.sonar.beam import MAX_CAPTURES, spread_order

    return [capture_ids[i] for i in spread_order(len(capture_ids))][:MAX_CAPTURES]


def beam_crop_of(data: SessionData, cid: str, detections: dict):
    """One capture's crop for the beam-width estimate (sonar.beam.beam_crop), loaded from its cloud."""
    from calib_core.detect.sonar.beam import beam_crop
    from calib_core.io.clouds import load_cloud

    P = load_cloud(data.session.capture(cid).cloud_path).points_m
    return beam_crop(P, data.session.sphere_radius_m, data.session.beam_width_deg or 1.0,
                     _operator_center(detections, cid))


def beam_width_from_crops(data: SessionData, crops: list) -> float | None:
    """The session's effective beam width from the crops of :func:`beam_crop_of`, or None."""
    from calib_core.detect.sonar.beam import estimate_from_crops

    est = estimate_from_crops(crops, data.session.sphere_radius_m, data.session.beam_width_deg or 1.0)
    return None if est.reason else float(est.beam_width_deg)


def session_beam_width(data: SessionData, capture_ids: list[str], detections: dict) -> float | None:
    """Load the clouds of ``capture_ids`` and estimate the session's effective beam width
    (:func:`estimate_session_beam_width`); None when it cannot be estimated."""
    return session_beam_width_shared(data, capture_ids, detections)[0]


@dataclass(frozen=True)
class SharedCloud:
    """A capture's cloud (sonar frame, m) as the beam width estimate loaded it, and the part of
    its candidate search that does not depend on the beam width
    (:func:`calib_core.detect.sonar.search.prepare_search`): its final detection reuses both."""

    points_sonar_m: np.ndarray
    prepared: object


def session_beam_width_shared(data: SessionData, capture_ids: list[str],
                              detections: dict) -> tuple[float | None, dict[str, SharedCloud]]:
    """(:func:`session_beam_width`, {capture_id: SharedCloud} of the clouds whose sphere the
    estimate detected: everything but operator-validated centres)."""
    from calib_core.io.clouds import load_cloud

    clouds = {cid: load_cloud(data.session.capture(cid).cloud_path).points_m for cid in capture_ids}
    prepared = prepared_searches(data, clouds, detections)
    width = estimate_session_beam_width(data, clouds, detections, prepared)
    return width, {cid: SharedCloud(clouds[cid], prepared[cid]) for cid in prepared}


def prepared_searches(data: SessionData, clouds: dict[str, np.ndarray], detections: dict) -> dict:
    """{capture_id: the cloud's prepared candidate search} for the clouds without an
    operator-validated sonar centre (the ones the beam width estimate detects the sphere in)."""
    from calib_core.detect.sonar.search import prepare_search

    r = data.session.sphere_radius_m
    return {cid: prepare_search(np.asarray(P, float).reshape(-1, 3), r) for cid, P in clouds.items()
            if _operator_center(detections, cid) is None}


def detect_one(data: SessionData, cid: str, sensor: str, image_rgb=None, cloud: SharedCloud | None = None) -> dict:
    """One automatic detection (no fingerprint): what a worker process runs. ``image_rgb``: an
    image task's image, already loaded (:func:`load_capture_image`); ``cloud``: a sonar task's
    cloud and prepared search, from the beam width estimate."""
    if sensor == "sonar":
        if cloud is not None:
            return detect_sonar_entry(data, cid, points_sonar_m=cloud.points_sonar_m, prepared=cloud.prepared)
        return detect_sonar_entry(data, cid)
    return detect_image_entry(data, cid, sensor, image_rgb=image_rgb)


def prefetch_jobs(data: SessionData, todo: list[tuple[str, str]]) -> list:
    """[(key, function)] loading what ``todo``'s image tasks need, in the order they need it:
    each camera's background model (cached in ``data``) before its first image, then the image
    (key (capture_id, camera)). A background model that fails is left for its first detection
    to compute again and report, as it would without the prefetch."""
    jobs, seen = [], set()
    for cid, sensor in todo:
        if sensor == "sonar":
            continue
        if sensor not in seen:
            seen.add(sensor)
            jobs.append((("background", sensor), lambda cam=sensor: _background_or_none(data, cam)))
        jobs.append(((cid, sensor), lambda c=cid, cam=sensor: load_capture_image(data, c, cam)))
    return jobs


def _background_or_none(data: SessionData, cam: str):
    try:
        return data.background(cam)
    except Exception:  # noqa: BLE001 (raised again by the detection, in its place)
        return None
