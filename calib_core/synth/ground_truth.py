"""``ground_truth.yaml``: the exact truth behind a synthetic session (the benchmarks' referee).

Format ``sonar-camera-ground-truth/1`` (written next to session.yaml)::

    format: sonar-camera-ground-truth/1
    preset: canal
    seed: 1
    range_scale: 1.0            # cloud range = true range * range_scale
    sphere_diameter_m: 0.22     # the TRUE diameter (session.yaml may state a wrong one)
    session_diameter_m: 0.22    # what session.yaml states
    cameras: {cam1: {T_cam_sonar: 4x4}}
    stereo: {T_cam2_cam1: 4x4}  # exact, = T_cam2_sonar @ inv(T_cam1_sonar); T_cam3_cam1 too with three
    sonar: {frame: ..., beam_width_deg, n_beams, fan_deg, pan_step_deg, pan_span_deg, ...}
    captures:
      p01:
        target: true            # false for non-target captures (flange), centre then null
        center_sonar_m: [x, y, z]          # true centre during the scan, unscaled
        center_sonar_at_image_m: [x, y, z] # true centre when the images were taken
        moved_m: 0.0            # distance between the two
        motion_px: [dx, dy]     # photographic presets only: the ball's blur during the exposure
                                # (px in the first camera; null = still); the centre is mid-exposure
        images:
          cam1: {center_uv_px: [u, v], visible: true, in_image: true, occluded_fraction: 0.0,
                 distance_m: 2.1}

``center_uv_px`` is the raw (distorted) pixel of the perspective projection of the sphere
centre at image time (what a perfect detector reports); null when behind the camera.
``visible`` = whole silhouette inside the image and at most 25 % of it hidden.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calib_core.io.yaml_safe import read_yaml_mapping

GT_FORMAT = "sonar-camera-ground-truth/1"
GT_FILE = "ground_truth.yaml"


def _mat(v):
    return None if v is None else np.asarray(v, dtype=float)


def load_ground_truth(session_root: str | Path) -> dict | None:
    """Read ``ground_truth.yaml`` of a session (None if there is none).

    Returns the mapping as written, with transforms (4x4) and centres (3,) and pixels (2,)
    converted to numpy arrays.
    """
    path = Path(session_root) / GT_FILE
    if not path.is_file():
        return None
    gt = read_yaml_mapping(path, "ground truth")
    for cam in (gt.get("cameras") or {}).values():
        cam["T_cam_sonar"] = _mat(cam.get("T_cam_sonar"))
    for k in list((gt.get("stereo") or {})):
        gt["stereo"][k] = _mat(gt["stereo"][k])
    for cap in (gt.get("captures") or {}).values():
        for k in ("center_sonar_m", "center_sonar_at_image_m"):
            cap[k] = _mat(cap.get(k))
        for im in (cap.get("images") or {}).values():
            im["center_uv_px"] = _mat(im.get("center_uv_px"))
    return gt


def to_list(a, nd: int = 10):
    """numpy -> nested lists of floats rounded to ``nd`` decimals (None passes through)."""
    if a is None:
        return None
    return np.round(np.asarray(a, dtype=float), nd).tolist()
