"""Frames of a capture whose sphere drifts during the scan (the ``drift`` preset).

The scan sees the sphere at the capture's centre; the cameras record ``n_frames`` frames
during the scan while the sphere moves ``drift_m`` in a straight horizontal line through
that centre (the middle frame has it at the centre). Frames go to
``frames/<cam>/<id>_<j>.jpg``; the truth (positions, pixels) is returned for ground_truth.yaml.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calib_core.geometry import invert_T, transform_points
from calib_core.io.images import save_image
from calib_core.synth.camera_render import finish_image, render_radiance

N_FRAMES = 5


def drift_positions(rng, center_world: np.ndarray, drift_m: float, n: int = N_FRAMES) -> np.ndarray:
    """(n,3) sphere centres along a random horizontal line, ``drift_m`` long, centred on the capture."""
    a = rng.uniform(0, 2 * np.pi)
    direction = np.array([np.cos(a), np.sin(a), 0.0])
    f = np.linspace(-0.5, 0.5, n)
    return center_world[None] + f[:, None] * drift_m * direction[None]


def write_drift_frames(out: Path, cid: str, rig, scene_for, centers_world: np.ndarray, water, opts, rng,
                       jpeg_quality: int) -> dict:
    """Render and save the frames; ``scene_for(center_world)`` builds the scene with the sphere there."""
    truth = {"drift_m": float(np.linalg.norm(centers_world[-1] - centers_world[0])), "frames": {}}
    for cam_name, (cam, T_wc) in rig.cams.items():
        uv = []
        for j, c in enumerate(centers_world):
            L, _ = render_radiance(scene_for(c), cam, T_wc, water, aa=opts.aa)
            save_image(out / "frames" / cam_name / f"{cid}_{j}.jpg", finish_image(L, opts, rng),
                       jpeg_quality=jpeg_quality)
            C = transform_points(invert_T(T_wc), c[None])[0]
            uv.append([float(v) for v in cam.project(C[None])[0]])
        truth["frames"][cam_name] = {"center_uv_px": uv}
    truth["centers_world_m"] = [[float(v) for v in c] for c in centers_world]
    return truth
