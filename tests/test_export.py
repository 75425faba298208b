"""Exports round-trip: each format is parsed back and its numbers compared (1e-9)."""

from __future__ import annotations

import argparse
import json
import shlex
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from calib_core.camera import CameraModel
from calib_core.errors import SessionError
from calib_core.export import FORMATS, FrameNames, export_text
from calib_core.geometry import T_from_rotvec, invert_T
from calib_core.io.intrinsics import save_intrinsics_ros
from calib_core.results import save_calibration
from sonarcal_cli.commands import export as cmd_export

TOL = 1e-9


def _T(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return T_from_rotvec(rng.normal(size=3) * 1.2, rng.normal(size=3) * 0.6)


def _cams() -> dict[str, CameraModel]:
    return {
        "cam1": CameraModel(1920, 1080, [[1402.5, 0, 961.25], [0, 1398.75, 538.5], [0, 0, 1]],
                            [-0.12, 0.031, 0.0011, -0.0007, 0.004], "cam1"),
        "cam2": CameraModel(1280, 720, [[905.0, 0, 640.5], [0, 903.0, 359.25], [0, 0, 1]],
                            [0.05, -0.01, 0.0, 0.0002, 0.0], "cam2"),
    }


def _calibration(seed: int = 0) -> dict:
    return {
        "format": "sonar-camera-calibration/1",
        "session": "export-test",
        "cameras": {
            "cam1": {"T_cam_sonar": _T(seed).tolist(), "rms_reprojection_px": 1.5,
                     "captures_used": ["p01", "p02"], "covariance": (np.eye(6) * 1e-6).tolist()},
            "cam2": {"T_cam_sonar": _T(seed + 100).tolist(), "rms_reprojection_px": 2.0,
                     "captures_used": ["p01"], "covariance": (np.eye(6) * 2e-6).tolist()},
        },
    }


def make_session(root: Path, seed: int = 0) -> dict:
    """A minimal session folder with two cameras and a calibration.json."""
    cams = _cams()
    for name, m in cams.items():
        save_intrinsics_ros(root / "intrinsics" / f"{name}.yaml", m, name)
    (root / "clouds").mkdir(parents=True, exist_ok=True)
    np.save(root / "clouds" / "p01.npy", np.zeros((3, 3)))
    manifest = {
        "format": "sonar-camera-session/1", "name": "export-test", "sphere": {"diameter": 0.22},
        "cameras": {n: {"intrinsics": f"intrinsics/{n}.yaml"} for n in cams},
        "captures": [{"id": "p01", "cloud": "clouds/p01.npy"}],
    }
    (root / "session.yaml").write_text(yaml.safe_dump(manifest))
    cal = _calibration(seed)
    save_calibration(root / "results" / "calibration.json", cal)
    return cal


def _close(a, b):
    np.testing.assert_allclose(np.asarray(a, float), np.asarray(b, float), atol=TOL, rtol=0)


def _T_from_xyz_q(xyz, q):
    return np.block([[Rotation.from_quat(q).as_matrix(), np.reshape(xyz, (3, 1))], [np.zeros((1, 3)), np.ones((1, 1))]])


def _commands(text: str) -> list[list[str]]:
    return [shlex.split(ln.rstrip("&").strip()) for ln in text.splitlines() if ln.strip() and not ln.startswith("#")]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_tf_static_publishes_child_pose_in_parent(seed):
    cal = _calibration(seed)
    text = export_text(cal, "tf-static")
    cmds = _commands(text)
    assert len(cmds) == 2
    for cmd, cam in zip(cmds, ["cam1", "cam2"]):
        assert cmd[:3] == ["rosrun", "tf2_ros", "static_transform_publisher"]
        nums = [float(v) for v in cmd[3:10]]
        parent, child = cmd[10:12]
        assert (parent, child) == ("sonar", f"{cam}_optical_frame")
        T_parent_child = _T_from_xyz_q(nums[:3], nums[3:7])
        # the camera pose in the sonar frame maps camera points to sonar points
        _close(T_parent_child, invert_T(np.asarray(cal["cameras"][cam]["T_cam_sonar"])))
        assert abs(np.linalg.norm(nums[3:7]) - 1) < 1e-12 and nums[6] >= 0
    assert "pose of the child frame in the parent frame" in text
    # ROS 2 named form carries the same numbers
    ros2 = [ln for ln in text.splitlines() if ln.startswith("# ROS 2:")][0]
    toks = shlex.split(ros2[len("# ROS 2:"):])
    xyz = [float(toks[toks.index(f"--{k}") + 1]) for k in ("x", "y", "z")]
    _close(xyz, [float(v) for v in cmds[0][3:6]])


def test_tf_static_parent_camera_and_names():
    cal = _calibration(3)
    frames = FrameNames(sonar="bv5000", camera_pattern="{cam}_link", parent="camera")
    cmd = _commands(export_text(cal, "tf-static", camera="cam2", frames=frames))
    assert len(cmd) == 1 and cmd[0][10:12] == ["cam2_link", "bv5000"]
    _close(_T_from_xyz_q([float(v) for v in cmd[0][3:6]], [float(v) for v in cmd[0][6:10]]),
           cal["cameras"]["cam2"]["T_cam_sonar"])


@pytest.mark.parametrize("parent", ["sonar", "camera"])
def test_tf2_yaml_round_trip(parent):
    cal = _calibration(4)
    text = export_text(cal, "tf2-yaml", frames=FrameNames(parent=parent))
    assert text.startswith("#") and "Frames:" in text
    doc = yaml.safe_load(text)
    assert len(doc["transforms"]) == 2
    for tf, cam in zip(doc["transforms"], ["cam1", "cam2"]):
        tr, rot = tf["transform"]["translation"], tf["transform"]["rotation"]
        T = _T_from_xyz_q([tr["x"], tr["y"], tr["z"]], [rot["x"], rot["y"], rot["z"], rot["w"]])
        T_cam_sonar = np.asarray(cal["cameras"][cam]["T_cam_sonar"])
        if parent == "sonar" or cam != "cam1":  # one tree: only the first camera is above sonar
            assert (tf["header"]["frame_id"], tf["child_frame_id"]) == ("sonar", f"{cam}_optical_frame")
            _close(T, invert_T(T_cam_sonar))
        else:
            assert (tf["header"]["frame_id"], tf["child_frame_id"]) == (f"{cam}_optical_frame", "sonar")
            _close(T, T_cam_sonar)
        assert set(tf["header"]["stamp"]) == {"sec", "nanosec"}


def _rpy_matrix(r, p, y):
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx  # URDF: fixed-axis roll, pitch, yaw


@pytest.mark.parametrize("seed", [5, 6])
def test_urdf_joint_origin(seed):
    cal = _calibration(seed)
    text = export_text(cal, "urdf")
    root = ET.fromstring(text.split("?>", 1)[1])
    assert root.tag == "robot"
    assert {ln.get("name") for ln in root.findall("link")} == {"sonar", "cam1_optical_frame", "cam2_optical_frame"}
    joints = root.findall("joint")
    assert len(joints) == 2
    for j, cam in zip(joints, ["cam1", "cam2"]):
        assert j.get("type") == "fixed"
        assert j.find("parent").get("link") == "sonar" and j.find("child").get("link") == f"{cam}_optical_frame"
        o = j.find("origin")
        xyz = [float(v) for v in o.get("xyz").split()]
        rpy = [float(v) for v in o.get("rpy").split()]
        T = np.eye(4)
        T[:3, :3] = _rpy_matrix(*rpy)
        T[:3, 3] = xyz
        _close(T, invert_T(np.asarray(cal["cameras"][cam]["T_cam_sonar"])))
    assert "pose of the child frame in the parent frame" in text


def test_kalibr_camchain():
    cal, cams = _calibration(7), _cams()
    text = export_text(cal, "kalibr", intrinsics=cams)
    doc = yaml.safe_load(text)
    assert list(doc) == ["cam0", "cam1"]
    for key, cam in zip(["cam0", "cam1"], ["cam1", "cam2"]):
        e, m = doc[key], cams[cam]
        assert e["camera_name"] == cam and e["camera_model"] == "pinhole" and e["distortion_model"] == "radtan"
        _close(e["intrinsics"], [m.fx, m.fy, m.cx, m.cy])
        _close(e["distortion_coeffs"], m.dist[:4])
        assert e["resolution"] == [m.width_px, m.height_px]
        _close(e["T_cam_sonar"], cal["cameras"][cam]["T_cam_sonar"])
    # chained stereo: cam1 -> cam2
    T21 = np.asarray(cal["cameras"]["cam2"]["T_cam_sonar"]) @ invert_T(np.asarray(cal["cameras"]["cam1"]["T_cam_sonar"]))
    _close(doc["cam1"]["T_cn_cnm1"], T21)
    assert "T_cn_cnm1" not in doc["cam0"]
    assert "k3" in text  # cam1's k3 != 0 is reported as dropped
    assert "maps points in the sonar frame" in text


def test_camera_info_round_trip(tmp_path):
    from calib_core.io.intrinsics import load_intrinsics

    cams = _cams()
    text = export_text(_calibration(), "camera-info", camera="cam2", intrinsics=cams)
    p = tmp_path / "cam2.yaml"
    p.write_text(text)
    back = load_intrinsics(p)
    _close(back.K, cams["cam2"].K)
    _close(back.dist, cams["cam2"].dist)
    assert (back.width_px, back.height_px) == (1280, 720)
    with pytest.raises(ValueError, match="one camera"):
        export_text(_calibration(), "camera-info", intrinsics=cams)


def test_json_is_the_spec():
    cal = _calibration(8)
    doc = json.loads(export_text(cal, "json", camera="cam1"))
    assert doc["format"] == "sonar-camera-calibration/1" and list(doc["cameras"]) == ["cam1"]
    _close(doc["cameras"]["cam1"]["T_cam_sonar"], cal["cameras"]["cam1"]["T_cam_sonar"])
    _close(doc["cameras"]["cam1"]["covariance"], cal["cameras"]["cam1"]["covariance"])
    assert "T_cam_sonar" in doc["frames"]


def test_unknown_camera_and_format():
    with pytest.raises(KeyError, match="cam9"):
        export_text(_calibration(), "tf-static", camera="cam9")
    with pytest.raises(ValueError, match="unknown export format"):
        export_text(_calibration(), "bag")


# ---- the command ---------------------------------------------------------------
def _args(session, fmt, **kw):
    p = argparse.ArgumentParser()
    sub = p.add_subparsers()
    cmd_export.add_parser(sub)
    argv = ["export", str(session), "--format", fmt]
    for k, v in kw.items():
        argv += [f"--{k.replace('_', '-')}", str(v)]
    return p.parse_args(argv)


@pytest.mark.parametrize("fmt", FORMATS)
def test_cli_every_format_to_file(tmp_path, fmt):
    cal = make_session(tmp_path, seed=9)
    out = tmp_path / "out" / f"export.{fmt}"
    kw = {"out": out}
    if fmt == "camera-info":
        kw["camera"] = "cam1"
    args = _args(tmp_path, fmt, **kw)
    assert args.run(args) == 0
    text = out.read_text()
    if fmt == "json":
        _close(json.loads(text)["cameras"]["cam2"]["T_cam_sonar"], cal["cameras"]["cam2"]["T_cam_sonar"])
    elif fmt == "tf-static":
        cmd = _commands(text)[0]
        _close(_T_from_xyz_q([float(v) for v in cmd[3:6]], [float(v) for v in cmd[6:10]]),
               invert_T(np.asarray(cal["cameras"]["cam1"]["T_cam_sonar"])))
    elif fmt in ("tf2-yaml", "kalibr", "camera-info"):
        assert yaml.safe_load(text)
    else:
        assert ET.fromstring(text.split("?>", 1)[1]).tag == "robot"


def test_cli_stdout_and_errors(tmp_path, capsys):
    make_session(tmp_path)
    args = _args(tmp_path, "tf2-yaml", camera="cam2", sonar_frame="bv")
    assert args.run(args) == 0
    doc = yaml.safe_load(capsys.readouterr().out)
    assert doc["transforms"][0]["header"]["frame_id"] == "bv"
    bad = _args(tmp_path, "urdf", camera="nope")
    with pytest.raises(SessionError, match="nope"):
        bad.run(bad)
    (tmp_path / "results" / "calibration.json").unlink()
    args = _args(tmp_path, "json")
    with pytest.raises(SessionError, match="calibration file not found"):
        args.run(args)


def test_range_scale_is_stated_in_every_transform_export():
    cal = dict(_calibration(10), range_scale={"value": 1.02, "sigma": 0.001, "estimated": True})
    for fmt in ("tf-static", "tf2-yaml", "urdf", "kalibr"):
        text = export_text(cal, fmt, intrinsics=_cams())
        assert "range scale 1.02" in text and "+2.000 %" in text, fmt
    assert "range scale" not in export_text(_calibration(10), "tf-static")
    ET.fromstring(export_text(cal, "urdf").split("?>", 1)[1])  # still valid XML
