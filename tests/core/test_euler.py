"""YZZ′ Euler angles (R = R_z(yaw)·R_y(pitch)·R_z(roll)) and the singular-pitch convention."""

import numpy as np
import pytest

from addon.core.errors import InputError
from addon.core.kinematics.euler import matrix_to_yzz, pose_from_xyz_yzz, pose_to_xyz_yzz, yzz_to_matrix
from addon.core.kinematics.transforms import rot_y, rot_z


def reference(yaw, pitch, roll):
    """The definition, composed from elementary rotations."""
    return (rot_z(yaw) @ rot_y(pitch) @ rot_z(roll))[:3, :3]


def test_matrix_matches_definition():
    rng = np.random.default_rng(1)
    for yaw, pitch, roll in rng.uniform(-4, 4, size=(200, 3)):
        np.testing.assert_allclose(yzz_to_matrix(yaw, pitch, roll), reference(yaw, pitch, roll), atol=1e-15)


def test_known_orientation_tool_pointing_down():
    # Pitch 180° turns the tool's Z (approach axis) to point straight down.
    R = yzz_to_matrix(0.0, np.pi, 0.0)
    np.testing.assert_allclose(R @ [0, 0, 1], [0, 0, -1], atol=1e-15)


def test_round_trip_general_angles_and_ranges():
    rng = np.random.default_rng(2)
    for yaw, pitch, roll in zip(rng.uniform(-np.pi, np.pi, 500), rng.uniform(1e-3, np.pi - 1e-3, 500),
                                rng.uniform(-np.pi, np.pi, 500)):
        y, p, r = matrix_to_yzz(reference(yaw, pitch, roll))
        assert 0.0 <= p <= np.pi and -np.pi < y <= np.pi and -np.pi < r <= np.pi
        np.testing.assert_allclose([y, p, r], [yaw, pitch, roll], atol=1e-12)


def test_negative_pitch_returns_equivalent_positive_form():
    # (yaw, −p, roll) ≡ (yaw + π, p, roll + π), wrapped into (−π, π].
    y, p, r = matrix_to_yzz(reference(0.3, -0.8, 0.2))
    assert (y, p, r) == pytest.approx((0.3 - np.pi, 0.8, 0.2 - np.pi), abs=1e-14)
    np.testing.assert_allclose(reference(y, p, r), reference(0.3, -0.8, 0.2), atol=1e-15)


@pytest.mark.parametrize("pitch", [0.0, np.pi])
def test_singular_pitch_convention_roll_zero(pitch):
    # Only yaw + roll (pitch 0) or yaw − roll (pitch π) is defined; roll is set to 0.
    yaw, roll = 0.7, -0.4
    y, p, r = matrix_to_yzz(reference(yaw, pitch, roll))
    assert r == 0.0
    assert p == pitch
    total = yaw + roll if pitch == 0.0 else yaw - roll
    assert y == pytest.approx(total, abs=1e-15)
    np.testing.assert_allclose(reference(y, p, r), reference(yaw, pitch, roll), atol=1e-15)


@pytest.mark.parametrize("pitch", [1e-13, 1e-10, 1e-7, np.pi - 1e-10, np.pi - 1e-13])
def test_near_singular_round_trip_reproduces_matrix(pitch):
    # Above the singular threshold (sin pitch ≥ 1e-12) the angles reproduce R to
    # rounding; below it pitch snaps to 0 or π, which costs at most ~2·sin(pitch).
    R = reference(1.1, pitch, -2.5)
    y, p, r = matrix_to_yzz(R)
    assert np.max(np.abs(reference(y, p, r) - R)) <= max(1e-14, 2.5 * np.sin(pitch))


def test_pose_round_trip_and_errors():
    T = pose_from_xyz_yzz([10, -20, 30], [0.1, 0.2, 0.3])
    xyz, yzz = pose_to_xyz_yzz(T)
    np.testing.assert_allclose(xyz, [10, -20, 30])
    np.testing.assert_allclose(yzz, [0.1, 0.2, 0.3], atol=1e-15)
    with pytest.raises(InputError, match="finite"):
        pose_from_xyz_yzz([0, 0, np.nan], [0, 0, 0])
    with pytest.raises(InputError, match="yaw"):
        yzz_to_matrix(np.inf, 0, 0)
    with pytest.raises(InputError):
        matrix_to_yzz(np.diag([1.0, 1.0, 2.0]))
