"""ROS sensor messages <-> numpy: PointCloud2, Image, CompressedImage, CameraInfo.

Works on the message objects ``rosbags`` deserialises (ROS 1 and ROS 2 field spellings);
the ``*_msg`` builders make messages for the synthetic bag writer. A message this module
cannot turn into numbers raises ``ValueError`` with a short reason (the caller names the
bag and topic).
"""

from __future__ import annotations

import io

import cv2
import numpy as np

from calib_core import MAX_IMAGE_PIXELS
from calib_core.camera import CameraModel
from calib_core.io.images import to_uint8_16

POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"
IMAGE = "sensor_msgs/msg/Image"
COMPRESSED = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
TF_STATIC = "tf2_msgs/msg/TFMessage"
IMAGE_TYPES = (IMAGE, COMPRESSED)
MAX_PIXELS = MAX_IMAGE_PIXELS  # the project's image limit; guards against decompression bombs

_PF_DTYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}
_INTENSITY_NAMES = ("intensity", "intensities", "i", "reflectance")


# ---- reading ------------------------------------------------------------------------
def stamp_ns(msg) -> int:
    """Header stamp in ns (ROS 1 ``secs/nsecs`` and ROS 2 ``sec/nanosec``)."""
    st = msg.header.stamp
    sec = getattr(st, "sec", getattr(st, "secs", 0))
    nsec = getattr(st, "nanosec", getattr(st, "nsecs", 0))
    return int(sec) * 1_000_000_000 + int(nsec)


def cloud_from_msg(msg) -> tuple[np.ndarray, np.ndarray | None]:
    """(N,3) float64 points and (N,) intensity or None, NaN points dropped."""
    names = {f.name: f for f in msg.fields}
    if not all(k in names for k in "xyz"):
        raise ValueError(f"PointCloud2 has no x/y/z fields (fields: {', '.join(names) or 'none'})")
    order = ">" if msg.is_bigendian else "<"
    keep = [n for n in ("x", "y", "z") + _INTENSITY_NAMES if n in names]
    fmt = {}
    for n in keep:
        f = names[n]
        if f.datatype not in _PF_DTYPES:
            raise ValueError(f"PointCloud2 field '{n}' has unknown datatype {f.datatype}")
        fmt[n] = (order + _PF_DTYPES[f.datatype], f.offset)
    step, n_pts = int(msg.point_step), int(msg.width) * int(msg.height)
    data = np.asarray(msg.data, dtype=np.uint8)
    if step <= 0 or n_pts * step > data.size:
        raise ValueError(f"PointCloud2 data holds {data.size} bytes, fewer than {n_pts} points x {step}")
    if int(msg.row_step) * int(msg.height) == data.size and int(msg.row_step) != int(msg.width) * step:
        data = data.reshape(int(msg.height), int(msg.row_step))[:, : int(msg.width) * step].ravel()
    dt = np.dtype({"names": list(fmt), "formats": [v[0] for v in fmt.values()],
                   "offsets": [v[1] for v in fmt.values()], "itemsize": step})
    rec = np.frombuffer(data[: n_pts * step].tobytes() if not data.flags.c_contiguous else data[: n_pts * step],
                        dtype=dt, count=n_pts)
    pts = np.column_stack([rec["x"], rec["y"], rec["z"]]).astype(np.float64)
    inten_name = next((n for n in _INTENSITY_NAMES if n in fmt), None)
    inten = None if inten_name is None else rec[inten_name].astype(np.float64)
    ok = np.isfinite(pts).all(axis=1)
    if not ok.all():
        pts = pts[ok]
        inten = None if inten is None else inten[ok]
    return pts, inten


def image_from_msg(msg, msgtype: str) -> np.ndarray:
    """RGB uint8 (H,W,3) from an Image or CompressedImage message."""
    if msgtype == COMPRESSED:
        return _decode_compressed(msg)
    enc = str(msg.encoding).lower()
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    if h * w > MAX_PIXELS or h <= 0 or w <= 0:
        raise ValueError(f"image claims {w} x {h} pixels")
    data = np.asarray(msg.data, dtype=np.uint8)
    if data.size < h * step:
        raise ValueError(f"image data holds {data.size} bytes, fewer than {h} rows x {step}")
    rows = data[: h * step].reshape(h, step)
    if enc in ("rgb8", "bgr8", "rgba8", "bgra8", "mono8", "8uc1", "8uc3"):
        ch = {"rgb8": 3, "bgr8": 3, "8uc3": 3, "rgba8": 4, "bgra8": 4}.get(enc, 1)
        img = rows[:, : w * ch].reshape(h, w, ch)
        if ch == 1:
            return np.repeat(img, 3, axis=2)
        if enc.startswith("bgr") or enc == "8uc3":
            return np.ascontiguousarray(img[:, :, 2::-1])
        return np.ascontiguousarray(img[:, :, :3])
    if enc in ("mono16", "16uc1"):
        big = bool(msg.is_bigendian)
        img = np.frombuffer(rows[:, : w * 2].tobytes(), dtype=">u2" if big else "<u2").reshape(h, w)
        return np.repeat(to_uint8_16(img)[..., None], 3, axis=2)
    bayer = {"bayer_rggb8": cv2.COLOR_BayerRG2RGB, "bayer_bggr8": cv2.COLOR_BayerBG2RGB,
             "bayer_gbrg8": cv2.COLOR_BayerGB2RGB, "bayer_grbg8": cv2.COLOR_BayerGR2RGB}
    if enc in bayer:
        return cv2.cvtColor(np.ascontiguousarray(rows[:, :w]), bayer[enc])
    raise ValueError(f"image encoding '{msg.encoding}' is not supported (use rgb8, bgr8, mono8, mono16 or bayer)")


def _decode_compressed(msg) -> np.ndarray:
    from PIL import Image as PILImage

    raw = np.asarray(msg.data, dtype=np.uint8)
    try:
        with PILImage.open(io.BytesIO(raw.tobytes())) as im:  # reads the header only
            w, h = im.size
    except Exception:
        raise ValueError(f"compressed image format '{msg.format}' cannot be decoded") from None
    if w * h > MAX_PIXELS:
        raise ValueError(f"compressed image claims {w} x {h} pixels")
    img = cv2.imdecode(raw, cv2.IMREAD_COLOR | cv2.IMREAD_ANYDEPTH)  # a 16-bit PNG keeps its depth
    if img is None:
        raise ValueError(f"compressed image ('{msg.format}') is corrupt or truncated")
    if img.dtype == np.uint16:
        img = to_uint8_16(img)  # the 16-bit files' rule
    elif img.dtype != np.uint8:
        raise ValueError(f"compressed image ('{msg.format}') has {img.dtype} pixels (use 8- or 16-bit)")
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def camera_from_info(msg, name: str) -> CameraModel:
    """CameraModel from a CameraInfo message (plumb_bob, rational_polynomial's 8 terms, or
    equidistant's 4)."""
    K = np.asarray(getattr(msg, "k", getattr(msg, "K", None)), dtype=float).reshape(3, 3)
    D = np.asarray(getattr(msg, "d", getattr(msg, "D", [])), dtype=float).ravel()
    model = str(msg.distortion_model or "plumb_bob")
    if model not in ("plumb_bob", "rational_polynomial", "equidistant", "") or (model == "" and D.size):
        raise ValueError(f"distortion model '{model}' is not supported (use plumb_bob, rational_polynomial or equidistant)")
    if not (np.isfinite(K).all() and K[0, 0] > 0 and K[1, 1] > 0 and msg.width > 0 and msg.height > 0):
        raise ValueError("CameraInfo holds no valid camera matrix (is the camera calibrated?)")
    if model == "equidistant":
        if np.any(D[4:] != 0) or not np.isfinite(D).all():
            raise ValueError(f"equidistant distortion has 4 coefficients k1..k4, got {D.size}")
        return CameraModel(int(msg.width), int(msg.height), K, D[:4], name=name, fisheye=True)
    if model != "rational_polynomial" and np.any(D[5:8] != 0):
        raise ValueError("plumb_bob distortion has 5 coefficients, but k4..k6 are not zero (rational_polynomial?)")
    return CameraModel(int(msg.width), int(msg.height), K, D[:8], name=name)


# ---- building (synthetic bags) ------------------------------------------------------
def header_msg(ts, stamp: int, frame: str, ros1: bool):
    t = ts.types["builtin_interfaces/msg/Time"](sec=stamp // 1_000_000_000, nanosec=stamp % 1_000_000_000)
    H = ts.types["std_msgs/msg/Header"]
    return H(seq=0, stamp=t, frame_id=frame) if ros1 else H(stamp=t, frame_id=frame)


def cloud_msg(ts, stamp: int, frame: str, points_m: np.ndarray, intensity: np.ndarray | None, ros1: bool):
    """PointCloud2 with float32 x, y, z (and intensity), unorganised."""
    PF = ts.types["sensor_msgs/msg/PointField"]
    names = ["x", "y", "z"] + (["intensity"] if intensity is not None else [])
    rec = np.empty(len(points_m), dtype=[(n, "<f4") for n in names])
    for i, n in enumerate("xyz"):
        rec[n] = points_m[:, i]
    if intensity is not None:
        rec["intensity"] = intensity
    fields = [PF(name=n, offset=4 * i, datatype=7, count=1) for i, n in enumerate(names)]
    return ts.types[POINTCLOUD2](header=header_msg(ts, stamp, frame, ros1), height=1, width=len(rec), fields=fields,
                                 is_bigendian=False, point_step=rec.itemsize, row_step=rec.nbytes,
                                 data=rec.view(np.uint8).ravel(), is_dense=True)


def image_msg(ts, stamp: int, frame: str, image_rgb: np.ndarray, ros1: bool):
    h, w = image_rgb.shape[:2]
    return ts.types[IMAGE](header=header_msg(ts, stamp, frame, ros1), height=h, width=w, encoding="rgb8",
                           is_bigendian=0, step=3 * w, data=np.ascontiguousarray(image_rgb, np.uint8).ravel())


def compressed_msg(ts, stamp: int, frame: str, image_rgb: np.ndarray, ros1: bool, quality: int = 92):
    ok, buf = cv2.imencode(".jpg", cv2.cvtColor(image_rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, quality])
    return ts.types[COMPRESSED](header=header_msg(ts, stamp, frame, ros1), format="jpeg", data=buf.ravel())


def info_msg(ts, stamp: int, frame: str, cam: CameraModel, ros1: bool):
    P = np.hstack([cam.K, np.zeros((3, 1))]).ravel()
    Roi = ts.types["sensor_msgs/msg/RegionOfInterest"]
    roi = Roi(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
    arrays = dict(d=np.asarray(cam.dist, float), k=cam.K.ravel().astype(float), r=np.eye(3).ravel(), p=P)
    if ros1:
        arrays = {k.upper(): v for k, v in arrays.items()}
    return ts.types[CAMERA_INFO](header=header_msg(ts, stamp, frame, ros1), height=cam.height_px, width=cam.width_px,
                                 distortion_model=cam.distortion_model, binning_x=0, binning_y=0, roi=roi, **arrays)
