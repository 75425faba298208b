"""``sonarcal import`` on bad input: one line naming the bag and the problem, exit 2, nothing written."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from calib_core.camera import CameraModel
from calib_core.ingest import rosmsg
from calib_core.ingest.bagwrite import BagWriter
from sonarcal_cli.main import main

NS = 1_000_000_000
CAM = CameraModel(64, 48, [[60, 0, 32], [0, 60, 24], [0, 0, 1]])


def _bag(path: Path, kind="ros1", images=True, compressed_data=None, encoding="rgb8") -> Path:
    rng = np.random.default_rng(0)
    with BagWriter(path, kind) as w:
        ts, r1 = w.typestore, w.ros1
        for i in range(6):
            t = (1 + i) * NS
            w.write("/sonar/points", rosmsg.POINTCLOUD2, t,
                    rosmsg.cloud_msg(ts, t, "sonar", rng.normal(size=(50, 3)), None, r1))
            if not images:
                continue
            w.write("/cam1/camera_info", rosmsg.CAMERA_INFO, t, rosmsg.info_msg(ts, t, "cam1", CAM, r1))
            if compressed_data is not None:
                msg = ts.types[rosmsg.COMPRESSED](header=rosmsg.header_msg(ts, t, "cam1", r1), format="jpeg",
                                                  data=np.frombuffer(compressed_data, np.uint8))
                w.write("/cam1/image_raw/compressed", rosmsg.COMPRESSED, t, msg)
            else:
                msg = rosmsg.image_msg(ts, t, "cam1", np.full((48, 64, 3), 90, np.uint8), r1)
                msg.encoding = encoding
                w.write("/cam1/image_raw", rosmsg.IMAGE, t, msg)
    return path


def _run(capsys, *args) -> tuple[int, str]:
    rc = main(["import", *map(str, args)])
    err = capsys.readouterr().err.strip()
    return rc, err


def _assert_nothing_written(parent: Path, before: set) -> None:
    assert set(p.name for p in parent.iterdir()) == before


@pytest.mark.parametrize("case, args, expect", [
    ("unknown topic", ["--sonar-topic", "/nope"], "unknown topic '/nope'"),
    ("unknown camera topic", ["--camera-topic", "/cam9/image"], "unknown topic '/cam9/image'"),
    ("wrong topic type", ["--sonar-topic", "/cam1/image_raw"], "expected sensor_msgs/msg/PointCloud2"),
])
def test_topic_errors(tmp_path, capsys, case, args, expect):
    bag = _bag(tmp_path / "a.bag")
    before = {p.name for p in tmp_path.iterdir()}
    rc, err = _run(capsys, bag, "--out", tmp_path / "s", "--diameter", 0.2, *args)
    assert rc == 2 and len(err.splitlines()) == 1, err
    assert str(bag) in err and expect in err
    _assert_nothing_written(tmp_path, before)


@pytest.mark.parametrize("kind", ["ros1", "ros2"])
def test_bag_without_images(tmp_path, capsys, kind):
    bag = _bag(tmp_path / ("a.bag" if kind == "ros1" else "a"), kind, images=False)
    rc, err = _run(capsys, bag, "--out", tmp_path / "s", "--diameter", 0.2)
    assert rc == 2 and "no camera images" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "s").exists()


def test_undecodable_compressed_image(tmp_path, capsys):
    bag = _bag(tmp_path / "a.bag", compressed_data=b"this is not a jpeg at all")
    before = {p.name for p in tmp_path.iterdir()}
    rc, err = _run(capsys, bag, "--out", tmp_path / "s", "--diameter", 0.2, "--split", "message")
    assert rc == 2 and len(err.splitlines()) == 1, err
    assert "/cam1/image_raw/compressed" in err and "cannot be decoded" in err
    _assert_nothing_written(tmp_path, before)


def test_unsupported_encoding(tmp_path, capsys):
    bag = _bag(tmp_path / "a.bag", encoding="yuv422")
    rc, err = _run(capsys, bag, "--out", tmp_path / "s", "--diameter", 0.2, "--split", "message")
    assert rc == 2 and "yuv422" in err and len(err.splitlines()) == 1


@pytest.mark.parametrize("kind", ["ros1", "ros2"])
def test_truncated_bag(tmp_path, capsys, kind):
    bag = _bag(tmp_path / ("a.bag" if kind == "ros1" else "a"), kind)
    data_file = bag if kind == "ros1" else next(bag.glob("*.mcap"))
    raw = data_file.read_bytes()
    data_file.write_bytes(raw[: len(raw) * 6 // 10])
    before = {p.name for p in tmp_path.iterdir()}
    rc, err = _run(capsys, bag, "--out", tmp_path / "s", "--diameter", 0.2)
    assert rc == 2 and len(err.splitlines()) == 1, err
    assert "truncated or corrupt" in err and str(bag) in err
    _assert_nothing_written(tmp_path, before)


def test_not_a_bag_and_missing(tmp_path, capsys):
    txt = tmp_path / "notes.txt"
    txt.write_text("hello")
    rc, err = _run(capsys, txt, "--out", tmp_path / "s", "--diameter", 0.2)
    assert rc == 2 and "not a bag" in err
    rc, err = _run(capsys, tmp_path / "nope.bag", "--out", tmp_path / "s", "--diameter", 0.2)
    assert rc == 2 and "bag not found" in err


def test_output_must_be_new(tmp_path, capsys):
    bag = _bag(tmp_path / "a.bag")
    out = tmp_path / "s"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    rc, err = _run(capsys, bag, "--out", out, "--diameter", 0.2)
    assert rc == 2 and "not an empty folder" in err
    assert [p.name for p in out.iterdir()] == ["keep.txt"]


def test_missing_diameter_and_list(tmp_path, capsys):
    bag = _bag(tmp_path / "a.bag")
    rc, err = _run(capsys, bag, "--out", tmp_path / "s")
    assert rc == 2 and "--diameter" in err
    assert main(["import", str(bag), "--list"]) == 0
    out = capsys.readouterr().out
    assert "/sonar/points" in out and "PointCloud2" in out and "6" in out


def test_small_bag_imports_one_cloud_per_scan(tmp_path, capsys):
    """Whole-scan clouds 1 s apart, one frame each: --split message makes six captures."""
    bag = _bag(tmp_path / "a.bag")
    rc = main(["import", str(bag), "--out", str(tmp_path / "s"), "--diameter", "0.2", "--split", "message"])
    assert rc == 0
    import yaml

    man = yaml.safe_load((tmp_path / "s" / "session.yaml").read_text())
    assert [c["id"] for c in man["captures"]] == [f"p{i:02d}" for i in range(1, 7)]
    assert man["source"]["scan_split"] == "one PointCloud2 per scan"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


@pytest.mark.parametrize("kind, suffix", [("ros2-db3", ".db3"), ("ros2", ".mcap")])
def test_ros2_storage_file_path_and_compressed_frames(tmp_path, capsys, kind, suffix):
    """A ROS 2 bag given by its .db3 / .mcap file; JPEG CompressedImage frames decode."""
    import cv2

    frame = np.zeros((48, 64, 3), np.uint8)
    frame[:, :32] = 200
    ok, jpg = cv2.imencode(".jpg", frame)
    bag = _bag(tmp_path / "b", kind, compressed_data=jpg.tobytes())
    data_file = next(bag.glob(f"*{suffix}"))
    out = tmp_path / "s"
    assert main(["import", str(data_file), "--out", str(out), "--diameter", "0.2", "--split", "message"]) == 0
    from calib_core.io.images import load_image
    from calib_core.session import load_session

    s = load_session(out)
    img = load_image(s.captures[0].image_paths["cam1"])
    assert img.shape == (48, 64, 3) and abs(int(img[10, 5, 0]) - 200) < 8 and int(img[10, 60, 0]) < 8
    assert s.raw["source"]["cameras"]["cam1"]["image_topic"] == "/cam1/image_raw/compressed"


def test_camera_info_topic_without_messages_and_bad_name(tmp_path, capsys):
    bag = tmp_path / "a.bag"
    with BagWriter(bag, "ros1") as w:
        ts = w.typestore
        w.connection("/cam1/camera_info", rosmsg.CAMERA_INFO)  # declared, never published
        for i in range(3):
            t = (1 + i) * NS
            w.write("/sonar/points", rosmsg.POINTCLOUD2, t, rosmsg.cloud_msg(ts, t, "s", np.ones((5, 3)), None, True))
            w.write("/cam1/image_raw", rosmsg.IMAGE, t, rosmsg.image_msg(ts, t, "c", np.zeros((48, 64, 3), np.uint8), True))
    rc, err = _run(capsys, bag, "--out", tmp_path / "s", "--diameter", 0.2)
    assert rc == 2 and "no CameraInfo message for camera cam1" in err and "--intrinsics" in err
    rc, err = _run(capsys, bag, "--out", tmp_path / "s", "--diameter", 0.2, "--camera-topic", "../x=/cam1/image_raw")
    assert rc == 2 and "camera name" in err
    assert not (tmp_path / "s").exists()


def test_synth_writes_a_bag_beside_the_session(tmp_path, capsys):
    out = tmp_path / "q"
    assert main(["synth", str(out), "--preset", "quick", "--scale", "0.1", "--bag", "ros1"]) == 0
    bag = tmp_path / "q.bag"
    assert bag.is_file() and not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    capsys.readouterr()
    assert main(["import", str(bag), "--list"]) == 0
    listing = capsys.readouterr().out
    assert "/sonar/points" in listing and "/cam1/image_raw" in listing
    rc = main(["synth", str(tmp_path / "q2"), "--preset", "quick", "--scale", "0.1", "--bag", "ros1",
               "--bag-path", str(bag)])
    assert rc == 2 and "exists already" in capsys.readouterr().err


def _camchain(path: Path) -> Path:
    """A two-camera Kalibr camchain: cam0 is not our camera (fx 500), cam1 is (fx 61)."""
    def entry(f):
        return {"camera_model": "pinhole", "intrinsics": [f, f, 32.0, 24.0], "distortion_model": "radtan",
                "distortion_coeffs": [0.0, 0.0, 0.0, 0.0], "resolution": [64, 48], "rostopic": "/x/image_raw"}
    import yaml

    path.write_text(yaml.safe_dump({"cam0": entry(500.0), "cam1": entry(61.0)}))
    return path


def test_intrinsics_entry_names_the_camchain_entry(tmp_path, capsys):
    """``--intrinsics cam1=chain.yaml --intrinsics-entry cam1=cam1`` takes that entry of the camchain;
    without it, a camchain whose entries name no camera is refused (no guess)."""
    from calib_core.io.intrinsics import load_intrinsics
    from calib_core.session import load_session

    bag, chain = _bag(tmp_path / "a.bag"), _camchain(tmp_path / "chain.yaml")
    rc, err = _run(capsys, bag, "--out", tmp_path / "s", "--diameter", 0.2, "--split", "message",
                   "--intrinsics", f"cam1={chain}")
    assert rc == 2 and "chain.yaml" in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "s").exists()
    rc, err = _run(capsys, bag, "--out", tmp_path / "s", "--diameter", 0.2, "--split", "message",
                   "--intrinsics", f"cam1={chain}", "--intrinsics-entry", "cam2=cam1")
    assert rc == 2 and "--intrinsics-entry" in err, err
    rc, err = _run(capsys, bag, "--out", tmp_path / "s", "--diameter", 0.2, "--split", "message",
                   "--intrinsics", f"cam1={chain}", "--intrinsics-entry", "cam1=cam1")
    assert rc == 0, err
    cam = load_intrinsics(load_session(tmp_path / "s").cameras["cam1"].intrinsics_path)
    assert cam.K[0, 0] == pytest.approx(61.0)
