"""Images (png/jpg, grey, 16-bit, RGBA, float) and background videos/folders."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from calib_core.errors import SessionError
from calib_core.io.images import (image_size, list_frames, load_background_frames, load_image, load_video_frames,
                                  save_image)


@pytest.fixture
def rgb():
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (30, 40, 3), dtype=np.uint8)
    img[0, 0] = (255, 0, 0)  # pure red: catches BGR/RGB swaps
    return img


@pytest.mark.parametrize("suffix", [".png", ".bmp", ".tif", ".webp"])
def test_lossless_round_trip_is_rgb(tmp_path, rgb, suffix):
    save_image(tmp_path / f"a{suffix}", rgb)
    back = load_image(tmp_path / f"a{suffix}")
    assert back.dtype == np.uint8 and back.shape == (30, 40, 3)
    np.testing.assert_array_equal(back, rgb)
    assert tuple(back[0, 0]) == (255, 0, 0)


def test_jpeg_round_trip_is_close(tmp_path):
    img = np.zeros((32, 32, 3), np.uint8)
    img[:, :] = (200, 40, 10)
    save_image(tmp_path / "a.jpg", img, jpeg_quality=95)
    back = load_image(tmp_path / "a.jpg")
    assert np.abs(back.astype(int) - img).max() < 8
    assert image_size(tmp_path / "a.jpg") == (32, 32)


def test_other_writers_grey_16bit_rgba_float(tmp_path, rgb):
    grey = rgb[:, :, 1]
    cv2.imwrite(str(tmp_path / "g.png"), grey)
    g = load_image(tmp_path / "g.png")
    assert g.shape == (30, 40, 3) and (g[:, :, 0] == grey).all() and (g[:, :, 2] == grey).all()

    bgr16 = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR).astype(np.uint16) * 257
    cv2.imwrite(str(tmp_path / "d.png"), bgr16)
    np.testing.assert_array_equal(load_image(tmp_path / "d.png"), rgb)

    bgra = np.dstack([cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), np.full((30, 40), 128, np.uint8)])
    cv2.imwrite(str(tmp_path / "a.png"), bgra)
    np.testing.assert_array_equal(load_image(tmp_path / "a.png"), rgb)

    cv2.imwrite(str(tmp_path / "f.tiff"), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR).astype(np.float32) / 255)
    f = load_image(tmp_path / "f.tiff")
    assert f.dtype == np.uint8 and np.abs(f.astype(int) - rgb).max() <= 1

    cv2.imwrite(str(tmp_path / "g16.png"), grey.astype(np.uint16) * 257)
    assert (load_image(tmp_path / "g16.png")[:, :, 0] == grey).all()


@pytest.mark.parametrize("cut", [0.3, 0.9, 0.999])
@pytest.mark.parametrize("suffix", [".png", ".jpg"])
def test_truncated_images_are_refused(tmp_path, rgb, cut, suffix):
    save_image(tmp_path / f"a{suffix}", rgb)
    data = (tmp_path / f"a{suffix}").read_bytes()
    (tmp_path / f"t{suffix}").write_bytes(data[: int(len(data) * cut)])
    with pytest.raises(SessionError) as ei:
        load_image(tmp_path / f"t{suffix}")
    assert ei.value.path == tmp_path / f"t{suffix}"


def test_missing_empty_and_garbage(tmp_path):
    with pytest.raises(SessionError, match="not found"):
        load_image(tmp_path / "nope.png")
    (tmp_path / "e.png").write_bytes(b"")
    with pytest.raises(SessionError, match="empty"):
        load_image(tmp_path / "e.png")
    (tmp_path / "r.png").write_bytes(np.random.default_rng(1).bytes(5000))
    with pytest.raises(SessionError, match="cannot decode"):
        load_image(tmp_path / "r.png")
    (tmp_path / "dir.png").mkdir()
    with pytest.raises(SessionError):
        load_image(tmp_path / "dir.png")


def test_background_folder_single_image_and_listing(tmp_path, rgb):
    for k in range(3):
        save_image(tmp_path / "bg" / f"f{k}.png", rgb)
    (tmp_path / "bg" / "notes.txt").write_text("not an image")
    (tmp_path / "bg" / ".f9.png.abc.tmp").write_bytes(b"half a file")  # a leftover atomic-write temp file
    assert [p.name for p in list_frames(tmp_path / "bg")] == ["f0.png", "f1.png", "f2.png"]
    assert len(load_background_frames(tmp_path / "bg")) == 3
    assert len(load_background_frames(tmp_path / "bg" / "f1.png")) == 1
    (tmp_path / "empty").mkdir()
    with pytest.raises(SessionError, match="holds no images"):
        load_background_frames(tmp_path / "empty")


def _write_video(path, fourcc, n=20, fps=10.0, size=(48, 32)):
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), fps, size)
    if not w.isOpened():
        return False
    for i in range(n):
        frame = np.zeros((size[1], size[0], 3), np.uint8)
        frame[:, :, 2] = 10 * i  # red grows with time (BGR in OpenCV)
        w.write(frame)
    w.release()
    return path.is_file() and path.stat().st_size > 0


@pytest.mark.parametrize("fourcc,suffix", [("mp4v", ".mp4"), ("MJPG", ".avi")])
def test_video_background(tmp_path, fourcc, suffix):
    path = tmp_path / f"bg{suffix}"
    if not _write_video(path, fourcc):
        pytest.skip(f"OpenCV here has no {fourcc} encoder for {suffix}")
    frames = load_video_frames(path, max_frames=5)
    assert 1 <= len(frames) <= 5 and frames[0].shape == (32, 48, 3) and frames[0].dtype == np.uint8
    reds = [f[:, :, 0].mean() for f in frames]
    assert reds == sorted(reds) and reds[-1] > reds[0] + 50, "frames spread over the video, in order, RGB"
    # a window: only frames from 1.0 s to 1.5 s (frames 10..15)
    win = load_background_frames(path, start_s=1.0, end_s=1.5, max_frames=60)
    assert all(90 <= f[:, :, 0].mean() <= 160 for f in win)
    with pytest.raises(SessionError, match="no frames in the window"):
        load_video_frames(path, start_s=50.0)


def test_video_missing_and_corrupt(tmp_path):
    with pytest.raises(SessionError, match="not found"):
        load_video_frames(tmp_path / "x.mp4")
    (tmp_path / "r.mp4").write_bytes(np.random.default_rng(2).bytes(3000))
    with pytest.raises(SessionError):
        load_background_frames(tmp_path / "r.mp4")


@pytest.mark.parametrize("bits", [10, 12, 16])
def test_16bit_files_holding_fewer_bits_use_their_full_scale(tmp_path, bits):
    """A 12-bit camera frame in a 16-bit PNG keeps its contrast (not 0-16 DN)."""
    full = (1 << bits) - 1
    grey = np.tile(np.linspace(0, full, 40).astype(np.uint16), (30, 1))
    cv2.imwrite(str(tmp_path / "m.png"), grey)
    back = load_image(tmp_path / "m.png")[:, :, 0].astype(int)
    expected = np.round(grey.astype(float) * 255.0 / full).astype(int)
    assert np.abs(back - expected).max() <= 1
    assert back.max() == 255


def test_a_resized_frame_gets_a_hint_to_scale_the_intrinsics(tmp_path, rgb):
    save_image(tmp_path / "half.png", rgb)  # 40 x 30
    with pytest.raises(SessionError, match=r"scaled by 0\.5: scale fx, fy, cx, cy") as ei:
        load_image(tmp_path / "half.png", expected_wh=(80, 60))
    assert "\n" not in ei.value.problem
    with pytest.raises(SessionError) as ei:
        load_image(tmp_path / "half.png", expected_wh=(80, 45))
    assert "scaled by" not in ei.value.problem
