"""Intrinsics files: ROS camera_info YAML (plumb_bob, rational_polynomial, equidistant) and
OpenCV FileStorage YAML/XML."""

from __future__ import annotations

import re
import unicodedata
from pathlib import Path

import cv2
import numpy as np
import yaml

from calib_core.camera import CameraModel
from calib_core.errors import SessionError, short_repr
from calib_core.io.atomic import atomic_write_text
from calib_core.io.kalibr import camera_from_camchain, is_camchain
from calib_core.io.yaml_safe import parse_yaml_checked

MAX_INTRINSICS_BYTES = 1024 * 1024


def load_intrinsics(path: str | Path, camera: str | None = None, entry: str | None = None) -> CameraModel:
    """Read a ROS camera_info YAML, a Kalibr camchain or an OpenCV FileStorage file into a
    CameraModel. Of a camchain with several cameras: the ``entry`` key (cam0, ...), else the one
    whose camera_name or rostopic names ``camera`` (see :mod:`calib_core.io.kalibr`)."""
    path = Path(path)
    if not path.is_file():
        raise SessionError(path, "intrinsics file not found")
    try:
        size = path.stat().st_size
        if size > MAX_INTRINSICS_BYTES:
            raise SessionError(path, f"intrinsics file is {size / 1e6:.1f} MB: an intrinsics file is a few kB")
        raw = path.read_bytes()
    except OSError as e:
        raise SessionError(path, f"cannot read intrinsics file: {e.strerror or type(e).__name__}") from None
    if not raw.strip():
        raise SessionError(path, "intrinsics file is empty")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise SessionError(path, "not a text file (invalid UTF-8): expected ROS camera_info YAML") from None
    head = text.lstrip()
    if head.startswith("%YAML:") or "!!opencv-matrix" in text or head.startswith("<?xml"):
        check_storage_depth(path, text)  # OpenCV's parsers recurse on the C stack: a deep file crashes them
        return _load_opencv_storage(path)
    data = parse_yaml_checked(path, text)
    if not isinstance(data, dict):
        raise SessionError(path, "expected a ROS camera_info mapping (image_width, camera_matrix, ...)")
    if is_camchain(data):
        cam = camera_from_camchain(path, data, camera, entry)
        _check_K_values(path, cam.K, cam.width_px, cam.height_px)
        check_distortion(path, np.asarray(cam.dist, float))
        return cam
    if entry is not None:
        raise SessionError(path, f"intrinsics_entry {short_repr(entry)} is given, but this is not a Kalibr camchain "
                                 "(cam0: {intrinsics: ...}); leave intrinsics_entry out for a ROS camera_info file")
    return _from_ros(path, data)


def _matrix(path: Path, data: dict, key: str, size: int | tuple[int, ...]) -> np.ndarray:
    node = data.get(key)
    if node is None:
        raise SessionError(path, f"missing '{key}'")
    vals = node.get("data") if isinstance(node, dict) else node
    try:
        arr = np.asarray(vals, dtype=float).ravel()
    except (TypeError, ValueError, OverflowError, RecursionError):
        raise SessionError(path, f"'{key}' must be a list of numbers") from None
    sizes = (size,) if isinstance(size, int) else size
    if arr.size not in sizes:
        raise SessionError(path, f"'{key}' has {arr.size} values, expected {' or '.join(map(str, sizes))}")
    if not np.isfinite(arr).all():
        raise SessionError(path, f"'{key}' holds NaN or infinite values")
    return arr


def _check_K(path: Path, K: np.ndarray, w: int, h: int) -> None:
    if K[0, 0] <= 0 or K[1, 1] <= 0:
        raise SessionError(path, f"focal lengths must be positive (fx={K[0, 0]}, fy={K[1, 1]})")
    if abs(K[2, 2] - 1) > 1e-9 or abs(K[1, 0]) > 1e-9 or abs(K[2, 0]) > 1e-9 or abs(K[2, 1]) > 1e-9:
        raise SessionError(path, "camera_matrix must be [fx, s, cx, 0, fy, cy, 0, 0, 1]")
    if not (0 < w <= 100_000 and 0 < h <= 100_000):
        raise SessionError(path, f"image size {w} x {h} is not plausible (1 to 100000 pixels a side)")
    _check_K_values(path, K, w, h)


# finite but absurd values (fx 1e308 or 1e-300, cx 1e308, distortion 1e308) ran the detectors on
# nonsense ("no round outline" everywhere) with numpy overflow warnings on stderr
MAX_FOCAL_PER_SIDE = 1000.0  # fx up to 1000 image widths: a field of view of 0.06 degrees
MAX_ABS_DISTORTION = 1e4


def _check_K_values(path: Path, K: np.ndarray, w: int, h: int) -> None:
    fx, fy, s, cx, cy = K[0, 0], K[1, 1], K[0, 1], K[0, 2], K[1, 2]
    side = max(w, h)
    if not (1.0 <= fx <= MAX_FOCAL_PER_SIDE * side and 1.0 <= fy <= MAX_FOCAL_PER_SIDE * side):
        raise SessionError(path, f"focal lengths fx={fx:.6g}, fy={fy:.6g} px are not plausible for a {w} x {h} image "
                                 f"(1 to {MAX_FOCAL_PER_SIDE * side:.0f} px)")
    if not (-w <= cx <= 2 * w and -h <= cy <= 2 * h):
        raise SessionError(path, f"principal point ({cx:.6g}, {cy:.6g}) px is far outside the {w} x {h} image")
    if abs(s) > max(fx, fy):
        raise SessionError(path, f"skew {s:.6g} is not plausible (cameras have about 0)")


def check_distortion(path: Path, dist: np.ndarray) -> None:
    """Distortion coefficients of a plausible size (see MAX_ABS_DISTORTION)."""
    if np.abs(dist).max(initial=0.0) > MAX_ABS_DISTORTION:
        raise SessionError(path, f"distortion coefficients up to {np.abs(dist).max():.6g} are not plausible "
                                 f"(at most {MAX_ABS_DISTORTION:.0e})")


def _camera_name(path: Path, value) -> str:
    """camera_name: short text (a number is accepted as its text); never str() of a tree."""
    if value is None or value == "":
        return path.stem
    if isinstance(value, bool) or not isinstance(value, (str, int, float)):
        raise SessionError(path, f"camera_name must be text, got a {type(value).__name__}")
    text = value if isinstance(value, str) else repr(value)
    if len(text) > 200 or any(unicodedata.category(ch) in ("Cc", "Cf") for ch in text):
        raise SessionError(path, "camera_name must be one line of at most 200 characters (no control characters)")
    return text


def _from_ros(path: Path, data: dict) -> CameraModel:
    try:
        w, h = int(data["image_width"]), int(data["image_height"])
    except KeyError as e:
        raise SessionError(path, f"missing '{e.args[0]}'") from None
    except (TypeError, ValueError, OverflowError):
        raise SessionError(path, "image_width and image_height must be whole numbers") from None
    if isinstance(data["image_width"], (bool, float)) and data["image_width"] != w or \
            isinstance(data["image_height"], (bool, float)) and data["image_height"] != h:
        raise SessionError(path, "image_width and image_height must be whole numbers")
    K = _matrix(path, data, "camera_matrix", 9).reshape(3, 3)
    model = data.get("distortion_model", "plumb_bob")
    if model not in ("plumb_bob", "rational_polynomial", "equidistant", "fisheye", "", None):
        raise SessionError(path, f"distortion_model {short_repr(model)} is not supported "
                                 "(use plumb_bob, rational_polynomial or equidistant)")
    dist = _matrix(path, data, "distortion_coefficients", (4, 5, 8)) if "distortion_coefficients" in data else np.zeros(5)
    check_distortion(path, dist)
    if model in ("equidistant", "fisheye"):
        _check_K(path, K, w, h)
        if dist.size != 4 and np.any(dist[4:] != 0):
            raise SessionError(path, f"equidistant (fisheye) distortion has 4 coefficients k1..k4, "
                                     f"but {dist.size} are given and values 5-{dist.size} are not zero")
        return CameraModel(w, h, K, dist[:4], name=_camera_name(path, data.get("camera_name")), fisheye=True)
    if dist.size == 8 and model == "plumb_bob" and np.any(dist[5:] != 0):
        raise SessionError(path, "plumb_bob distortion has 5 coefficients, but k4..k6 (values 6-8) are not zero: "
                                 "write distortion_model: rational_polynomial")
    _check_K(path, K, w, h)
    return CameraModel(w, h, K, dist, name=_camera_name(path, data.get("camera_name")))


MAX_STORAGE_DEPTH = 32
_XML_TAG = re.compile(r"<(/?)[A-Za-z_][^<>]*?(/?)>")


def check_storage_depth(path: Path, text: str) -> None:
    """Refuse an OpenCV FileStorage text nested deeper than MAX_STORAGE_DEPTH (XML tags, or
    YAML flow brackets plus block indentation and '- ' markers), before OpenCV parses it."""
    depth = 0
    if text.lstrip().startswith("<"):
        for m in _XML_TAG.finditer(text):
            if m.group(2):
                continue  # <empty/>
            depth += -1 if m.group(1) else 1
            if depth > MAX_STORAGE_DEPTH:
                break
    else:
        flow, indents = 0, []
        for line in text.splitlines():
            body = line.lstrip(" ")
            if not body or body.startswith("#"):
                continue
            indent = len(line) - len(body)
            while indents and indents[-1] >= indent:
                indents.pop()
            indents.append(indent)
            dashes = len(re.match(r"(-\s+)*", body).group(0).split("-")) - 1
            for ch in body:
                flow += 1 if ch in "[{" else -1 if ch in "]}" else 0
                depth = max(depth, flow + len(indents) + dashes)
            depth = max(depth, len(indents) + dashes)
            if depth > MAX_STORAGE_DEPTH:
                break
    if depth > MAX_STORAGE_DEPTH:
        raise SessionError(path, f"cannot parse OpenCV FileStorage file: nested more than {MAX_STORAGE_DEPTH} levels deep")


def _load_opencv_storage(path: Path) -> CameraModel:
    try:
        return _read_opencv_storage(path)
    except (cv2.error, SystemError) as e:  # OpenCV's parser throws on malformed files
        msg = str(e).strip().splitlines()[-1] if isinstance(e, cv2.error) and str(e).strip() else "parse error"
        raise SessionError(path, f"cannot parse OpenCV FileStorage file ({msg})") from None
    except (TypeError, ValueError, OverflowError, AttributeError):
        raise SessionError(path, "OpenCV FileStorage file holds values of the wrong type") from None


def _read_opencv_storage(path: Path) -> CameraModel:
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    try:
        if not fs.isOpened():
            raise SessionError(path, "cannot parse OpenCV FileStorage file")

        def node(*names):
            for n in names:
                nd = fs.getNode(n)
                if not nd.empty():
                    return nd
            return None

        Kn = node("camera_matrix", "K", "cameraMatrix")
        if Kn is None:
            raise SessionError(path, "missing 'camera_matrix' (or K / cameraMatrix)")
        K = Kn.mat()
        if K is None or K.size != 9:
            raise SessionError(path, "camera_matrix must be a 3x3 matrix")
        K = K.reshape(3, 3).astype(float)
        dn = node("distortion_coefficients", "D", "dist_coeffs", "distCoeffs")
        dist = np.zeros(5) if dn is None else np.asarray(dn.mat(), float).ravel()
        if dist.size not in (4, 5, 8):
            raise SessionError(path, f"distortion has {dist.size} values, expected 4, 5 or 8")
        wn, hn = node("image_width", "width"), node("image_height", "height")
        if wn is None or hn is None:
            raise SessionError(path, "missing image_width / image_height")
        if not (wn.isInt() or wn.isReal()) or not (hn.isInt() or hn.isReal()):
            raise SessionError(path, "image_width and image_height must be numbers")
        w, h = int(wn.real()), int(hn.real())
        fn = node("fisheye_model")  # OpenCV's calibration sample writes it (1: cv::fisheye's k1..k4)
        fisheye = fn is not None and (fn.isInt() or fn.isReal()) and fn.real() != 0
    finally:
        fs.release()
    if not np.isfinite(K).all() or not np.isfinite(dist).all():
        raise SessionError(path, "camera matrix or distortion holds NaN or infinite values")
    _check_K(path, K, w, h)
    check_distortion(path, dist)
    if fisheye and dist.size != 4:
        raise SessionError(path, f"fisheye_model: 1 (OpenCV's fisheye model) has 4 distortion values, got {dist.size}")
    return CameraModel(w, h, K, dist, name=path.stem, fisheye=fisheye)


def camera_info_dict(cam: CameraModel, name: str | None = None) -> dict:
    """ROS camera_info dictionary (as written by ROS camera_calibration)."""
    P = np.hstack([cam.K, np.zeros((3, 1))])
    return {
        "image_width": int(cam.width_px),
        "image_height": int(cam.height_px),
        "camera_name": name or cam.name or "camera",
        "camera_matrix": {"rows": 3, "cols": 3, "data": [float(v) for v in cam.K.ravel()]},
        "distortion_model": cam.distortion_model,
        "distortion_coefficients": {"rows": 1, "cols": int(cam.dist.size), "data": [float(v) for v in cam.dist]},
        "rectification_matrix": {"rows": 3, "cols": 3, "data": [float(v) for v in np.eye(3).ravel()]},
        "projection_matrix": {"rows": 3, "cols": 4, "data": [float(v) for v in P.ravel()]},
    }


def save_intrinsics_ros(path: str | Path, cam: CameraModel, name: str | None = None) -> None:
    """Write ROS camera_info YAML atomically."""
    atomic_write_text(path, yaml.safe_dump(camera_info_dict(cam, name), sort_keys=False, default_flow_style=None))
