"""Checkerboard intrinsics and stereo on images rendered here through the lens model."""

from __future__ import annotations

import argparse

import cv2
import numpy as np
import pytest
import yaml

from calib_core.camera import CameraModel
from calib_core.geometry import look_at_T_cam_world, make_T, pose_error
from calib_core.io.images import save_image
from calib_core.io.intrinsics import load_intrinsics
from calib_core.solve.checkerboard import calibrate_intrinsics, calibrate_stereo, parse_pattern
from calib_core.errors import SessionError

PATTERN = (9, 6)
SQUARE = 0.03


class Renderer:
    """Renders a planar checkerboard through a CameraModel: each pixel's ray, from the exact
    inverse lens model, is intersected with the board plane. Edges are anti-aliased with a
    ramp one pixel footprint wide (sin(pi u) clipped), which keeps the corners unbiased."""

    def __init__(self, cam: CameraModel):
        self.cam = cam
        u, v = np.meshgrid(np.arange(cam.width_px, dtype=float), np.arange(cam.height_px, dtype=float))
        xy = cam.normalize(np.column_stack([u.ravel(), v.ravel()]))
        self.rays = np.column_stack([xy, np.ones(len(xy))])
        self.ray_len = np.linalg.norm(self.rays, axis=1)
        self.shape = (cam.height_px, cam.width_px)

    def render(self, T_cam_board: np.ndarray) -> np.ndarray:
        R, t = T_cam_board[:3, :3], T_cam_board[:3, 3]
        img = np.full(self.shape, 120, np.uint8)
        # only the pixels inside the projected board (with its white margin) need work
        edge = np.array([[x, y, 0.0] for x in (-2.5 * SQUARE, (PATTERN[0] + 1.5) * SQUARE)
                         for y in (-2.5 * SQUARE, (PATTERN[1] + 1.5) * SQUARE)])
        uv = self.cam.project(edge @ R.T + t)
        u0, v0 = np.clip(np.floor(uv.min(axis=0)) - 3, 0, None).astype(int)
        u1, v1 = np.minimum(np.ceil(uv.max(axis=0)) + 3, [self.shape[1] - 1, self.shape[0] - 1]).astype(int)
        idx = (np.arange(v0, v1 + 1)[:, None] * self.shape[1] + np.arange(u0, u1 + 1)[None, :]).ravel()
        rays = self.rays[idx]
        n = R[:, 2]
        lam = (n @ t) / (rays @ n)
        B = (rays * lam[:, None] - t) @ R  # board coordinates (m)
        w = np.maximum(lam, 1e-3) * self.ray_len[idx] / (self.cam.fx * SQUARE)  # pixel footprint in squares
        ramp = lambda q: np.clip(np.sin(np.pi * q) / (np.pi * w), -1, 1)  # noqa: E731
        bx, by = B[:, 0] / SQUARE, B[:, 1] / SQUARE
        check = -ramp(bx) * ramp(by)  # +1 white, -1 black, square (0,0) black
        inside = (bx >= -1) & (bx <= PATTERN[0]) & (by >= -1) & (by <= PATTERN[1]) & (lam > 0)
        val = np.where(inside, 127.5 + 107.5 * check, 235.0)
        margin = (bx > -2.5) & (bx < PATTERN[0] + 1.5) & (by > -2.5) & (by < PATTERN[1] + 1.5) & (lam > 0)
        img.ravel()[idx] = np.clip(np.where(margin, val, 120.0), 0, 255).astype(np.uint8)
        return np.repeat(img[:, :, None], 3, axis=2)


def board_poses(rng, n):
    """Board poses (T_cam_board) around 0.5-0.9 m, tilted, spread over the view."""
    centre = np.array([(PATTERN[0] - 1) * SQUARE / 2, (PATTERN[1] - 1) * SQUARE / 2, 0.0])
    out = []
    for _ in range(n):
        d = rng.uniform(0.5, 0.85)
        eye = np.array([rng.uniform(-0.25, 0.25), rng.uniform(-0.2, 0.2), -d])  # camera seen from the board
        T_cam_world = look_at_T_cam_world(eye, [rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05), 0], up_world=(0, -1, 0))
        # shift the board in the view so that the boards together cover most of the image
        T_cam_world[:3, 3] += [rng.uniform(-0.12, 0.12) * d, rng.uniform(-0.08, 0.08) * d, 0.0]
        T_world_board = make_T(np.eye(3), -centre)
        out.append(T_cam_world @ T_world_board)
    return out


CAM = CameraModel(640, 480, [[560.0, 0, 322.0], [0, 558.0, 236.0], [0, 0, 1]], [-0.18, 0.07, 0.0008, -0.0005, 0.0], "cam1")


T21 = make_T(cv2.Rodrigues(np.radians([0.5, -3.0, 0.8]))[0], [-0.12, 0.004, 0.01])


@pytest.fixture(scope="module")
def boards():
    """12 board poses rendered in camera 1 and, where the whole board is in view, in camera 2 (T21)."""
    r = Renderer(CAM)
    rng = np.random.default_rng(5)
    out = []
    for i, T in enumerate(board_poses(rng, 12)):
        T2 = T21 @ T
        corners = (T2 @ np.array([[-SQUARE, -SQUARE, 0, 1.0], [PATTERN[0] * SQUARE, PATTERN[1] * SQUARE, 0, 1]]).T).T
        both = CAM.in_image(CAM.project(corners[:, :3]), margin_px=5).all()
        out.append((f"b{i:02d}", r.render(T), r.render(T2) if both else None))
    return out


def test_parse_pattern():
    assert parse_pattern("9x6") == (9, 6)
    with pytest.raises(SessionError):
        parse_pattern("nine by six")


def test_intrinsics_recovered_from_rendered_boards(boards):
    images = [(n, a) for n, a, _ in boards] + [("blank", np.full((480, 640, 3), 120, np.uint8))]
    res = calibrate_intrinsics(images, PATTERN, SQUARE, name="cam1")
    assert "blank" in res.skipped and len(res.per_image_rms_px) >= 10
    assert res.rms_px < 0.3 and max(res.per_image_rms_px.values()) < 0.5
    assert abs(res.cam.fx - CAM.fx) / CAM.fx < 0.01 and abs(res.cam.fy - CAM.fy) / CAM.fy < 0.01
    assert abs(res.cam.cx - CAM.cx) < 4 and abs(res.cam.cy - CAM.cy) < 4
    # the lens model as a whole: pixels of rays across the covered view agree within a pixel
    xy = CAM.normalize(np.array([[90.0, 70.0], [550, 80], [320, 240], [100, 410], [540, 400]]))
    assert np.max(np.abs(res.cam.distort(xy) - CAM.distort(xy))) < 1.0


def test_too_few_boards_is_a_clear_error():
    blank = np.full((480, 640, 3), 120, np.uint8)
    with pytest.raises(SessionError, match="checkerboard was found in only 0"):
        calibrate_intrinsics([("a", blank), ("b", blank)], PATTERN, SQUARE)


def test_stereo_transform_recovered(boards):
    pairs = [(n, a, b) for n, a, b in boards if b is not None]
    assert len(pairs) >= 5
    res = calibrate_stereo(pairs, CAM, CAM, PATTERN, SQUARE)
    dr, dt = pose_error(res.T_cam2_cam1, T21)
    assert np.degrees(dr) < 0.15 and dt < 0.002
    assert res.rms_px < 0.3 and np.all(np.linalg.eigvalsh(res.cov) > 0)
    # the approximate covariance is of the right order: the error is within a few sigma
    e = np.concatenate([np.radians(0) + cv2.Rodrigues(res.T_cam2_cam1[:3, :3] @ T21[:3, :3].T)[0].ravel(),
                        res.T_cam2_cam1[:3, 3] - T21[:3, 3]])
    assert np.all(np.abs(e) < 6 * np.sqrt(np.diag(res.cov)) + 1e-5)


def test_cli_intrinsics_and_stereo(boards, tmp_path):
    from sonarcal_cli.commands import intrinsics as cmd_intrinsics, stereo as cmd_stereo

    (tmp_path / "c1").mkdir()
    (tmp_path / "c2").mkdir()
    for n, a, b in boards:
        save_image(tmp_path / "c1" / f"{n}.png", a)
        if b is not None:
            save_image(tmp_path / "c2" / f"{n}.png", b)
    sub = argparse.ArgumentParser().add_subparsers()
    cmd_intrinsics.add_parser(sub)
    cmd_stereo.add_parser(sub)
    parser = sub._name_parser_map
    a = parser["intrinsics"].parse_args([str(tmp_path / "c1"), "--pattern", "9x6", "--square", str(SQUARE),
                                         "--out", str(tmp_path / "cam1.yaml")])
    assert a.run(a) == 0
    cam = load_intrinsics(tmp_path / "cam1.yaml")
    assert abs(cam.fx - CAM.fx) / CAM.fx < 0.01 and cam.name == "cam1"
    b = parser["stereo"].parse_args([str(tmp_path / "c1"), str(tmp_path / "c2"), "--square", str(SQUARE),
                                     "--intrinsics1", str(tmp_path / "cam1.yaml"),
                                     "--intrinsics2", str(tmp_path / "cam1.yaml"), "--out", str(tmp_path / "st.yaml")])
    assert b.run(b) == 0
    doc = yaml.safe_load((tmp_path / "st.yaml").read_text())
    T = np.asarray(doc["T_cam2_cam1"])
    assert np.linalg.norm(T[:3, 3] - T21[:3, 3]) < 0.003 and np.asarray(doc["cov_T_cam2_cam1"]).shape == (6, 6)
    bad = parser["intrinsics"].parse_args([str(tmp_path / "nope"), "--square", "0.03", "--out", str(tmp_path / "x.yaml")])
    with pytest.raises(SessionError):
        bad.run(bad)
    assert not (tmp_path / "x.yaml").exists()
