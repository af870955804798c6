"""Forward kinematics (Eq. 1–3), link frames, Jacobian and the bundled robots."""

import numpy as np
import pytest

from addon.core.errors import InputError
from addon.core.kinematics.robot import Robot
from addon.core.config.rigs import load_robot
from addon.core.kinematics.transforms import rot_x, rot_z, rotation_vector, trans

ROBOTS = ["adept_viper_s650", "puma560", "ur5"]


def literal_fk(robot, q):
    """Eq. 1–3 written out with elementary transforms, independently of Robot.fk."""
    T = robot.base.copy()
    for i in range(6):
        T = T @ rot_z(q[i] + robot.theta_offset_rad[i]) @ trans(robot.a_mm[i], 0, robot.d_mm[i]) @ rot_x(robot.alpha_rad[i])
    return T @ robot.tool


@pytest.fixture(params=ROBOTS)
def robot(request):
    return load_robot(request.param)


def test_bundled_rigs_hold_the_published_tables():
    viper = load_robot("adept_viper_s650")
    np.testing.assert_array_equal(viper.a_mm, [75, 270, 90, 0, 0, 0])
    np.testing.assert_array_equal(viper.d_mm, [335, 0, 0, 295, 0, 80])
    np.testing.assert_allclose(np.degrees(viper.alpha_rad), [-90, 0, -90, 90, -90, 0])
    np.testing.assert_allclose(np.degrees(viper.theta_offset_rad), [0, -90, 0, 0, 0, 180])
    np.testing.assert_allclose(np.degrees(viper.q_min_rad), [-170, -45, -256, -190, -120, -360])
    np.testing.assert_allclose(np.degrees(viper.q_max_rad), [170, 190, 29, 190, 120, 360])
    puma = load_robot("puma560")
    np.testing.assert_array_equal(puma.a_mm, [0, 431.8, 20.3, 0, 0, 0])
    np.testing.assert_array_equal(puma.d_mm, [671.83, 0, 150.05, 431.8, 0, 0])
    np.testing.assert_allclose(np.degrees(puma.q_min_rad), [-160, -45, -225, -110, -100, -266])
    ur5 = load_robot("ur5")
    np.testing.assert_array_equal(ur5.a_mm, [0, -425, -392.25, 0, 0, 0])
    np.testing.assert_array_equal(ur5.d_mm, [89.159, 0, 0, 109.15, 94.65, 82.3])
    np.testing.assert_allclose(np.degrees(ur5.alpha_rad), [90, 0, 0, 90, -90, 0])
    np.testing.assert_allclose(np.degrees(ur5.q_max_rad), [360] * 6)


def test_fk_matches_literal_product(robot):
    rng = np.random.default_rng(7)
    for q in rng.uniform(-7, 7, size=(50, 6)):  # beyond ±2π on purpose
        np.testing.assert_allclose(robot.fk(q), literal_fk(robot, q), atol=1e-10)


def test_batch_fk_equals_single(robot):
    rng = np.random.default_rng(8)
    qs = robot.random_q(300, rng)
    Ts = robot.fk(qs)
    assert Ts.shape == (300, 4, 4)
    for q, T in zip(qs[:40], Ts[:40]):
        np.testing.assert_allclose(T, robot.fk(q), atol=1e-10)
    assert robot.fk(qs[:1]).shape == (1, 4, 4)
    assert robot.fk(np.zeros((0, 6))).shape == (0, 4, 4)


def test_angles_beyond_two_pi_are_periodic(robot):
    q = np.radians([10, 20, -30, 40, 50, 60])
    np.testing.assert_allclose(robot.fk(q + 2 * np.pi * np.array([1, -2, 3, 0, 5, -7])), robot.fk(q), atol=1e-9)


def test_puma_zero_pose_matches_corke():
    # Robotics Toolbox puma560 at qz: t = (0.4521, -0.1501, 0.4318) m with d1 = 0
    # and R = I; our rig includes the 671.83 mm base height in d1.
    T = load_robot("puma560").fk(np.zeros(6))
    np.testing.assert_allclose(T[:3, 3], [452.1, -150.05, 431.8 + 671.83], atol=1e-9)
    np.testing.assert_allclose(T[:3, :3], np.eye(3), atol=1e-15)


def test_ur5_zero_pose_by_hand():
    # Stretched horizontally: x = a2 + a3, y = −(d4 + d6), z = d1 − d5.
    T = load_robot("ur5").fk(np.zeros(6))
    np.testing.assert_allclose(T[:3, 3], [-425 - 392.25, -(109.15 + 82.3), 89.159 - 94.65], atol=1e-9)


def test_viper_link_origins_at_zero_by_hand():
    # q = 0 (θ2 = −90°): up 335 and forward 75 to joint 2, up 270 to joint 3,
    # up 90 to the elbow axis line, forward 295 to the wrist centre, forward 80 to the flange.
    frames = load_robot("adept_viper_s650").link_frames(np.zeros(6))
    assert frames.shape == (7, 4, 4)
    expected = [[0, 0, 0], [75, 0, 335], [75, 0, 605], [75, 0, 695], [370, 0, 695], [370, 0, 695], [450, 0, 695]]
    np.testing.assert_allclose(frames[:, :3, 3], expected, atol=1e-12)
    np.testing.assert_allclose(frames[6, :3, 2], [1, 0, 0], atol=1e-15)  # flange faces forward


def test_link_frames_chain_and_batch(robot):
    rng = np.random.default_rng(9)
    qs = robot.random_q(5, rng)
    F = robot.link_frames(qs)
    assert F.shape == (5, 7, 4, 4)
    for q, frames in zip(qs, F):
        np.testing.assert_allclose(frames, robot.link_frames(q), atol=1e-12)
        np.testing.assert_allclose(frames[-1] @ robot.tool, robot.fk(q), atol=1e-12)
        A = robot.link_transforms(q)
        for i in range(6):
            np.testing.assert_allclose(frames[i] @ A[i], frames[i + 1], atol=1e-10)


def test_tool_and_base_transforms(robot):
    tool = trans(0, 0, 120) @ rot_x(0.3)
    base = trans(100, -50, 20) @ rot_z(0.5)
    mounted = robot.with_tool(tool).with_base(base)
    q = np.radians([5, 15, -25, 35, 45, 55])
    np.testing.assert_allclose(mounted.fk(q), base @ robot.fk(q) @ tool, atol=1e-10)
    np.testing.assert_allclose(mounted.flange_fk(q), base @ robot.flange_fk(q), atol=1e-10)
    np.testing.assert_allclose(mounted.fk(np.array([q, q]))[1], mounted.fk(q), atol=1e-10)
    assert robot.tool is not mounted.tool  # with_tool returns a new robot, the old one unchanged
    np.testing.assert_array_equal(robot.tool, np.eye(4))


def test_jacobian_matches_finite_differences(robot):
    robot = robot.with_tool(trans(10, -5, 60))
    rng = np.random.default_rng(10)
    h = 1e-6
    for q in robot.random_q(10, rng):
        J = robot.jacobian(q)
        T0 = robot.fk(q)
        for i in range(6):
            dq = np.zeros(6)
            dq[i] = h
            Tp, Tm = robot.fk(q + dq), robot.fk(q - dq)
            v = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
            w = (rotation_vector(Tp[:3, :3] @ T0[:3, :3].T) - rotation_vector(Tm[:3, :3] @ T0[:3, :3].T)) / (2 * h)
            np.testing.assert_allclose(J[:3, i], v, atol=1e-6 * robot.length_scale_mm)
            np.testing.assert_allclose(J[3:, i], w, atol=1e-8)


def test_manipulability_and_condition_at_singularities():
    viper = load_robot("adept_viper_s650")
    generic = np.radians([10, 40, -60, 30, 45, 20])
    wrist = generic.copy()
    wrist[4] = 0.0  # axes 4 and 6 aligned
    assert viper.manipulability(generic) > 1e-3
    assert np.isfinite(viper.condition_number(generic))
    assert viper.manipulability(wrist) < 1e-12
    assert viper.condition_number(wrist) > 1e12
    ur5 = load_robot("ur5")
    stretched = np.radians([30, -60, 0, -90, 45, 10])  # q3 = 0: elbow fully stretched
    assert ur5.manipulability(stretched) < 1e-12
    # Near a singularity the measures degrade smoothly, not abruptly.
    near = wrist.copy()
    near[4] = 1e-4
    assert 0 < viper.manipulability(near) < viper.manipulability(generic)


@pytest.mark.parametrize(
    "q,fragment",
    [
        ([0, 0, np.nan, 0, 0, 0], "finite"),
        ([0, 0, 0, np.inf, 0, 0], "finite"),
        ([0, 0, 0], "shape"),
        ("abc", "numbers"),
        (np.zeros((2, 3, 6)), "shape"),
    ],
)
def test_bad_joint_vectors_are_refused(q, fragment):
    with pytest.raises(InputError, match=fragment):
        load_robot("puma560").fk(q)


def test_limit_helpers():
    viper = load_robot("adept_viper_s650")
    q = np.radians([0, 0, 0, 0, 130, 0])
    assert not viper.within_limits(q)
    (msg,) = viper.limit_violations(q)
    assert "J5" in msg and "130" in msg and "120" in msg
    assert viper.within_limits(np.zeros(6))
    assert viper.within_limits(np.array([np.zeros(6), q])).tolist() == [True, False]
    # A hair beyond a limit of ±3.14159 rad (a URDF's ±pi to six figures) reads as beyond it.
    from dataclasses import replace

    tight = replace(viper, q_min_rad=np.full(6, -3.14159), q_max_rad=np.full(6, 3.14159))
    (msg,) = tight.limit_violations(np.array([0.0, 0.0, 0.0, -np.pi, 0.0, 0.0]))
    assert msg == "J4 = -180.0000° outside [-179.9998°, 179.9998°]"


def test_robot_constructor_validates():
    good = dict(name="t", a_mm=[0] * 6, d_mm=[0] * 6, alpha_rad=[0] * 6, theta_offset_rad=[0] * 6,
                q_min_rad=[-1] * 6, q_max_rad=[1] * 6)
    Robot(**good)
    with pytest.raises(InputError, match="shape"):
        Robot(**{**good, "a_mm": [0] * 5})
    with pytest.raises(InputError, match="NaN"):
        Robot(**{**good, "d_mm": [0, 0, np.nan, 0, 0, 0]})
    with pytest.raises(InputError, match="joint 2 limits"):
        Robot(**{**good, "q_min_rad": [-1, 2, -1, -1, -1, -1]})
    with pytest.raises(InputError, match="tool"):
        Robot(**good, tool=np.diag([1, 1, 2, 1.0]))


def test_waypoints_take_what_check_transform_takes_and_refuse_what_it_refuses():
    """One rule for a rigid pose (a review: the waypoints' own, stricter test refused scans whose
    probe mount check_transform had taken, 9e-7 off orthonormal)."""
    from addon.core.kinematics.path import Waypoints
    from addon.core.kinematics.transforms import check_transform

    near = np.eye(4)
    near[:3, :3] *= 1.0 + 4.5e-7  # RᵀR − I ≈ 9e-7, det − 1 ≈ 1.35e-6
    check_transform(near)
    assert len(Waypoints(near[None], np.zeros(1), np.zeros(1, int))) == 1
    for bad in (np.diag([1.0, 1.0, 1.0 + 1e-5, 1.0]), np.diag([1.0, 1.0, -1.0, 1.0])):
        with pytest.raises(InputError):
            check_transform(bad)
        with pytest.raises(InputError, match="waypoint 0's pose is not a rigid transform"):
            Waypoints(bad[None], np.zeros(1), np.zeros(1, int))
