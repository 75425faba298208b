"""Point cloud loaders: every format, our writer and other tools' writers (open3d, laspy, hand-typed text)."""

from __future__ import annotations

import numpy as np
import pytest

from calib_core.errors import SessionError
from calib_core.io.clouds import CLOUD_SUFFIXES, Cloud, load_cloud, save_cloud


@pytest.fixture
def cloud():
    rng = np.random.default_rng(0)
    pts = rng.uniform([-3, -2, 0.5], [3, 2, 9], size=(500, 3))
    return Cloud(pts, rng.uniform(0, 255, 500).round())


# float32 (PLY/PCD as the sonar writes them), 1e-6 text, 1e-4 LAS scale
TOL = {".ply": 1e-6, ".pcd": 1e-6, ".xyz": 1e-6, ".csv": 1e-6, ".txt": 1e-6, ".npy": 0, ".las": 1e-4, ".laz": 1e-4}


@pytest.mark.parametrize("suffix", [s for s in CLOUD_SUFFIXES if s != ".off"])  # .off is read-only (test_ingest_units)
@pytest.mark.parametrize("with_intensity", [True, False])
def test_round_trip(tmp_path, cloud, suffix, with_intensity):
    c = cloud if with_intensity else Cloud(cloud.points_m)
    path = tmp_path / f"c{suffix}"
    save_cloud(path, c)
    back = load_cloud(path)
    assert back.points_m.dtype == np.float64 and back.points_m.shape == (500, 3)
    np.testing.assert_allclose(back.points_m, c.points_m, atol=TOL[suffix] * 10, rtol=1e-6)
    if with_intensity:
        assert back.intensity is not None
        np.testing.assert_allclose(back.intensity, c.intensity, atol=1e-3)
    elif suffix not in (".las", ".laz"):  # LAS always has an intensity dimension
        assert back.intensity is None
    assert not list(tmp_path.glob(".*")), "no temp file left behind"


@pytest.mark.parametrize("name,ascii_,compressed", [("a.ply", True, False), ("b.ply", False, False),
                                                    ("a.pcd", True, False), ("b.pcd", False, False),
                                                    ("c.pcd", False, True)])
def test_files_written_by_open3d(tmp_path, cloud, name, ascii_, compressed):
    import open3d as o3d

    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(cloud.points_m))
    assert o3d.io.write_point_cloud(str(tmp_path / name), pc, write_ascii=ascii_, compressed=compressed)
    back = load_cloud(tmp_path / name)
    np.testing.assert_allclose(back.points_m, cloud.points_m, atol=1e-5)


@pytest.mark.parametrize("name,ascii_", [("i.ply", True), ("j.ply", False), ("i.pcd", True), ("j.pcd", False)])
def test_open3d_tensor_files_keep_intensity(tmp_path, cloud, name, ascii_):
    import open3d as o3d

    t = o3d.t.geometry.PointCloud(o3d.core.Tensor(cloud.points_m.astype(np.float32)))
    t.point.intensity = o3d.core.Tensor(cloud.intensity.astype(np.float32)[:, None])
    assert o3d.t.io.write_point_cloud(str(tmp_path / name), t, write_ascii=ascii_)
    back = load_cloud(tmp_path / name)
    np.testing.assert_allclose(back.intensity, cloud.intensity, atol=1e-3)


def test_ply_with_faces_and_double_vertices(tmp_path):
    # a mesh PLY (e.g. exported from a modeller): vertices are the points, faces ignored
    pts = np.array([[0, 0, 1.0], [1, 0, 1.0], [0, 1, 1.0], [1, 1, 1.5]])
    head = ("ply\nformat binary_little_endian 1.0\ncomment made by hand\nelement vertex 4\nproperty double x\n"
            "property double y\nproperty double z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n")
    faces = b"".join(bytes([3]) + np.array(f, "<i4").tobytes() for f in ([0, 1, 2], [1, 3, 2]))
    (tmp_path / "m.ply").write_bytes(head.encode() + pts.astype("<f8").tobytes() + faces)
    np.testing.assert_array_equal(load_cloud(tmp_path / "m.ply").points_m, pts)


def test_las_and_laz_written_by_laspy(tmp_path, cloud):
    import laspy

    for suffix in (".las", ".laz"):
        header = laspy.LasHeader(point_format=3, version="1.4")
        header.scales = np.array([0.001, 0.001, 0.001])
        header.offsets = np.array([-10.0, -10.0, 0.0])
        las = laspy.LasData(header)
        las.x, las.y, las.z = cloud.points_m.T
        las.intensity = cloud.intensity.astype(np.uint16)
        las.write(str(tmp_path / f"l{suffix}"))
        back = load_cloud(tmp_path / f"l{suffix}")
        np.testing.assert_allclose(back.points_m, cloud.points_m, atol=1e-3)
        np.testing.assert_allclose(back.intensity, cloud.intensity)


@pytest.mark.parametrize("text,n,has_intensity", [
    ("x y z\n1 2 3\n4 5 6\n", 2, False),
    ("# sonar export\n# units: m\nx,y,z,intensity\n1,2,3,10\n4,5,6,20\n", 2, True),
    ("1\t2\t3\t7\n\n4\t5\t6\t8\n", 2, True),
    ("X;Y;Z\n1;2;3\n4;5;6\n", 2, False),
    ("  1.5e0   2 3  \r\n-4 5 6\r\n", 2, False),
    ("1, 2, 3\n4, 5, 6\n# trailing comment\n", 2, False),
    ("1 2 3 9\n4 5 6\n", 2, False),  # intensity on only some rows: dropped, points kept
])
def test_text_variants(tmp_path, text, n, has_intensity):
    for suffix in (".xyz", ".csv", ".txt"):
        p = tmp_path / f"t{suffix}"
        p.write_text(text)
        c = load_cloud(p)
        assert len(c) == n
        np.testing.assert_allclose(c.points_m[-1], [-4, 5, 6] if "-4" in text else [4, 5, 6])
        assert (c.intensity is not None) == has_intensity


def test_text_with_bom_and_extra_columns(tmp_path):
    p = tmp_path / "t.csv"
    p.write_bytes("\ufeffx,y,z,intensity,r,g,b\n1,2,3,4,0,0,0\n".encode("utf-8"))
    c = load_cloud(p)
    np.testing.assert_allclose(c.points_m, [[1, 2, 3]])
    np.testing.assert_allclose(c.intensity, [4])


@pytest.mark.parametrize("arr", [np.ones((5, 3), np.float32), np.ones((5, 4)), np.arange(15, dtype=np.int16).reshape(5, 3)])
def test_npy_shapes_and_dtypes(tmp_path, arr):
    np.save(tmp_path / "a.npy", arr)
    c = load_cloud(tmp_path / "a.npy")
    assert c.points_m.shape == (5, 3) and c.points_m.dtype == np.float64
    assert (c.intensity is not None) == (arr.shape[1] == 4)


def test_nonfinite_points_rejected_or_dropped(tmp_path, cloud):
    pts = cloud.points_m.copy()
    pts[3] = np.nan
    pts[7, 1] = np.inf
    save_cloud(tmp_path / "n.npy", Cloud(pts, cloud.intensity))
    with pytest.raises(SessionError, match="2 of 500 points are NaN or infinite"):
        load_cloud(tmp_path / "n.npy", allow_nonfinite=False)
    c = load_cloud(tmp_path / "n.npy")  # "no return" rows of an organised cloud: dropped, counted
    assert len(c) == 498 and len(c.intensity) == 498 and np.isfinite(c.points_m).all()
    assert c.n_without_return == 2 and load_cloud(tmp_path / "n.npy", allow_nonfinite=True).n_without_return == 2


@pytest.mark.parametrize("suffix", [".ply", ".pcd", ".xyz", ".npy"])
def test_nan_points_in_each_format(tmp_path, suffix):
    pts = np.array([[0, 0, 1.0], [np.nan, 0, 1.0], [1, 1, 1]])
    save_cloud(tmp_path / f"n{suffix}", Cloud(pts))
    c = load_cloud(tmp_path / f"n{suffix}")
    assert len(c) == 2 and c.n_without_return == 1
    save_cloud(tmp_path / f"a{suffix}", Cloud(np.full((4, 3), np.nan)))
    with pytest.raises(SessionError, match="no return") as ei:
        load_cloud(tmp_path / f"a{suffix}")
    assert ei.value.path == tmp_path / f"a{suffix}"


def test_organised_pcd_with_nan_as_pcl_writes_it(tmp_path):
    """An organised 4 x 3 PCD (``is_dense`` false in PCL terms) whose NaN rows mean no return."""
    rows = ["1 2 3", "nan nan nan", "0.5 0.5 2", "nan nan nan"] * 3
    head = ("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n"
            "COUNT 1 1 1\nWIDTH 4\nHEIGHT 3\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 12\nDATA ascii\n")
    (tmp_path / "o.pcd").write_text(head + "\n".join(rows) + "\n")
    c = load_cloud(tmp_path / "o.pcd")
    assert len(c) == 6 and c.n_without_return == 6 and np.isfinite(c.points_m).all()


def test_unknown_suffix_and_writer_errors(tmp_path, cloud):
    (tmp_path / "c.obj").write_text("v 1 2 3\n")
    with pytest.raises(SessionError, match="unknown point cloud format"):
        load_cloud(tmp_path / "c.obj")
    with pytest.raises(SessionError, match="cannot write"):
        save_cloud(tmp_path / "c.obj", cloud)


def test_uppercase_suffix(tmp_path, cloud):
    save_cloud(tmp_path / "C.PLY", cloud)
    assert len(load_cloud(tmp_path / "C.PLY")) == 500


def test_points_at_the_sensor_origin_are_no_return(tmp_path, cloud):
    pts = cloud.points_m.copy()
    pts[:40] = 0.0  # a LiDAR driver's "no return"
    save_cloud(tmp_path / "z.npy", Cloud(pts, cloud.intensity))
    c = load_cloud(tmp_path / "z.npy")
    assert len(c) == 460 and c.n_without_return == 40 and c.points_m.any(axis=1).all() and len(c.intensity) == 460
    save_cloud(tmp_path / "zz.npy", Cloud(np.zeros((30, 3))))
    with pytest.raises(SessionError, match="no return"):
        load_cloud(tmp_path / "zz.npy")


def test_absurdly_far_points_are_no_return(tmp_path, cloud):
    """One point at 1e308 m (a corrupt value) or float32's maximum (a driver's "no return"
    marker) overflowed the sonar detector's voxel grid: an internal error instead of a cloud."""
    pts = np.vstack([cloud.points_m, [[1e308, 0.0, 1.0]], [[3.4e38, 3.4e38, 3.4e38]]])
    np.save(tmp_path / "far.npy", pts)
    c = load_cloud(tmp_path / "far.npy")
    assert len(c) == len(cloud.points_m) and c.n_without_return == 2 and np.abs(c.points_m).max() < 1e3
    with pytest.raises(SessionError, match="2 of 502 points are NaN or infinite"):
        load_cloud(tmp_path / "far.npy", allow_nonfinite=False)
    np.save(tmp_path / "all_far.npy", np.full((10, 3), 1e308))
    with pytest.raises(SessionError, match="no return"):
        load_cloud(tmp_path / "all_far.npy")


def test_complex_npy_is_refused(tmp_path, cloud):
    """Complex numbers used to be cast to their real part with a ComplexWarning on stderr."""
    np.save(tmp_path / "c.npy", cloud.points_m.astype(np.complex128))
    with pytest.raises(SessionError, match=r"number array, got complex128"):
        load_cloud(tmp_path / "c.npy")
