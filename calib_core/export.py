"""Export a calibration (``results/calibration.json``) to the formats other tools read.

Formats (:data:`FORMATS`), each a text produced by :func:`export_text`:

- ``json``: the calibration.json content of the session-format spec (plus a ``frames`` note).
- ``tf-static``: a ROS ``static_transform_publisher`` command line per camera,
  ``x y z qx qy qz qw parent child`` (ROS 1 ``rosrun`` form, which ROS 2 also accepts;
  the ROS 2 named-argument form follows as a comment).
- ``tf2-yaml``: a tf2_msgs/TFMessage-like YAML: ``transforms:`` a list of
  geometry_msgs/TransformStamped (header.frame_id, child_frame_id, transform).
- ``urdf``: ``<link>`` and fixed ``<joint>`` elements (origin xyz rpy) in a ``<robot>``.
- ``kalibr``: a Kalibr-style camchain YAML (pinhole, radtan) with ``T_cam_sonar``.
- ``camera-info``: ROS camera_info YAML of one camera's intrinsics.

Frames: every pose published to ROS is the pose of the *child* frame in the *parent*
frame, i.e. ``T_parent_child`` (it maps child-frame points into the parent frame).
With the default ``parent="sonar"`` that is ``T_sonar_cam = inverse(T_cam_sonar)``.
The published transforms always form one tree (one root, one parent per child, no
cycle), as tf2 and urdfdom require: with ``parent="camera"`` the first exported camera
is the root, ``sonar`` its child, and every further camera a child of ``sonar``
(:func:`tree_edges`).
The camera frame is the OpenCV/ROS optical frame (x right, y down, z forward), named
``<camera>_optical_frame`` unless given. Every file states its frame naming in a comment
(or, for JSON, in its ``frames`` key). Numbers are written with full precision.
"""

from __future__ import annotations

import json
import xml.sax.saxutils as sx
from dataclasses import dataclass

import numpy as np
import yaml

from calib_core.camera import CameraModel
from calib_core.geometry import invert_T
from calib_core.markup import plain_line, ros_frame_id

FORMATS = ("json", "tf-static", "tf2-yaml", "urdf", "kalibr", "camera-info")
NEEDS_INTRINSICS = ("kalibr", "camera-info")


@dataclass(frozen=True)
class FrameNames:
    """Frame naming for ROS exports.

    Attributes:
        sonar: name of the sonar frame.
        camera_pattern: camera frame name, ``{cam}`` is replaced by the camera name.
        parent: "sonar" (publish T_sonar_cam, the camera in the sonar frame) or
            "camera" (publish T_cam_sonar, the sonar in the camera frame).
    """

    sonar: str = "sonar"
    camera_pattern: str = "{cam}_optical_frame"
    parent: str = "sonar"

    def camera(self, cam: str) -> str:
        """The camera's frame id: the pattern filled in, made a valid ROS frame id."""
        return ros_frame_id(self.camera_pattern.replace("{cam}", ros_frame_id(cam)))

    @property
    def sonar_frame(self) -> str:
        return ros_frame_id(self.sonar)

    def parent_child(self, cam: str) -> tuple[str, str]:
        if self.parent not in ("sonar", "camera"):
            raise ValueError(f"parent must be 'sonar' or 'camera', got {self.parent!r}")
        sonar = self.sonar_frame
        return (sonar, self.camera(cam)) if self.parent == "sonar" else (self.camera(cam), sonar)


def _f(x: float) -> str:
    """Shortest text that reads back to exactly the same float."""
    return repr(float(x))


def quaternion_xyzw(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (x, y, z, w) of a rotation matrix, with w >= 0."""
    from scipy.spatial.transform import Rotation  # lazy: scipy costs ~0.3 s at every CLI start

    q = Rotation.from_matrix(np.asarray(R, float)[:3, :3]).as_quat()
    return -q if q[3] < 0 else q


def rpy_rad(R: np.ndarray) -> np.ndarray:
    """URDF roll, pitch, yaw (rad): R = Rz(yaw) Ry(pitch) Rx(roll) (fixed axes x, y, z)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(np.asarray(R, float)[:3, :3]).as_euler("xyz")


def _cameras(calibration: dict, camera: str | None) -> dict:
    cams = calibration.get("cameras") or {}
    if camera is None:
        return cams
    if camera not in cams:
        raise KeyError(f"no camera '{camera}' in the calibration (cameras: {', '.join(cams) or 'none'})")
    return {camera: cams[camera]}


def T_parent_child(calibration: dict, cam: str, frames: FrameNames) -> np.ndarray:
    """The transform that ROS publishes for camera ``cam`` alone: the child's pose in the parent."""
    T_cam_sonar = np.asarray(calibration["cameras"][cam]["T_cam_sonar"], float)
    return invert_T(T_cam_sonar) if frames.parent == "sonar" else T_cam_sonar


@dataclass(frozen=True)
class Edge:
    """One published transform: ``T_parent_child`` (child pose in parent) for camera ``cam``."""

    cam: str
    parent: str
    child: str
    T_parent_child: np.ndarray


def tree_edges(calibration: dict, camera: str | None, frames: FrameNames) -> list[Edge]:
    """The transforms to publish, always a tree rooted at one frame.

    ``parent="sonar"``: sonar -> every camera. ``parent="camera"``: the first camera is the
    root with sonar as its child, and the other cameras hang below sonar (a frame may have
    only one parent, so sonar cannot be the child of two cameras).
    """
    frames.parent_child("probe")  # validates frames.parent
    cams = list(_cameras(calibration, camera))
    edges = []
    for k, cam in enumerate(cams):
        T_cam_sonar = np.asarray(calibration["cameras"][cam]["T_cam_sonar"], float)
        if frames.parent == "camera" and k == 0:
            edges.append(Edge(cam, frames.camera(cam), frames.sonar, T_cam_sonar))
        else:
            edges.append(Edge(cam, frames.sonar, frames.camera(cam), invert_T(T_cam_sonar)))
    return edges


def _frame_comment(frames: FrameNames, prefix: str = "# ") -> str:
    lines = [
        f"Frames: sonar frame '{frames.sonar_frame}' (the frame the sonar cloud is written in, metres);",
        f"camera frame '{frames.camera('<cam>')}' (OpenCV/ROS optical: x right, y down, z forward).",
        "Each transform is the pose of the child frame in the parent frame (T_parent_child, maps child points",
        f"into the parent); parent here is the {frames.parent} frame. T_cam_sonar maps sonar points into the camera.",
    ]
    if frames.parent == "camera":
        lines.append("One tree: the first camera is the root, sonar its child, further cameras children of sonar.")
    return "\n".join(prefix + s for s in lines) + "\n"


def _scale_note(calibration: dict, prefix: str = "# ") -> str:
    """A comment line when the calibration estimated a sonar range scale != 1."""
    s = calibration.get("range_scale")
    v = s.get("value") if isinstance(s, dict) else None
    if not isinstance(v, (int, float)) or isinstance(v, bool) or v == 1.0:
        return ""
    return (f"{prefix}Sonar range scale {_f(v)}: divide sonar cloud points by it before applying these transforms\n"
            f"{prefix}(the cloud's sound speed was off by {100 * (v - 1):+.3f} %).\n")


def to_json(calibration: dict, camera: str | None = None) -> str:
    """The calibration.json of the spec (only ``camera`` if given) with a ``frames`` note."""
    out = dict(calibration)
    out["cameras"] = _cameras(calibration, camera)
    out.setdefault("frames", {
        "T_cam_sonar": "maps points in the sonar frame (metres) into the camera's OpenCV optical frame "
                       "(x right, y down, z forward); its translation is the sonar origin seen from the camera",
        "covariance": "6x6 over (rotation vector rad, translation m) of T_cam_sonar",
    })
    return json.dumps(out, indent=2) + "\n"


def to_tf_static(calibration: dict, camera: str | None = None, frames: FrameNames = FrameNames()) -> str:
    """``rosrun tf2_ros static_transform_publisher x y z qx qy qz qw parent child``, one per camera."""
    text = "#!/bin/sh\n# sonarcal calibration as ROS static transforms.\n" + _frame_comment(frames) + _scale_note(calibration)
    for e in tree_edges(calibration, camera, frames):
        cam, parent, child, T = e.cam, e.parent, e.child, e.T_parent_child
        q = quaternion_xyzw(T[:3, :3])
        nums = [*T[:3, 3], *q]
        text += f"# {plain_line(cam)}: pose of '{child}' in '{parent}'\n"
        text += "rosrun tf2_ros static_transform_publisher " + " ".join(_f(v) for v in nums) + f" {parent} {child} &\n"
        named = " ".join(f"--{k} {_f(v)}" for k, v in zip(("x", "y", "z", "qx", "qy", "qz", "qw"), nums))
        text += f"# ROS 2: ros2 run tf2_ros static_transform_publisher {named} --frame-id {parent} --child-frame-id {child}\n"
    return text


def to_tf2_yaml(calibration: dict, camera: str | None = None, frames: FrameNames = FrameNames()) -> str:
    """tf2 static transforms: ``transforms:`` list of geometry_msgs/TransformStamped."""
    tfs = []
    for e in tree_edges(calibration, camera, frames):
        parent, child, T = e.parent, e.child, e.T_parent_child
        q = quaternion_xyzw(T[:3, :3])
        tfs.append({
            "header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": parent},
            "child_frame_id": child,
            "transform": {
                "translation": {"x": float(T[0, 3]), "y": float(T[1, 3]), "z": float(T[2, 3])},
                "rotation": {"x": float(q[0]), "y": float(q[1]), "z": float(q[2]), "w": float(q[3])},
            },
        })
    head = ("# sonarcal calibration as tf2 static transforms (geometry_msgs/TransformStamped).\n" + _frame_comment(frames)
            + _scale_note(calibration))
    return head + yaml.safe_dump({"transforms": tfs}, sort_keys=False)


def to_urdf(calibration: dict, camera: str | None = None, frames: FrameNames = FrameNames(),
            robot_name: str = "sonarcal") -> str:
    """URDF links and fixed joints (``<origin xyz rpy>`` = pose of the child link in the parent)."""
    q = sx.quoteattr
    body = []
    links = []
    for e in tree_edges(calibration, camera, frames):
        parent, child, T = e.parent, e.child, e.T_parent_child
        xyz = " ".join(_f(v) for v in T[:3, 3])
        rpy = " ".join(_f(v) for v in rpy_rad(T[:3, :3]))
        for name in (parent, child):
            if name not in links:
                links.append(name)
        body.append(f"  <joint name={q(parent + '_to_' + child)} type=\"fixed\">\n"
                    f"    <parent link={q(parent)}/>\n    <child link={q(child)}/>\n"
                    f"    <origin xyz=\"{xyz}\" rpy=\"{rpy}\"/>\n  </joint>")
    comment = (_frame_comment(frames, prefix="  ") + _scale_note(calibration, "  ")).replace("--", "- -")
    return (f"<?xml version=\"1.0\"?>\n<!-- sonarcal calibration: paste the links and joints into your URDF.\n"
            f"{comment}  rpy: roll, pitch, yaw (rad) about fixed x, y, z: R = Rz(yaw) Ry(pitch) Rx(roll). -->\n"
            f"<robot name={q(robot_name)}>\n" + "\n".join(f"  <link name={q(n)}/>" for n in links) + "\n"
            + "\n".join(body) + "\n</robot>\n")


def _kalibr_distortion(cam: str, m: CameraModel, notes: list[str]) -> tuple[str, list[float]]:
    """Kalibr's (distortion_model, distortion_coeffs) for a camera model; what Kalibr cannot
    hold is named in ``notes``."""
    if m.fisheye:
        return "equidistant", [float(v) for v in m.dist]
    k1, k2, p1, p2, k3 = (float(v) for v in m.dist[:5])
    if k3 != 0.0:
        notes.append(f"# {plain_line(cam)}: k3 = {_f(k3)} is not part of Kalibr's radtan model and was dropped.")
    if m.rational:
        notes.append(f"# {plain_line(cam)}: the rational model's k4..k6 = "
                     f"{', '.join(_f(float(v)) for v in m.dist[5:])} are not part of Kalibr's radtan model "
                     "and were dropped: these intrinsics are only an approximation there.")
    return "radtan", [k1, k2, p1, p2]


def to_kalibr(calibration: dict, intrinsics: dict[str, CameraModel], camera: str | None = None,
              topic_pattern: str = "/{cam}/image_raw") -> str:
    """Kalibr-style camchain YAML: cam0, cam1, ... with pinhole/radtan (or pinhole/equidistant)
    intrinsics and ``T_cam_sonar``.

    ``T_cam_sonar`` follows Kalibr's ``T_cam_imu`` convention (maps sonar points into the
    camera). From the second camera on, ``T_cn_cnm1`` (previous camera -> this camera) is
    chained through the sonar: T_cn_sonar inverse(T_cnm1_sonar). Kalibr's radtan has no k3:
    it is dropped (and named in a comment) when non-zero.
    """
    out = {}
    notes = []
    prev = None
    for i, (cam, c) in enumerate(_cameras(calibration, camera).items()):
        if cam not in intrinsics:
            raise KeyError(f"no intrinsics for camera '{cam}'")
        m = intrinsics[cam]
        T = np.asarray(c["T_cam_sonar"], float)
        model, coeffs = _kalibr_distortion(cam, m, notes)
        entry = {
            "camera_name": cam,
            "camera_model": "pinhole",
            "intrinsics": [m.fx, m.fy, m.cx, m.cy],
            "distortion_model": model,
            "distortion_coeffs": coeffs,
            "resolution": [int(m.width_px), int(m.height_px)],
            "rostopic": topic_pattern.format(cam=cam),
            "T_cam_sonar": [[float(v) for v in row] for row in T],
        }
        if prev is not None:
            entry["T_cn_cnm1"] = [[float(v) for v in row] for row in T @ invert_T(prev)]
        prev = T
        out[f"cam{i}"] = entry
    head = ("# sonarcal calibration as a Kalibr-style camchain.\n"
            "# T_cam_sonar maps points in the sonar frame (metres) into this camera's optical frame\n"
            "# (x right, y down, z forward), like Kalibr's T_cam_imu. T_cn_cnm1 maps the previous\n"
            "# camera's frame into this one (chained through the sonar calibration).\n"
            "# intrinsics: [fu, fv, pu, pv] px; distortion_coeffs: radtan [k1, k2, r1, r2] (OpenCV order)\n"
            "# or equidistant [k1, k2, k3, k4].\n")
    return head + _scale_note(calibration) + "".join(n + "\n" for n in notes) + \
        yaml.safe_dump(out, sort_keys=False, default_flow_style=None)


def to_camera_info(cam_model: CameraModel, name: str) -> str:
    """ROS camera_info YAML (as ROS camera_calibration writes it) for one camera."""
    from calib_core.io.intrinsics import camera_info_dict

    head = (f"# Intrinsics of camera '{plain_line(name)}' (ROS camera_info). Pixels of the raw image; frame:\n"
            f"# the camera's optical frame (x right, y down, z forward). Distortion plumb_bob, OpenCV order.\n")
    return head + yaml.safe_dump(camera_info_dict(cam_model, name), sort_keys=False, default_flow_style=None)


def export_text(calibration: dict, fmt: str, camera: str | None = None, intrinsics: dict | None = None,
                frames: FrameNames = FrameNames()) -> str:
    """The export of ``calibration`` in format ``fmt`` (one of :data:`FORMATS`).

    ``intrinsics`` ({camera: CameraModel}) is needed for "kalibr" and "camera-info";
    "camera-info" covers one camera: ``camera``, or the only camera. Raises KeyError
    for an unknown camera, ValueError for an unknown format or missing intrinsics.
    """
    if fmt not in FORMATS:
        raise ValueError(f"unknown export format '{fmt}' (use one of {', '.join(FORMATS)})")
    if fmt in NEEDS_INTRINSICS and not intrinsics:
        raise ValueError(f"format '{fmt}' needs the cameras' intrinsics")
    if fmt == "json":
        return to_json(calibration, camera)
    if fmt == "tf-static":
        return to_tf_static(calibration, camera, frames)
    if fmt == "tf2-yaml":
        return to_tf2_yaml(calibration, camera, frames)
    if fmt == "urdf":
        return to_urdf(calibration, camera, frames)
    if fmt == "kalibr":
        return to_kalibr(calibration, intrinsics, camera)
    names = [camera] if camera else list(intrinsics)
    if camera is None and len(names) != 1:
        raise ValueError(f"format 'camera-info' covers one camera: pick one with --camera ({', '.join(names)})")
    if names[0] not in intrinsics:
        raise KeyError(f"no intrinsics for camera '{names[0]}'")
    return to_camera_info(intrinsics[names[0]], names[0])
