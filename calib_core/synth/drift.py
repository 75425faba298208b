"""Frames of a capture whose sphere drifts during the scan (the ``drift`` preset).

The scan sees the sphere at the capture's centre; the cameras record ``n_frames`` frames
during the scan while the sphere moves ``drift_m`` in a straight horizontal line through
that centre (the middle frame has it at the centre: it is the capture's still), across the first camera's line of sight
(a drift along it moves the image centre little: a check of the image track could not see it).
The line is fixed by the geometry and its sense by a random stream of its own, so a change to
how many random numbers the rest of the capture draws (the sonar simulator's) does not turn it. Frames go to
``frames/<cam>/<id>_<j>.jpg``; the truth (positions, pixels) is returned for ground_truth.yaml.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from calib_core.geometry import invert_T, transform_points
from calib_core.io.images import save_image
from calib_core.synth.camera_render import finish_image, render_radiance

N_FRAMES = 5


def drift_positions(rng, center_world: np.ndarray, drift_m: float, eye_world: np.ndarray,
                    n: int = N_FRAMES) -> np.ndarray:
    """(n,3) sphere centres along a horizontal line ``drift_m`` long, centred on the capture and
    square to the horizontal line of sight from ``eye_world`` (its sense drawn from ``rng``)."""
    sight = np.asarray(center_world, float) - np.asarray(eye_world, float)
    across = np.array([-sight[1], sight[0], 0.0])
    if np.linalg.norm(across) < 1e-9:  # looking straight down: any horizontal line is across
        across = np.array([1.0, 0.0, 0.0])
    direction = across / np.linalg.norm(across) * (1.0 if rng.uniform() < 0.5 else -1.0)
    f = np.linspace(-0.5, 0.5, n)
    return center_world[None] + f[:, None] * drift_m * direction[None]


def write_drift_frames(out: Path, cid: str, rig, scene_for, centers_world: np.ndarray, water, opts, rng,
                       jpeg_quality: int, stills: dict[str, str] | None = None) -> dict:
    """Render and save the frames; ``scene_for(center_world)`` builds the scene with the sphere there.
    The middle frame of a camera with a still in ``stills`` (camera -> path relative to ``out``, the
    capture's image, rendered from the same scene with the sphere at the centre) is that still's
    file: the frame recorded mid-scan is the capture's image, as in every other capture of a bag
    written from the session, so a bag holds the same data as the folder."""
    truth = {"drift_m": float(np.linalg.norm(centers_world[-1] - centers_world[0])), "frames": {}}
    mid = len(centers_world) // 2
    for cam_name, (cam, T_wc) in rig.cams.items():
        uv = []
        for j, c in enumerate(centers_world):
            dst = out / "frames" / cam_name / f"{cid}_{j}.jpg"
            if j == mid and stills and cam_name in stills:
                dst.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(out / stills[cam_name], dst.with_suffix(Path(stills[cam_name]).suffix))
            else:
                L, _ = render_radiance(scene_for(c), cam, T_wc, water, aa=opts.aa)
                save_image(dst, finish_image(L, opts, rng), jpeg_quality=jpeg_quality)
            C = transform_points(invert_T(T_wc), c[None])[0]
            uv.append([float(v) for v in cam.project(C[None])[0]])
        truth["frames"][cam_name] = {"center_uv_px": uv}
    truth["centers_world_m"] = [[float(v) for v in c] for c in centers_world]
    return truth
