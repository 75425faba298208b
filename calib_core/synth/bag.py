"""Write a (synthetic) session folder as a ROS bag recorded the way a field rig records it.

Timeline: ``BACKGROUND_S`` seconds of sphere-free camera frames (the session's background
frames), then one sonar scan per capture, ``scan_s`` long, separated by ``gap_s``. Each scan's
cloud is cut by pan angle (the sonar pans about its z axis) into ``n_slices`` PointCloud2
messages spread over the scan; each camera publishes ``frames_per_scan`` frames during it
(the capture's still mid-scan and copies of it with fresh sensor noise around it, or, where the session holds
``frames/<cam>/<id>_<j>.<ext>``, those frames: the drifting target of the ``drift`` preset)
and a CameraInfo with each frame.

Topics: ``/sonar/points``, ``/<cam>/image_raw`` (or ``/<cam>/image_raw/compressed``),
``/<cam>/camera_info`` (frame id: the camera's name), and ``/tf_static`` with the session's
stereo transform when it has one.
"""

from __future__ import annotations

import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calib_core.ingest import rosmsg
from calib_core.ingest.bagwrite import BagWriter
from calib_core.io.clouds import load_cloud
from calib_core.io.images import list_frames, load_image
from calib_core.session import load_session

NS = 1_000_000_000
BACKGROUND_S = 2.0
SONAR_TOPIC = "/sonar/points"


@dataclass(frozen=True)
class BagTimeline:
    """Recording timeline of a synthetic bag (seconds from the bag's start)."""

    scan_s: float = 60.0
    gap_s: float = 8.0
    first_scan_s: float = 5.0
    n_slices: int = 60
    frames_per_scan: int = 5
    frame_noise_dn: float = 1.5
    compressed: bool = False

    def scan_window(self, k: int) -> tuple[float, float]:
        t0 = self.first_scan_s + k * (self.scan_s + self.gap_s)
        return t0, t0 + self.scan_s


def image_topic(cam: str, compressed: bool) -> str:
    return f"/{cam}/image_raw" + ("/compressed" if compressed else "")


def write_session_bag(session_dir, out_path, kind: str = "ros2", timeline: BagTimeline = BagTimeline(),
                      seed: int = 0, progress=None) -> Path:
    """Write session ``session_dir`` as a bag at ``out_path`` (which must not exist).

    The bag is written inside a temporary folder beside ``out_path`` and renamed into place.
    """
    out = Path(out_path).absolute()
    if out.exists():
        raise FileExistsError(f"{out} exists already")
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.writing-", dir=out.parent))
    try:
        _write(session_dir, tmp / out.name, kind, timeline, seed, progress)
        (tmp / out.name).rename(out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out


def _write(session_dir, out_path: Path, kind: str, timeline: BagTimeline, seed: int, progress) -> None:
    s = load_session(session_dir)
    rng = np.random.default_rng(seed)
    cams = {c: s.camera_model(c) for c in s.cameras}
    total = len(s.captures) + 1
    with BagWriter(out_path, kind) as w:
        _write_tf_static(w, s)
        _write_backgrounds(w, s, cams, timeline)
        if progress:
            progress(1, total, "backgrounds")
        for k, cap in enumerate(s.captures):
            t0, t1 = timeline.scan_window(k)
            _write_scan(w, load_cloud(cap.cloud_path), t0, t1, timeline.n_slices)
            for cam, path in cap.image_paths.items():
                frames = _frames_for(s.root, cam, cap.id, path, timeline.frames_per_scan)
                repeated = all(f is frames[0] for f in frames)
                for j, img in enumerate(frames):
                    t = t0 + (j + 0.5) / len(frames) * (t1 - t0)
                    # the still is the frame recorded mid-scan; the others are repeats with fresh noise
                    noisy = repeated and j != len(frames) // 2
                    frame = _noisy(img, rng, timeline.frame_noise_dn) if noisy else img
                    _write_frame(w, cam, cams[cam], int(t * NS), frame, timeline.compressed)
            if progress:
                progress(k + 2, total, cap.id)


def _write_tf_static(w: BagWriter, s) -> None:
    """The session's stereo transforms as /tf_static (parent = target camera's frame)."""
    from calib_core.ingest.tf import tf_static_msg

    for key, T in s.stereo.items():
        target, source = _stereo_names(key, s.cameras)
        if target is None:
            continue
        msg = tf_static_msg(w.typestore, 0, target, source, np.asarray(T, float), w.ros1)
        w.write("/tf_static", rosmsg.TF_STATIC, 1, msg)


def _stereo_names(key: str, cameras) -> tuple[str | None, str | None]:
    for a in cameras:
        for b in cameras:
            if a != b and key == f"T_{a}_{b}":
                return a, b
    return None, None


def _write_backgrounds(w: BagWriter, s, cams, tl: BagTimeline) -> None:
    for cam, spec in s.cameras.items():
        if spec.background_path is None or not spec.background_path.is_dir():
            continue
        paths = list_frames(spec.background_path)
        for j, p in enumerate(paths):
            t = (j + 0.5) / len(paths) * BACKGROUND_S
            _write_frame(w, cam, cams[cam], int(t * NS), load_image(p), tl.compressed)


def _write_scan(w: BagWriter, cloud, t0: float, t1: float, n_slices: int) -> None:
    pts, inten = cloud.points_m, cloud.intensity
    az = np.arctan2(pts[:, 1], pts[:, 0])
    order = np.argsort(-az, kind="stable")  # pan from left (+y) to right
    for i, idx in enumerate(np.array_split(order, n_slices)):
        t = t0 + (i + 0.5) / n_slices * (t1 - t0)
        msg = rosmsg.cloud_msg(w.typestore, int(t * NS), "sonar", pts[idx],
                               None if inten is None else inten[idx], w.ros1)
        w.write(SONAR_TOPIC, rosmsg.POINTCLOUD2, int(t * NS), msg)


def _write_frame(w: BagWriter, cam: str, model, t_ns: int, img: np.ndarray, compressed: bool) -> None:
    ts = w.typestore
    if compressed:
        w.write(image_topic(cam, True), rosmsg.COMPRESSED, t_ns, rosmsg.compressed_msg(ts, t_ns, cam, img, w.ros1))
    else:
        w.write(image_topic(cam, False), rosmsg.IMAGE, t_ns, rosmsg.image_msg(ts, t_ns, cam, img, w.ros1))
    w.write(f"/{cam}/camera_info", rosmsg.CAMERA_INFO, t_ns, rosmsg.info_msg(ts, t_ns, cam, model, w.ros1))


def _frames_for(root: Path, cam: str, cid: str, still: Path, n: int) -> list[np.ndarray]:
    """The capture's recorded frames if the session has them, else its still ``n`` times."""
    folder = root / "frames" / cam
    if folder.is_dir():
        own = sorted(p for p in folder.iterdir() if p.stem.rsplit("_", 1)[0] == cid)
        if own:
            return [load_image(p) for p in own]
    img = load_image(still)
    return [img] * n


def _noisy(img: np.ndarray, rng, sigma_dn: float) -> np.ndarray:
    if sigma_dn <= 0:
        return img
    return np.clip(img + rng.normal(0, sigma_dn, img.shape), 0, 255).astype(np.uint8)
