"""Shared test helpers: a tiny valid session on disk, a folder hash, and a CLI runner.

Reuse from any test:

    def test_x(make_session):
        root = make_session(tmp_path, n_captures=4, cameras=("cam1",))

or import the plain functions: ``from conftest import build_session, edit_yaml, tree_hash, run_cli``.
"""

from __future__ import annotations

import hashlib
import importlib
import os
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from calib_core.camera import CameraModel
from calib_core.geometry import transform_points
from calib_core.io.clouds import Cloud, save_cloud
from calib_core.io.images import save_image
from calib_core.io.intrinsics import save_intrinsics_ros

sys.path.insert(0, str(Path(__file__).resolve().parent / "browser"))  # the browser tests' helpers
pytest_plugins = ["chromium_fixtures"]  # one Chromium per run, a context per module (``browser``)

SPHERE_DIAMETER_M = 0.22


def tiny_camera(name: str = "cam1", width_px: int = 64, height_px: int = 48) -> CameraModel:
    """A small camera (about 65 x 50 deg field of view) with mild plumb_bob distortion."""
    f = 0.78 * width_px
    K = [[f, 0, (width_px - 1) / 2], [0, f, (height_px - 1) / 2], [0, 0, 1]]
    return CameraModel(width_px, height_px, K, [-0.05, 0.01, 0.0005, -0.0003, 0.0], name=name)


def _T_cam_sonar(i_cam: int) -> np.ndarray:
    """Cameras side by side 0.3 m apart, 0.1 m above the sonar, looking along the sonar's z."""
    T = np.eye(4)
    T[:3, 3] = [-0.3 * i_cam, 0.1, 0.0]
    return T


def _sphere_cloud(center_m: np.ndarray, radius_m: float, n_points: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """Front cap of a sphere (facing the sonar at the origin) plus a flat floor, with intensity."""
    n_sphere = n_points // 2
    d = rng.normal(size=(n_sphere * 3, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d = d[(d @ -center_m) > 0][:n_sphere]  # normals facing the sonar
    sphere = center_m + radius_m * d
    n_floor = n_points - len(sphere)
    floor = np.column_stack([rng.uniform(-1.5, 1.5, n_floor), np.full(n_floor, 1.2), rng.uniform(0.5, 4.0, n_floor)])
    pts = np.vstack([sphere, floor]) + rng.normal(scale=0.002, size=(n_points, 3))
    inten = np.concatenate([np.full(len(sphere), 200.0), np.full(n_floor, 40.0)])
    return pts, inten


def _render(cam: CameraModel, center_cam_m: np.ndarray, radius_m: float) -> np.ndarray:
    """Bright gradient background with a dark disc where the sphere projects (approximate silhouette)."""
    h, w = cam.height_px, cam.width_px
    v, u = np.mgrid[0:h, 0:w]
    img = np.empty((h, w, 3), np.uint8)
    img[...] = (170 + 60 * v / max(h - 1, 1))[..., None].astype(np.uint8)
    uv = cam.project(center_cam_m[None])[0]
    r_px = cam.fx * radius_m / center_cam_m[2]
    if np.isfinite(uv).all():
        img[(u - uv[0]) ** 2 + (v - uv[1]) ** 2 <= r_px**2] = (25, 30, 35)
    return img


def build_session(root: str | Path, n_captures: int = 4, cameras=("cam1",), *, folder: str = "session",
                  cloud_ext: str = ".ply", n_points: int = 300, image_ext: str = ".png", seed: int = 0,
                  width_px: int = 64, height_px: int = 48, background: bool = False,
                  detections: bool = False) -> Path:
    """Write a minimal valid session under ``root/folder`` and return that folder.

    Tiny images (64 x 48 by default) with a dark disc at the sphere's projection, small
    clouds (a sphere cap plus a floor), ROS intrinsics per camera, optionally a background
    folder per camera and a detections.yaml with one accepted sonar entry.
    """
    rng = np.random.default_rng(seed)
    sess = Path(root) / folder
    sess.mkdir(parents=True, exist_ok=True)
    radius = SPHERE_DIAMETER_M / 2
    cams = {name: tiny_camera(name, width_px, height_px) for name in cameras}
    manifest: dict = {
        "format": "sonar-camera-session/1",
        "name": "test-session",
        "sphere": {"diameter": SPHERE_DIAMETER_M},
        "sonar": {"model": "test sonar", "sound_speed": 1481.0},
        "cameras": {},
        "captures": [],
    }
    for name, cam in cams.items():
        save_intrinsics_ros(sess / "intrinsics" / f"{name}.yaml", cam, name)
        spec = {"intrinsics": f"intrinsics/{name}.yaml"}
        if background:
            bg = np.full((height_px, width_px, 3), 200, np.uint8)
            for k in range(2):
                save_image(sess / "backgrounds" / name / f"bg{k}.png", bg)
            spec["background"] = f"backgrounds/{name}/"
        manifest["cameras"][name] = spec
    for i in range(n_captures):
        cid = f"p{i + 1:02d}"
        center_sonar = np.array([0.4 * (i % 3 - 1), 0.1 * (i % 2), 1.6 + 0.2 * i])
        pts, inten = _sphere_cloud(center_sonar, radius, n_points, rng)
        save_cloud(sess / "clouds" / f"{cid}{cloud_ext}", Cloud(pts, inten))
        images = {}
        for j, (name, cam) in enumerate(cams.items()):
            c_cam = transform_points(_T_cam_sonar(j), center_sonar)[0]
            save_image(sess / "images" / name / f"{cid}{image_ext}", _render(cam, c_cam, radius))
            images[name] = f"images/{name}/{cid}{image_ext}"
        manifest["captures"].append({"id": cid, "cloud": f"clouds/{cid}{cloud_ext}", "images": images})
    (sess / "session.yaml").write_text(yaml.safe_dump(manifest, sort_keys=False))
    if detections:
        det = {"format": "sonar-camera-detections/1",
               "captures": {"p01": {"sonar": {"center": [-0.4, 0.0, 1.6], "status": "accepted"}}}}
        (sess / "detections.yaml").write_text(yaml.safe_dump(det, sort_keys=False))
    return sess


@pytest.fixture
def make_session():
    """The :func:`build_session` builder: ``make_session(tmp_path, n_captures=4, cameras=("cam1",))``."""
    return build_session


@pytest.fixture
def session_dir(tmp_path) -> Path:
    """A ready two-camera, four-capture session folder."""
    return build_session(tmp_path, n_captures=4, cameras=("cam1", "cam2"))


def edit_yaml(path: str | Path, fn) -> None:
    """Load the YAML file ``path``, let ``fn`` change the data in place, write it back
    (key order kept): ``edit_yaml(root / "session.yaml", lambda d: d.update(name="x"))``."""
    p = Path(path)
    d = yaml.safe_load(p.read_text())
    fn(d)
    p.write_text(yaml.safe_dump(d, sort_keys=False, allow_unicode=True))


def tree_hash(folder: str | Path) -> dict[str, str]:
    """{relative path: sha256 (files) or 'link:target' (symlinks) or 'dir'} of everything under folder."""
    folder = Path(folder)
    out = {}
    for dirpath, dirnames, filenames in os.walk(folder):
        for n in dirnames + filenames:
            p = Path(dirpath) / n
            rel = str(p.relative_to(folder))
            if p.is_symlink():
                out[rel] = "link:" + os.readlink(p)
            elif p.is_dir():
                out[rel] = "dir"
            else:
                out[rel] = _file_digest(p)
    return out


def _file_digest(p: Path) -> str:
    """sha256 of a file; for huge (e.g. sparse test) files: size, mtime and both ends."""
    st = p.stat()
    if st.st_size <= 64 * 2**20:
        return hashlib.sha256(p.read_bytes()).hexdigest()
    with open(p, "rb") as f:
        head = f.read(2**20)
        f.seek(-(2**20), os.SEEK_END)
        tail = f.read()
    return f"{st.st_size}:{st.st_mtime_ns}:" + hashlib.sha256(head + tail).hexdigest()


# ---- CLI ------------------------------------------------------------------
def cli_command_exists(name: str) -> bool:
    """True when ``sonarcal_cli/commands/<name>.py`` exists (for tests of commands still being written)."""
    try:
        from sonarcal_cli.main import command_module

        importlib.import_module(command_module(name))
    except ModuleNotFoundError as e:
        if e.name == command_module(name):
            return False
        raise
    return True


def run_cli(argv: list[str]) -> int:
    """``sonarcal ARGV`` in-process through the real entry point ``sonarcal_cli.main.main``."""
    from sonarcal_cli.main import main

    return main(argv)


VENV_SONARCAL = Path(__file__).resolve().parents[1] / ".venv" / "bin" / "sonarcal"


def review_session_with_decoy_taken(root) -> tuple:
    """Detections of a `review` preset session in which the capture with the look-alike decoy
    keeps what the image detector says on its own (it takes the fully visible decoy), as a
    session without the sonar's second look would; saved to detections.yaml with its
    fingerprint, so `calibrate`, `detect` and the workbench reuse it.

    The session flow (:func:`calib_core.pipeline.detect_session`) now finds the half-hidden
    target itself through the sonar's prediction, so the wrong detection the review tools must
    diagnose has to be put back. Returns (SessionData, detections, ground truth)."""
    from calib_core.detections import save_detections
    from calib_core.pipeline import SessionData, detect_image_entry, detect_session
    from calib_core.session import load_session

    data = SessionData(load_session(root))
    gt = yaml.safe_load((Path(root) / "ground_truth.yaml").read_text())
    dets = detect_session(data, {})
    hidden = next(c for c, v in gt["captures"].items() if v["images"]["cam1"].get("occluded_fraction", 0) > 0.3)
    raw = detect_image_entry(data, hidden, "cam1")
    true_uv = gt["captures"][hidden]["images"]["cam1"]["center_uv_px"]
    assert raw.get("center") is not None and np.hypot(*np.subtract(raw["center"], true_uv)) > 20, \
        "the image detector alone no longer takes the decoy: the review scenario needs another wrong detection"
    dets[hidden]["cam1"] = raw
    save_detections(data.session, dets)
    return data, dets, gt
