"""The numpy reader of binary PLY / PCD gives open3d's points and intensities exactly."""

from __future__ import annotations

import numpy as np
import pytest

from calib_core.io.clouds import _read_open3d, load_cloud
from calib_core.io.cloud_headers import check_cloud_header


def _o3d_cloud(n=500, seed=3, dtype="float32"):
    import open3d as o3d

    rng = np.random.default_rng(seed)
    pc = o3d.t.geometry.PointCloud()
    pc.point.positions = o3d.core.Tensor(rng.normal(size=(n, 3)).astype(dtype))
    pc.point.intensity = o3d.core.Tensor(rng.uniform(0, 255, size=(n, 1)).astype("float32"))
    return pc


@pytest.mark.parametrize("name,dtype", [("a.ply", "float32"), ("b.ply", "float64"), ("c.pcd", "float32"),
                                        ("d.pcd", "float64")])
def test_numpy_reader_matches_open3d(tmp_path, name, dtype):
    import open3d as o3d

    path = tmp_path / name
    o3d.t.io.write_point_cloud(str(path), _o3d_cloud(dtype=dtype), write_ascii=False)
    ours = load_cloud(path)
    pts, inten = _read_open3d(path, check_cloud_header(path))
    np.testing.assert_array_equal(ours.points_m, np.asarray(pts, np.float64))
    np.testing.assert_array_equal(ours.intensity, np.asarray(inten, np.float64).reshape(-1))


def test_big_endian_ply_and_padding_field_pcd(tmp_path):
    pts = np.arange(12, dtype=float).reshape(4, 3) / 7
    head = "ply\nformat binary_big_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n" \
           "property float z\nproperty uchar red\nend_header\n"
    rows = np.zeros(4, dtype=[("x", ">f4"), ("y", ">f4"), ("z", ">f4"), ("r", "u1")])
    rows["x"], rows["y"], rows["z"] = pts.T
    (tmp_path / "be.ply").write_bytes(head.encode() + rows.tobytes())
    np.testing.assert_array_equal(load_cloud(tmp_path / "be.ply").points_m, pts.astype("f4").astype(float))
    head = ("VERSION .7\nFIELDS x _ y z _ intensity\nSIZE 4 1 4 4 2 4\nTYPE F U F F U F\nCOUNT 1 1 1 1 1 1\n"
            "WIDTH 4\nHEIGHT 1\nPOINTS 4\nDATA binary\n")
    rows = np.zeros(4, dtype=[("x", "<f4"), ("p", "u1"), ("y", "<f4"), ("z", "<f4"), ("q", "<u2"), ("i", "<f4")])
    rows["x"], rows["y"], rows["z"] = pts.T
    rows["i"] = [1, 2, 3, 4]
    (tmp_path / "p.pcd").write_bytes(head.encode() + rows.tobytes())
    c = load_cloud(tmp_path / "p.pcd")
    np.testing.assert_array_equal(c.points_m, pts.astype("f4").astype(float))
    np.testing.assert_array_equal(c.intensity, [1, 2, 3, 4])


def test_ply_without_xyz_is_refused(tmp_path):
    from calib_core.errors import SessionError

    head = "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float a\nproperty float b\n" \
           "property float c\nend_header\n"
    (tmp_path / "n.ply").write_bytes(head.encode() + np.zeros(6, "<f4").tobytes())
    with pytest.raises(SessionError, match="not a point cloud"):
        load_cloud(tmp_path / "n.ply")
