"""Camera intrinsics and stereo transforms from planar checkerboard images (OpenCV).

``pattern`` is the number of *inner* corners (columns, rows), e.g. (9, 6); ``square_m`` the
square size in metres. Corners: ``findChessboardCorners`` then ``cornerSubPix``. Intrinsics:
``calibrateCameraExtended`` (plumb_bob; k3 held at 0 unless asked, as ROS does). Stereo:
``stereoCalibrateExtended`` with both intrinsics fixed, giving ``T_cam2_cam1`` (maps cam1-frame
points to cam2). Its covariance is approximated from the spread of the per-pair relative
poses (each pair's two single-view PnP poses chained) divided by the number of pairs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from calib_core.camera import CameraModel
from calib_core.errors import SessionError
from calib_core.geometry import T_from_rotvec, invert_T, make_T
from calib_core.solve.model import log_so3


def parse_pattern(text: str) -> tuple[int, int]:
    """'9x6' -> (9, 6) inner corners; raises SessionError on anything else."""
    try:
        c, r = (int(v) for v in str(text).lower().split("x"))
    except ValueError:
        raise SessionError(None, f"pattern '{text}' must be COLSxROWS inner corners, e.g. 9x6") from None
    if c < 2 or r < 2:
        raise SessionError(None, f"pattern '{text}' needs at least 2x2 inner corners")
    return c, r


def board_points(pattern: tuple[int, int], square_m: float) -> np.ndarray:
    """(cols*rows, 3) board-frame corner coordinates (m), row by row, z = 0."""
    c, r = pattern
    g = np.mgrid[0:c, 0:r].T.reshape(-1, 2).astype(np.float64)
    return np.column_stack([g * square_m, np.zeros(len(g))])


def find_corners(image_rgb: np.ndarray, pattern: tuple[int, int]) -> np.ndarray | None:
    """Sub-pixel inner corners (N,2) in raw pixels, or None when the board is not found whole."""
    grey = cv2.cvtColor(image_rgb, cv2.COLOR_RGB2GRAY) if image_rgb.ndim == 3 else image_rgb
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    ok, corners = cv2.findChessboardCorners(grey, pattern, flags=flags)
    if not ok:
        return None
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4)
    corners = cv2.cornerSubPix(grey, corners.astype(np.float32), (5, 5), (-1, -1), crit)
    return corners.reshape(-1, 2).astype(np.float64)


@dataclass
class IntrinsicsResult:
    """Outcome of :func:`calibrate_intrinsics`.

    Attributes:
        cam: the calibrated CameraModel. rms_px: overall reprojection RMS.
        per_image_rms_px: {image name: RMS px} of the images used.
        skipped: {image name: reason}. sigma: 1-sigma of fx, fy, cx, cy, k1, k2, p1, p2, k3.
        poses: {image name: T_cam_board}. corners: {image name: (N,2) px}.
    """

    cam: CameraModel
    rms_px: float
    per_image_rms_px: dict
    skipped: dict
    sigma: dict = field(default_factory=dict)
    poses: dict = field(default_factory=dict)
    corners: dict = field(default_factory=dict)


def _detect_all(images, pattern, progress, what):
    found, skipped, size = {}, {}, None
    for i, (name, img) in enumerate(images):
        if progress:
            progress(i, len(images), f"{what} {name}")
        h, w = img.shape[:2]
        if size is None:
            size = (w, h)
        elif (w, h) != size:
            skipped[name] = f"image is {w} x {h}, the others {size[0]} x {size[1]}"
            continue
        c = find_corners(img, pattern)
        if c is None:
            skipped[name] = f"no complete {pattern[0]}x{pattern[1]} checkerboard found"
        else:
            found[name] = c
    if progress:
        progress(len(images), len(images), f"{what} done")
    return found, skipped, size


def calibrate_intrinsics(images: list[tuple[str, np.ndarray]], pattern: tuple[int, int], square_m: float,
                         name: str = "camera", fix_k3: bool = True, progress=None) -> IntrinsicsResult:
    """Intrinsics of one camera from ``[(name, RGB image)]`` checkerboard views."""
    if not square_m > 0:
        raise SessionError(None, f"square size must be positive metres, got {square_m}")
    found, skipped, size = _detect_all(images, pattern, progress, "corners")
    if len(found) < 3:
        raise SessionError(None, f"a checkerboard was found in only {len(found)} of {len(images)} images; at least "
                                 f"3 (better 15+, tilted and spread over the view) are needed. Is the pattern "
                                 f"{pattern[0]}x{pattern[1]} inner corners?")
    names = list(found)
    obj = [board_points(pattern, square_m).astype(np.float32) for _ in names]
    img = [found[n].astype(np.float32).reshape(-1, 1, 2) for n in names]
    flags = cv2.CALIB_FIX_K3 if fix_k3 else 0
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-12)
    rms, K, dist, rvecs, tvecs, std_in, _, per_view = cv2.calibrateCameraExtended(obj, img, size, None, None,
                                                                                  flags=flags, criteria=crit)
    cam = CameraModel(size[0], size[1], K, np.asarray(dist).ravel()[:5], name)
    std = np.asarray(std_in).ravel()
    keys = ["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"]
    poses = {n: T_from_rotvec(np.ravel(rv), np.ravel(tv)) for n, rv, tv in zip(names, rvecs, tvecs)}
    return IntrinsicsResult(cam, float(rms), {n: float(e) for n, e in zip(names, np.ravel(per_view))}, skipped,
                            {k: float(v) for k, v in zip(keys, std[:9])}, poses, found)


@dataclass
class StereoResult:
    """Outcome of :func:`calibrate_stereo`.

    Attributes:
        T_cam2_cam1: 4x4 (maps camera-1 points to camera 2). cov: 6x6 approximate covariance
            (rotation vector rad, translation m). rms_px: stereo reprojection RMS.
        per_pair_rms_px: {pair name: RMS px}. skipped: {pair name: reason}.
    """

    T_cam2_cam1: np.ndarray
    cov: np.ndarray
    rms_px: float
    per_pair_rms_px: dict
    skipped: dict


def calibrate_stereo(pairs: list[tuple[str, np.ndarray, np.ndarray]], cam1: CameraModel, cam2: CameraModel,
                     pattern: tuple[int, int], square_m: float, progress=None) -> StereoResult:
    """``T_cam2_cam1`` from ``[(name, image1, image2)]`` simultaneous checkerboard views, intrinsics fixed."""
    for cam, which in ((cam1, 1), (cam2, 2)):
        if cam.fisheye:
            raise SessionError(None, f"camera {which} has fisheye (equidistant) intrinsics: the checkerboard stereo "
                                     "calibration supports plumb_bob and rational_polynomial only; give the stereo "
                                     "transform in session.yaml (e.g. from Kalibr) instead")
    found1, skip1, size1 = _detect_all([(n, a) for n, a, _ in pairs], pattern, progress, "camera 1 corners")
    found2, skip2, size2 = _detect_all([(n, b) for n, _, b in pairs], pattern, progress, "camera 2 corners")
    for cam, size, which in ((cam1, size1, 1), (cam2, size2, 2)):
        if size is not None and size != (cam.width_px, cam.height_px):
            raise SessionError(None, f"camera {which} images are {size[0]} x {size[1]} but its intrinsics say "
                                     f"{cam.width_px} x {cam.height_px}")
    skipped = {n: f"camera 1: {r}" for n, r in skip1.items()}
    skipped.update({n: f"camera 2: {r}" for n, r in skip2.items() if n not in skipped})
    names = [n for n, _, _ in pairs if n in found1 and n in found2]
    if len(names) < 3:
        raise SessionError(None, f"the checkerboard was seen whole by both cameras in only {len(names)} pairs; at least "
                                 f"3 (better 10+) are needed")
    obj_pts = board_points(pattern, square_m)
    obj = [obj_pts.astype(np.float32) for _ in names]
    p1 = [found1[n].astype(np.float32).reshape(-1, 1, 2) for n in names]
    p2 = [found2[n].astype(np.float32).reshape(-1, 1, 2) for n in names]
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-12)
    out = cv2.stereoCalibrateExtended(obj, p1, p2, cam1.K, cam1.dist, cam2.K, cam2.dist,
                                      (cam1.width_px, cam1.height_px), None, None,
                                      flags=cv2.CALIB_FIX_INTRINSIC, criteria=crit)
    rms, R, T, per_view = out[0], out[5], out[6], out[-1]
    T21 = make_T(R, np.ravel(T))
    rel = []
    for n in names:
        ok1, r1, t1 = cv2.solvePnP(obj_pts, found1[n], cam1.K, cam1.dist)
        ok2, r2, t2 = cv2.solvePnP(obj_pts, found2[n], cam2.K, cam2.dist)
        if ok1 and ok2:
            Tn = T_from_rotvec(r2.ravel(), t2.ravel()) @ invert_T(T_from_rotvec(r1.ravel(), t1.ravel()))
            rel.append(np.concatenate([log_so3(Tn[:3, :3] @ R.T), Tn[:3, 3] - np.ravel(T)]))
    rel = np.array(rel)
    # Approximation: per-pair relative poses treated as independent, equally good estimates.
    cov = np.cov(rel.T) / len(rel) if len(rel) >= 3 else np.diag([math.radians(0.1) ** 2] * 3 + [0.002**2] * 3)
    errs = np.asarray(per_view).reshape(len(names), -1)
    per_pair = {n: float(np.sqrt(np.mean(e**2))) for n, e in zip(names, errs)}
    return StereoResult(T21, cov, float(rms), per_pair, skipped)


def folder_images(folder: str | Path) -> list[tuple[str, Path]]:
    """(file stem, path) of the image files in a folder, sorted; SessionError when there are none."""
    from calib_core.io.images import list_frames

    folder = Path(folder)
    if not folder.is_dir():
        raise SessionError(folder, "checkerboard image folder not found")
    frames = [p for p in list_frames(folder) if p.is_file()]
    if not frames:
        raise SessionError(folder, "no image files (.png .jpg .bmp .tif) in this folder")
    return [(p.stem, p) for p in frames]


def pair_folders(folder1: str | Path, folder2: str | Path) -> list[tuple[str, Path, Path]]:
    """Pair two cameras' checkerboard images by file name (or by order when names differ)."""
    a, b = folder_images(folder1), folder_images(folder2)
    db = dict(b)
    common = [n for n, _ in a if n in db]
    if common:
        return [(n, p, db[n]) for n, p in a if n in db]
    if len(a) != len(b):
        raise SessionError(Path(folder2), f"cannot pair images: no common file names and {len(a)} vs {len(b)} files")
    return [(f"{na}|{nb}", pa, pb) for (na, pa), (nb, pb) in zip(a, b)]
