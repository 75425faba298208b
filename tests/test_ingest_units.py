"""Scan splitting, motion figures and the ProScan .off reader."""

from __future__ import annotations

import numpy as np
import pytest

from calib_core.camera import CameraModel
from calib_core.errors import SessionError
from calib_core.ingest.motion import Track, capture_motion, motion_of, motion_summary_rows
from calib_core.ingest.scans import NS, scan_index, split_scans
from calib_core.io.clouds import load_cloud

CAM = CameraModel(640, 480, [[500, 0, 320], [0, 500, 240], [0, 0, 1]])


def _slices(starts_s, n=30, dt=0.5):
    return [int((s + i * dt) * NS) for s in starts_s for i in range(n)]


def test_gap_split_finds_each_pan():
    w, rule = split_scans(_slices([0, 40, 80]))
    assert len(w) == 3 and "pauses" in rule
    assert [x.n_messages for x in w] == [30, 30, 30]
    assert w[1].start_ns == 40 * NS and w[1].end_ns == int(54.5 * NS)
    assert scan_index(w, int(45 * NS)) == 1 and scan_index(w, int(30 * NS)) == -1


def test_scan_seconds_cuts_a_continuous_stream():
    w, rule = split_scans(_slices([0], n=120), scan_seconds=15)
    assert len(w) == 4 and all(x.n_messages == 30 for x in w) and "every 15 s" in rule


def test_whole_scan_messages_and_explicit_split():
    t = [int(s * NS) for s in (60, 120, 180, 240)]
    w, rule = split_scans(t)
    assert rule == "one PointCloud2 per scan" and len(w) == 4
    assert w[1].start_ns == t[0] + 1 and w[1].end_ns == t[1] and w[0].start_ns == 0
    w, _ = split_scans(t, split="message", scan_seconds=30)
    assert w[2].start_ns == 150 * NS
    w, _ = split_scans(_slices([0, 40]), split="gap", gap_seconds=100)
    assert len(w) == 1
    with pytest.raises(ValueError):
        split_scans(t, split="bogus")


class _Det:
    def __init__(self, uv, r=20.0, rng=2.0):
        self.found, self.center_uv_px, self.radius_px, self.range_m = uv is not None, uv, r, rng


def test_motion_px_and_metres():
    tr = Track()
    for i, u in enumerate([300, 305, 310, 315, 320]):
        tr.add(i, _Det(np.array([u, 240.0])))
    m = motion_of(tr, 2, CAM)
    assert m["motion_px"] == pytest.approx(10.0)
    assert m["motion_m"] == pytest.approx(10 / 500 * 2.0, rel=0.01)  # 10 px at f=500 px, 2 m away
    ent = capture_motion({"cam1": tr}, {"cam1": 2}, {"cam1": CAM}, 3.0, 0.02)
    assert ent["moved"] is True
    ent = capture_motion({"cam1": tr}, {"cam1": 2}, {"cam1": CAM}, 20.0, 0.05)
    assert ent["moved"] is False
    rows = motion_summary_rows({"tolerance_px": 3.0, "tolerance_m": 0.02, "captures": {"p01": ent}})
    assert rows[0][:3] == ["p01", "cam1", "5/5"] and rows[0][-1] == "still"


def test_motion_with_missed_frames():
    tr = Track()
    tr.add(0, _Det(None))
    tr.add(1, _Det(np.array([100.0, 100.0])))
    m = motion_of(tr, 1, CAM)
    assert m["found"] == 1 and m["motion_px"] is None
    assert capture_motion({"c": tr}, {"c": 1}, {"c": CAM}, 3, 0.02)["moved"] is False


def _write(path, text):
    path.write_text(text)
    return path


def test_off_reads_points_and_intensity(tmp_path):
    rng = np.random.default_rng(1)
    pts = rng.normal(size=(1000, 3))
    rgb = rng.integers(0, 256, (1000, 3))
    rows = "\n".join(f"{x:.6f} {y:.6f} {z:.6f} {r} {g} {b} 255" for (x, y, z), (r, g, b) in zip(pts, rgb))
    c = load_cloud(_write(tmp_path / "a.off", f"COFF\n1000 0 0\n{rows}\n"))
    np.testing.assert_allclose(c.points_m, pts, atol=1e-6)
    np.testing.assert_allclose(c.intensity, rgb.mean(axis=1))


@pytest.mark.parametrize("text, expect", [
    ("PLY\n1 0 0\n1 2 3 4 5 6 7\n", "first line must be OFF"),
    ("OFF\n1 0\n1 2 3 4 5 6 7\n", "three counts"),
    ("OFF\n0 0 0\n", "no points"),
    ("OFF\n4 0 0\n1 2 3 4 5 6 7\n2 3 4 5 6 7 8\n1 1 1 1 1 1 1\n", "truncated"),
    ("OFF\n2 0 0\n1 2 3 4 5 6\n1 2 3 4 5 6\n", "7 numbers"),
    ("OFF\n2 0 0\n1 2 3 4 5 6 7\n1 2 x 4 5 6 7\n", "bad point row"),
    ("OFF\n1 0 0\n1 2 3 4 5 6 7\n1 2 3 4 5 6 7\n", "more rows"),
    ("OFF\n1 0 0\nnan 2 3 4 5 6 7\n", "NaN"),
])
def test_off_strict(tmp_path, text, expect):
    with pytest.raises(SessionError) as e:
        load_cloud(_write(tmp_path / "bad.off", text))
    assert expect in str(e.value) and "bad.off" in str(e.value)


def test_off_huge_count_is_refused_before_allocating(tmp_path):
    with pytest.raises(SessionError, match="more than the"):
        load_cloud(_write(tmp_path / "big.off", "OFF\n900000000000 0 0\n1 2 3 4 5 6 7\n"))
    with pytest.raises(SessionError, match="too small"):
        load_cloud(_write(tmp_path / "small.off", "OFF\n90000 0 0\n1 2 3 4 5 6 7\n"))


def test_camera_names_from_topics():
    from calib_core.ingest.bag import camera_name

    assert camera_name("/cam1/image_raw", set()) == "cam1"
    assert camera_name("/cam1/image_raw/compressed", set()) == "cam1"
    assert camera_name("/stereo/left/image_raw", set()) == "stereo_left"
    assert camera_name("/camera/color/image_raw", set()) == "camera"
    assert camera_name("/image_raw", set()) == "cam"
    assert camera_name("/cam1/image_raw", {"cam1"}) == "cam1_2"
    assert camera_name("/we ird:name/image", set()) == "we_ird_name"


def test_mono16_message_is_scaled_as_a_16bit_file(tmp_path):
    """A 12-bit camera's mono16 frame from a bag gets the grey levels the same frame gets from a
    16-bit PNG (one rule: calib_core.io.images.to_uint8_16), not 0-16 DN."""
    from types import SimpleNamespace

    import cv2

    from calib_core.ingest.rosmsg import image_from_msg
    from calib_core.io.images import load_image

    grey = np.tile(np.linspace(100, 4000, 40).astype(np.uint16), (30, 1))
    msg = SimpleNamespace(encoding="mono16", height=30, width=40, step=80, is_bigendian=0,
                          data=np.frombuffer(grey.astype("<u2").tobytes(), np.uint8))
    from_bag = image_from_msg(msg, "sensor_msgs/msg/Image")
    cv2.imwrite(str(tmp_path / "g.png"), grey)
    np.testing.assert_array_equal(from_bag, load_image(tmp_path / "g.png"))
    assert from_bag.max() == 249


def test_compressed_16bit_png_message_is_scaled_as_a_16bit_file(tmp_path):
    from types import SimpleNamespace

    import cv2

    from calib_core.ingest.rosmsg import image_from_msg
    from calib_core.io.images import load_image

    grey = np.tile(np.linspace(100, 4000, 40).astype(np.uint16), (30, 1))
    ok, buf = cv2.imencode(".png", grey)
    msg = SimpleNamespace(format="mono16; png compressed", data=buf.ravel())
    from_bag = image_from_msg(msg, "sensor_msgs/msg/CompressedImage")
    cv2.imwrite(str(tmp_path / "g.png"), grey)
    np.testing.assert_array_equal(from_bag, load_image(tmp_path / "g.png"))
