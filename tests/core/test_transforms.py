"""Homogeneous transforms: elementary matrices, rigid inverse, validation, long chains."""

import numpy as np
import pytest

from addon.core.errors import InputError
from addon.core.kinematics.transforms import (
    check_transform,
    make_pose,
    orthonormality_error,
    orthonormalize,
    rigid_inverse,
    rot_x,
    rot_y,
    rot_z,
    rotation_angle,
    rotation_vector,
    trans,
    transform_points,
)


def axis_angle(axis, angle):
    """Rodrigues' formula, written out independently of the module under test."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


@pytest.mark.parametrize("fn,axis", [(rot_x, 0), (rot_y, 1), (rot_z, 2)])
def test_elementary_rotations_match_rodrigues(fn, axis):
    for angle in (0.3, -2.1, np.pi, 7.0):
        e = np.zeros(3)
        e[axis] = 1
        T = fn(angle)
        assert T.shape == (4, 4)
        np.testing.assert_allclose(T[:3, :3], axis_angle(e, angle), atol=1e-15)
        np.testing.assert_array_equal(T[3], [0, 0, 0, 1])
        np.testing.assert_array_equal(T[:3, 3], 0)


def test_right_angles_are_exact():
    # A 90° twist must give exact zeros, not 6e-17, so DH axes stay orthogonal.
    T = rot_x(np.pi / 2)
    assert T[1, 1] == 0.0 and T[2, 2] == 0.0 and T[2, 1] == 1.0 and T[1, 2] == -1.0
    assert rot_z(-np.pi / 2)[0, 0] == 0.0 and rot_z(np.pi)[0, 0] == -1.0


def test_batched_rotations_and_translations():
    angles = np.linspace(-3, 3, 7)
    Rs = rot_z(angles)
    assert Rs.shape == (7, 4, 4)
    for a, R in zip(angles, Rs):
        np.testing.assert_allclose(R, rot_z(a), atol=0)
    T = trans([[1, 2, 3], [4, 5, 6]])
    assert T.shape == (2, 4, 4)
    np.testing.assert_array_equal(T[1, :3, 3], [4, 5, 6])
    np.testing.assert_array_equal(trans(1, 2, 3)[:3, 3], [1, 2, 3])
    with pytest.raises(InputError):
        trans([1, 2])


def test_rigid_inverse_is_exact_inverse():
    rng = np.random.default_rng(3)
    for _ in range(50):
        T = make_pose(axis_angle(rng.normal(size=3), rng.uniform(-np.pi, np.pi)), rng.normal(scale=500, size=3))
        Ti = rigid_inverse(T)
        np.testing.assert_allclose(Ti @ T, np.eye(4), atol=1e-12)
        np.testing.assert_allclose(Ti, np.linalg.inv(T), atol=1e-12)
    stack = np.stack([rot_x(0.2) @ trans(1, 2, 3), rot_z(1.0) @ trans(-5, 0, 2)])
    np.testing.assert_allclose(rigid_inverse(stack) @ stack, np.broadcast_to(np.eye(4), (2, 4, 4)), atol=1e-14)


def test_transform_points():
    T = trans(10, 0, 0) @ rot_z(np.pi / 2)
    np.testing.assert_allclose(transform_points(T, [[1, 0, 0], [0, 1, 0]]), [[10, 1, 0], [9, 0, 0]], atol=1e-15)


@pytest.mark.parametrize(
    "bad,fragment",
    [
        (np.full((4, 4), np.nan), "NaN"),
        (np.diag([2.0, 1, 1, 1]), "not orthonormal"),
        (np.array([[1, 0.1, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]]), "not orthonormal"),
        (np.diag([-1.0, 1, 1, 1]), "reflection"),
        (np.eye(3), "shape"),
        (np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [1, 0, 0, 1.0]]), "bottom row"),
        ("abc", "numbers"),
    ],
)
def test_check_transform_rejects_with_clear_message(bad, fragment):
    with pytest.raises(InputError, match=fragment) as info:
        check_transform(bad, "probe mount")
    assert "probe mount" in str(info.value) or fragment == "numbers"


def test_check_transform_accepts_rounded_config_values():
    R = axis_angle([1, 2, 3], 0.7).round(7)  # what a hand-typed config holds
    check_transform(make_pose(R, [1, 2, 3]))


def test_rotation_angle_and_vector_accurate_near_zero_and_pi():
    for angle in (1e-12, 1e-7, 0.5, np.pi - 1e-9, np.pi):
        axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
        R = axis_angle(axis, angle)
        assert abs(rotation_angle(R) - angle) < 1e-15 + 1e-12 * angle
        v = rotation_vector(R)
        if angle < np.pi:
            np.testing.assert_allclose(v, axis * angle, atol=1e-13, rtol=1e-9)
        else:  # at π the axis sign is arbitrary
            np.testing.assert_allclose(np.abs(v), np.abs(axis) * np.pi, atol=1e-7)


def test_orthonormalize_returns_nearest_rotation():
    rng = np.random.default_rng(0)
    R = axis_angle([1, 1, 0], 0.4)
    noisy = R + 1e-6 * rng.normal(size=(3, 3))
    Rn = orthonormalize(noisy)
    assert orthonormality_error(Rn) < 4e-15
    assert np.linalg.det(Rn) > 0
    assert np.max(np.abs(Rn - R)) < 1e-5
    T = make_pose(noisy, [1, 2, 3])
    Tn = orthonormalize(T)
    np.testing.assert_array_equal(Tn[:3, 3], [1, 2, 3])
    assert orthonormality_error(Tn) < 4e-15


def test_million_chained_products_stay_orthonormal_and_on_target():
    # 10^6 small rotations about one fixed axis compose to one rotation by the sum
    # of the angles (ground truth from geometry), with a translation step each time.
    axis = np.array([0.2, -0.7, 0.4])
    step_angle = 2.3e-5
    step = make_pose(axis_angle(axis, step_angle), [0.0, 0.0, 0.0])
    n = 1_000_000
    T = np.eye(4)
    drift_before = 0.0
    for i in range(1, n + 1):
        T = T @ step
        if i % 1000 == 0:
            drift_before = max(drift_before, float(orthonormality_error(T)))
            T = orthonormalize(T)
    assert orthonormality_error(T) < 1e-12
    expected = axis_angle(axis, n * step_angle)
    assert np.max(np.abs(T[:3, :3] - expected)) < 1e-9
    assert drift_before < 1e-12  # re-orthonormalising every 1000 products is enough
