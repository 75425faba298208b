"""Rigid transform helpers in calib_core.geometry."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from calib_core.geometry import (invert_T, look_at_T_cam_world, make_T, pose_error, rotation_angle_rad,
                                 rotvec_from_T, T_from_rotvec, transform_points)


def random_T(seed):
    rng = np.random.default_rng(seed)
    return make_T(Rotation.random(random_state=seed).as_matrix(), rng.normal(size=3))


@pytest.mark.parametrize("seed", range(5))
def test_invert_and_compose(seed):
    T = random_T(seed)
    np.testing.assert_allclose(T @ invert_T(T), np.eye(4), atol=1e-12)
    np.testing.assert_allclose(invert_T(T), np.linalg.inv(T), atol=1e-12)


def test_transform_points_convention_X_a_equals_R_X_b_plus_t():
    T_a_b = random_T(1)
    X_b = np.random.default_rng(2).normal(size=(10, 3))
    X_a = transform_points(T_a_b, X_b)
    np.testing.assert_allclose(X_a, (T_a_b[:3, :3] @ X_b.T).T + T_a_b[:3, 3])
    np.testing.assert_allclose(transform_points(invert_T(T_a_b), X_a), X_b, atol=1e-12)
    assert transform_points(T_a_b, [1.0, 2.0, 3.0]).shape == (1, 3)


def test_rotvec_round_trip():
    rv = np.array([0.3, -1.1, 0.4])
    T = T_from_rotvec(rv, [1, 2, 3])
    np.testing.assert_allclose(rotvec_from_T(T), rv, atol=1e-12)
    np.testing.assert_allclose(T[:3, 3], [1, 2, 3])
    assert rotation_angle_rad(T[:3, :3]) == pytest.approx(np.linalg.norm(rv))


def test_rotation_angle_extremes_stay_in_range():
    assert rotation_angle_rad(np.eye(3)) == 0.0
    assert rotation_angle_rad(np.diag([1.0, -1.0, -1.0])) == pytest.approx(np.pi)
    # slightly non-orthonormal input must not give NaN
    assert np.isfinite(rotation_angle_rad(np.eye(3) * (1 + 1e-12)))


def test_pose_error():
    T = random_T(3)
    dT = T_from_rotvec([0, 0, 0.01], [0.003, 0.004, 0])
    r, t = pose_error(dT @ T, T)
    assert r == pytest.approx(0.01, abs=1e-12)
    assert t == pytest.approx(np.linalg.norm((dT @ T)[:3, 3] - T[:3, 3]))


def test_look_at_puts_target_on_the_optical_axis():
    eye, target = np.array([1.0, -2.0, 0.5]), np.array([0.2, 0.3, -0.4])
    T_cam_world = look_at_T_cam_world(eye, target)
    p = transform_points(T_cam_world, target)[0]
    np.testing.assert_allclose(p[:2], 0, atol=1e-12)
    assert p[2] == pytest.approx(np.linalg.norm(target - eye))
    R = T_cam_world[:3, :3]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    # world up (+z) appears as image up (-y in OpenCV) for a level camera
    T_level = look_at_T_cam_world([0, 0, 0], [1, 0, 0])
    up_cam = T_level[:3, :3] @ np.array([0, 0, 1.0])
    assert up_cam[1] < -0.99


def test_look_at_straight_up_is_still_rigid():
    T = look_at_T_cam_world([0, 0, 0], [0, 0, 5])
    R = T[:3, :3]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(transform_points(T, [0, 0, 5])[0], [0, 0, 5], atol=1e-12)
