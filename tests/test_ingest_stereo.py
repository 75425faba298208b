"""/tf_static -> session stereo transform (two cameras), and the TF tree arithmetic."""

from __future__ import annotations

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from calib_core.camera import CameraModel
from calib_core.geometry import invert_T, make_T
from calib_core.ingest import rosmsg
from calib_core.ingest.bagwrite import BagWriter
from calib_core.ingest.tf import edges_from_msgs, tf_static_msg, transform_between
from calib_core.session import load_session
from sonarcal_cli.main import main

NS = 1_000_000_000
CAM = CameraModel(64, 48, [[60, 0, 32], [0, 60, 24], [0, 0, 1]])


def _T(seed):
    rng = np.random.default_rng(seed)
    return make_T(Rotation.from_rotvec(rng.normal(0, 0.3, 3)).as_matrix(), rng.normal(0, 0.5, 3))


def _bag(bag, T_cam_cam1: dict):
    """A ROS 1 bag: 4 scans, cam1 and the cameras of ``T_cam_cam1`` (each tied to cam1 in
    /tf_static), camera_info and a flat image per scan and camera."""
    rng = np.random.default_rng(0)
    with BagWriter(bag, "ros1") as w:
        ts = w.typestore
        for c, T in T_cam_cam1.items():
            w.write("/tf_static", rosmsg.TF_STATIC, NS // 2, tf_static_msg(ts, 0, f"{c}_optical", "cam1_optical", T, True))
        for i in range(4):
            t = (1 + i) * NS
            w.write("/sonar/points", rosmsg.POINTCLOUD2, t, rosmsg.cloud_msg(ts, t, "sonar", rng.normal(size=(20, 3)), None, True))
            for c in ("cam1", *T_cam_cam1):
                w.write(f"/{c}/camera_info", rosmsg.CAMERA_INFO, t, rosmsg.info_msg(ts, t, f"{c}_optical", CAM, True))
                w.write(f"/{c}/image_raw", rosmsg.IMAGE, t,
                        rosmsg.image_msg(ts, t, f"{c}_optical", np.full((48, 64, 3), 80, np.uint8), True))
    return bag


def test_transform_between_composes_the_tree(tmp_path):
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    T_base_a, T_base_b = _T(1), _T(2)
    msgs = [tf_static_msg(ts, 0, "base", "cam_a", T_base_a, False), tf_static_msg(ts, 0, "/base", "cam_b", T_base_b, False)]
    edges = edges_from_msgs(msgs)
    np.testing.assert_allclose(transform_between(edges, "cam_b", "cam_a"), invert_T(T_base_b) @ T_base_a, atol=1e-9)
    np.testing.assert_allclose(transform_between(edges, "base", "cam_b"), T_base_b, atol=1e-9)
    assert transform_between(edges, "cam_a", "elsewhere") is None


def test_two_camera_bag_gets_stereo_from_tf_static(tmp_path, capsys):
    T21 = _T(3)
    bag = _bag(tmp_path / "two.bag", {"cam2": T21})
    out = tmp_path / "s"
    assert main(["import", str(bag), "--out", str(out), "--diameter", "0.2", "--split", "message"]) == 0
    s = load_session(out)
    assert sorted(s.cameras) == ["cam1", "cam2"]
    np.testing.assert_allclose(s.stereo["T_cam2_cam1"], T21, atol=1e-7)
    assert yaml.safe_load((out / "session.yaml").read_text())["source"]["stereo_from"] == "/tf_static"


def test_three_camera_bag_ties_each_camera_to_the_first(tmp_path):
    """A third camera's /tf_static link was dropped: only exactly two cameras got a stereo key."""
    T21, T31 = _T(3), _T(4)
    bag = _bag(tmp_path / "three.bag", {"cam2": T21, "cam3": T31})
    out = tmp_path / "s"
    assert main(["import", str(bag), "--out", str(out), "--diameter", "0.2", "--split", "message"]) == 0
    s = load_session(out)
    assert sorted(s.cameras) == ["cam1", "cam2", "cam3"] and set(s.stereo) == {"T_cam2_cam1", "T_cam3_cam1"}
    np.testing.assert_allclose(s.stereo["T_cam2_cam1"], T21, atol=1e-7)
    np.testing.assert_allclose(s.stereo["T_cam3_cam1"], T31, atol=1e-7)
