"""Images and background videos (OpenCV). Images are returned as RGB uint8 (H,W,3)."""

from __future__ import annotations

import struct
from pathlib import Path

import cv2
import numpy as np

from calib_core import MAX_IMAGE_PIXELS  # 7680 x 5120; also OpenCV's own cap (set in calib_core/__init__)
from calib_core.errors import SessionError

MAX_IMAGE_BYTES = 200 * 2**20
MAX_DECODED_BYTES = 250_000_000  # the decoded array; an 8-bit RGB camera frame of 40 MP is 120 MB
MAX_BACKGROUND_FILES = 100  # a background folder is sampled evenly down to this many frames
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".m4v")


def read_image_header(path: str | Path) -> tuple[int, int]:
    """(width, height) from the image file's header, without decoding the pixels.

    Every format OpenCV would decode here (PNG, JPEG, BMP, TIFF, WebP ...) is identified by
    PIL, which reads only the header. A file PIL cannot identify, or whose header claims
    more than MAX_IMAGE_PIXELS, is refused.
    """
    from PIL import Image, UnidentifiedImageError

    path = Path(path)
    try:
        with Image.open(path) as im:
            w, h = im.size
            sample_bytes = _decoded_bytes_per_pixel(im.mode)
            if im.format == "PNG" and _png_bit_depth(path) == 16:
                sample_bytes = max(sample_bytes, 8)  # OpenCV keeps 16 bits: up to 4 channels of 2 bytes
    except Image.DecompressionBombError:
        raise SessionError(path, "image header claims too many pixels to be a camera frame") from None
    except (UnidentifiedImageError, SyntaxError, ValueError, TypeError, EOFError, struct.error, OSError,
            IndexError, KeyError, ZeroDivisionError, OverflowError, MemoryError):
        wh = _tiff_size(path)  # PIL does not open every TIFF OpenCV does (e.g. 3-channel float)
        if wh is None:
            raise SessionError(path, "cannot decode image (its header is unreadable: corrupt, truncated or not an image)") from None
        w, h = wh
        sample_bytes = 16  # a TIFF PIL cannot open: assume up to 4 float channels
    if w <= 0 or h <= 0:
        raise SessionError(path, f"image header claims {w} x {h} pixels")
    if w * h > MAX_IMAGE_PIXELS:
        raise SessionError(path, f"image header claims {w} x {h} pixels: more than the {MAX_IMAGE_PIXELS // 10**6} "
                                 "megapixels of a camera frame")
    if w * h * sample_bytes > MAX_DECODED_BYTES:
        raise SessionError(path, f"image of {w} x {h} pixels in this pixel format decodes to "
                                 f"{w * h * sample_bytes / 1e6:.0f} MB: more than the {MAX_DECODED_BYTES / 1e6:.0f} MB "
                                 "allowed (use 8-bit images)")
    return int(w), int(h)


def _png_bit_depth(path: Path) -> int:
    with open(path, "rb") as f:
        head = f.read(26)
    return head[24] if len(head) >= 25 else 8


def _decoded_bytes_per_pixel(mode: str) -> int:
    """Bytes per pixel OpenCV's decode takes for a PIL mode (3 channels for colour, as OpenCV gives)."""
    if mode in ("1", "L", "P"):
        return 3  # expanded to RGB uint8 afterwards
    if mode.startswith("I;16"):
        return 6  # read as 16-bit: up to 3 channels of 2 bytes
    if mode in ("I", "F"):
        return 12  # 32-bit samples
    return 4 if mode in ("RGBA", "CMYK", "LA", "PA") else 3


def _tiff_size(path: Path) -> tuple[int, int] | None:
    """(width, height) from the first IFD of a classic TIFF, None when it is not one."""
    try:
        with open(path, "rb") as f:
            head = f.read(8)
            if head[:4] not in (b"II*\x00", b"MM\x00*"):
                return None
            e = "<" if head[:2] == b"II" else ">"
            f.seek(struct.unpack(e + "I", head[4:8])[0])
            (n,) = struct.unpack(e + "H", f.read(2))
            tags = {}
            for _ in range(min(n, 4096)):
                tag, typ, _count, raw = struct.unpack(e + "HHI4s", f.read(12))
                if tag in (256, 257):
                    tags[tag] = struct.unpack(e + ("H" if typ == 3 else "I"), raw[:2] if typ == 3 else raw)[0]
    except (OSError, struct.error):
        return None
    return (tags[256], tags[257]) if 256 in tags and 257 in tags else None


def _check_expected(path: Path, wh: tuple[int, int], expected_wh) -> None:
    if expected_wh is not None and tuple(int(v) for v in expected_wh) != wh:
        raise SessionError(path, f"image is {wh[0]} x {wh[1]} but its intrinsics say {expected_wh[0]} x {expected_wh[1]}"
                                 + _resize_hint(wh, expected_wh))


def _resize_hint(wh, expected_wh) -> str:
    """When the image is the intrinsics' frame resized by one factor (a half-size export,
    a binned camera), say so: the intrinsics can be scaled instead of recalibrated."""
    if min(int(expected_wh[0]), int(expected_wh[1]), *wh) <= 0:
        return ""
    sx, sy = wh[0] / float(expected_wh[0]), wh[1] / float(expected_wh[1])
    if abs(sx - sy) < 2.0 / max(wh) and sx != 1.0:
        return (f" (the same frame scaled by {sx:.4g}: scale fx, fy, cx, cy and the image size "
                f"in the intrinsics by {sx:.4g}, or use images of the calibrated size)")
    return ""


def load_image(path: str | Path, expected_wh: tuple[int, int] | None = None) -> np.ndarray:
    """Read an image file as RGB uint8 (H,W,3); greyscale is expanded to 3 channels.

    The size is read from the header first and checked against ``expected_wh`` (the
    intrinsics' width and height, when given) and MAX_IMAGE_PIXELS before any decoding.
    """
    path = Path(path)
    if not path.is_file():
        raise SessionError(path, "image file not found")
    size = path.stat().st_size
    if size == 0:
        raise SessionError(path, "image file is empty (0 bytes)")
    if size > MAX_IMAGE_BYTES:
        raise SessionError(path, f"image file is {size / 2**20:.0f} MiB: too large to be a camera frame")
    wh = read_image_header(path)
    _check_expected(path, wh, expected_wh)
    with open(path, "rb") as f:
        data = np.frombuffer(f.read(MAX_IMAGE_BYTES + 1), dtype=np.uint8)
    if data[:8].tobytes() == b"\x89PNG\r\n\x1a\n" and data[-4096:].tobytes().rfind(b"IEND") < 0:
        raise SessionError(path, "PNG file is truncated (no IEND chunk at its end)")
    try:
        img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
    except cv2.error:
        img = None
    if img is None:
        raise SessionError(path, "cannot decode image (corrupt, truncated or not an image)")
    if (img.shape[1], img.shape[0]) != wh:
        raise SessionError(path, f"image header says {wh[0]} x {wh[1]} but the pixels are {img.shape[1]} x {img.shape[0]}")
    return _to_rgb8(path, img)


# the bit depths cameras store in 16-bit files (PNG/TIFF)
SENSOR_BITS = (8, 10, 12, 14, 16)


def _container_max(img16: np.ndarray) -> int:
    """Full scale of a 16-bit image: machine-vision cameras store 10- or 12-bit pixels in
    16-bit files (PNG/TIFF), so a 12-bit frame whose brightest pixel is 4000 is scaled by
    255/4095, not 255/65535 (which would leave it at 0-16 DN). The bit depth is the smallest
    sensor depth (SENSOR_BITS) that holds the brightest pixel: not the brightest pixel's own
    bit length, which would put a background frame without the bright sphere (brightest 1900,
    11 bits) on another scale than the capture (4000, 12 bits) of the same camera."""
    need = int(img16.max()).bit_length() if img16.size else 16
    bits = next(b for b in SENSOR_BITS if b >= need)
    return (1 << bits) - 1


def to_uint8_16(img16: np.ndarray) -> np.ndarray:
    """A 16-bit image (any channels) as uint8 on its full scale (:func:`_container_max`): the one
    16-to-8-bit rule of files and of bag messages (mono16)."""
    return cv2.convertScaleAbs(img16, alpha=255.0 / _container_max(img16))  # rounds and saturates, no float copy


def _to_rgb8(path: Path, img: np.ndarray) -> np.ndarray:
    """Any decoded OpenCV image (BGR/BGRA/grey, 8/16-bit or float) -> RGB uint8."""
    if img.dtype == np.uint16:
        img = to_uint8_16(img)
    elif img.dtype in (np.float32, np.float64):
        np.nan_to_num(img, copy=False, posinf=0.0, neginf=0.0)
        np.clip(img, 0, None, out=img)
        scale = 255.0 if img.size and float(img.max()) <= 1.0 else 1.0  # float images in [0, 1] or [0, 255]
        img = cv2.convertScaleAbs(img, alpha=scale)
    elif img.dtype != np.uint8:
        raise SessionError(path, f"unsupported pixel type {img.dtype} (use 8- or 16-bit images)")
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    if img.ndim == 2:
        return cv2.cvtColor(img, cv2.COLOR_GRAY2RGB)
    if img.ndim != 3 or img.shape[2] not in (2, 3, 4):
        raise SessionError(path, f"unsupported image layout {img.shape}")
    if img.shape[2] == 2:  # grey + alpha
        return cv2.cvtColor(np.ascontiguousarray(img[:, :, 0]), cv2.COLOR_GRAY2RGB)
    if img.shape[2] == 4:
        return cv2.cvtColor(img, cv2.COLOR_BGRA2RGB)
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def save_image(path: str | Path, image_rgb: np.ndarray, jpeg_quality: int = 92) -> None:
    """Write an RGB uint8 image atomically; format from the suffix."""
    from calib_core.io.atomic import atomic_write_bytes

    path = Path(path)
    img = np.asarray(image_rgb)
    bgr = cv2.cvtColor(img, cv2.COLOR_RGB2BGR) if img.ndim == 3 else img
    params = [cv2.IMWRITE_JPEG_QUALITY, jpeg_quality] if path.suffix.lower() in (".jpg", ".jpeg") else [cv2.IMWRITE_PNG_COMPRESSION, 6]
    ok, buf = cv2.imencode(path.suffix.lower(), bgr, params)
    if not ok:
        raise SessionError(path, "cannot encode image")
    atomic_write_bytes(path, buf.tobytes())


def image_size(path: str | Path) -> tuple[int, int]:
    """(width, height) of an image file, from its header."""
    path = Path(path)
    if not path.is_file():
        raise SessionError(path, "image file not found")
    return read_image_header(path)


def list_frames(path: str | Path, root=None) -> list[Path]:
    """Image files in a folder (sorted), or the file itself. With ``root`` (the session
    folder), a file in the folder that is a symlink leading out of ``root`` is refused."""
    path = Path(path)
    if not path.is_dir():
        return [path]
    files = sorted(p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file())
    if root is not None:
        root_r = Path(root).resolve()
        for p in files:
            if p.is_symlink() and root_r not in p.resolve().parents:
                raise SessionError(p, "this background image is a symlink that leaves the session folder")
    return files


def load_video_frames(path: str | Path, start_s: float = 0.0, end_s: float | None = None,
                      max_frames: int = 60, expected_wh=None) -> list[np.ndarray]:
    """Decode up to ``max_frames`` RGB frames evenly spread over [start_s, end_s] of a video."""
    path = Path(path)
    if not path.is_file():
        raise SessionError(path, "video file not found")
    if path.stat().st_size == 0:
        raise SessionError(path, "video file is empty (0 bytes)")
    cap = cv2.VideoCapture(str(path))
    try:
        if not cap.isOpened():
            raise SessionError(path, "cannot open video (corrupt or unsupported codec)")
        vw, vh = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH) or 0), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT) or 0)
        if vw * vh > MAX_IMAGE_PIXELS:
            raise SessionError(path, f"video frames are {vw} x {vh} pixels: more than a camera frame")
        if vw and vh:
            _check_expected(path, (vw, vh), expected_wh)
        fps = cap.get(cv2.CAP_PROP_FPS)
        fps = fps if np.isfinite(fps) and 0 < fps < 10_000 else 25.0  # some containers report 0 or NaN
        n = cap.get(cv2.CAP_PROP_FRAME_COUNT)
        n = int(n) if np.isfinite(n) and 0 < n < 1e9 else 0
        if not (np.isfinite(start_s) and (end_s is None or np.isfinite(end_s))):
            raise SessionError(path, f"background window {start_s}-{end_s} s is not finite")
        first = int(max(0.0, start_s) * fps)
        last = n - 1 if end_s is None else min(n - 1, int(end_s * fps))
        if n <= 0 or last < first:
            raise SessionError(path, f"video has no frames in the window {start_s}-{end_s} s")
        idx = np.unique(np.linspace(first, last, min(max_frames, last - first + 1)).round().astype(int))
        frames = []
        for i in idx:
            cap.set(cv2.CAP_PROP_POS_FRAMES, int(i))
            ok, bgr = cap.read()
            if ok:
                if expected_wh is not None:
                    _check_expected(path, (bgr.shape[1], bgr.shape[0]), expected_wh)
                frames.append(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
        if not frames:
            raise SessionError(path, "no frame of the video could be decoded")
        return frames
    finally:
        cap.release()


def load_background_frames(path: str | Path, expected_wh=None, root=None, **video_window) -> list[np.ndarray]:
    """Background frames from a folder of images (evenly sampled down to MAX_BACKGROUND_FILES),
    one image, or a video file; each checked against ``expected_wh`` before decoding."""
    path = Path(path)
    if path.is_dir():
        files = list_frames(path, root)
        if not files:
            raise SessionError(path, "background folder holds no images")
        if len(files) > MAX_BACKGROUND_FILES:
            files = [files[i] for i in np.unique(np.linspace(0, len(files) - 1, MAX_BACKGROUND_FILES).round().astype(int))]
        return [load_image(f, expected_wh) for f in files]
    if path.suffix.lower() in VIDEO_SUFFIXES:
        return load_video_frames(path, expected_wh=expected_wh, **video_window)
    return [load_image(path, expected_wh)]
