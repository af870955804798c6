"""The armature rig reproduces the core's DH frames, probe and camera poses (Blender is float32)."""

from pathlib import Path

import numpy as np
import pytest

from addon.core.kinematics.cell import Cell
from addon.core.config.rigs import load_robot
from addon.core.config.rigs import load_probe
from addon.scene.cell import build_cell

GANTRY = str(Path(__file__).resolve().parents[2] / "rigs" / "robots" / "urdf" / "gantry.urdf")
POS_TOL_MM = 1e-3
ROT_TOL = 1e-5  # rad, as a bound on rotation-matrix entries


def check(scene_cell, q):
    robot, probe = scene_cell.cell.robot, scene_cell.probe
    frames = scene_cell.dh_frames_mm()
    expect = robot.link_frames(q)
    assert np.abs(frames[:, :3, 3] - expect[:, :3, 3]).max() < POS_TOL_MM
    assert np.abs(frames[:, :3, :3] - expect[:, :3, :3]).max() < ROT_TOL
    T = robot.fk(q)  # tool = probe mount T_L^6
    got = scene_cell.probe_to_world_mm()
    assert np.abs(got[:3, 3] - T[:3, 3]).max() < POS_TOL_MM and np.abs(got[:3, :3] - T[:3, :3]).max() < ROT_TOL
    for camera in (0, 1):
        C = T @ probe.cam2probe(camera)
        got = scene_cell.camera_to_world_mm(camera)
        assert np.abs(got[:3, 3] - C[:3, 3]).max() < POS_TOL_MM
        assert np.abs(got[:3, :3] - C[:3, :3]).max() < ROT_TOL


@pytest.mark.parametrize("name", ["adept_viper_s650", "puma560", "ur5", GANTRY])
def test_rig_matches_core_for_200_random_poses_set_directly_and_keyframed(scene, name):
    sc = build_cell(scene, Cell(load_robot(name)), load_probe("default"))
    rng = np.random.default_rng(3)
    qs = sc.cell.robot.random_q(200, rng)
    for q in qs:
        sc.pose(q)
        check(sc, q)
    frames = sc.keyframe(qs, np.zeros(len(qs)))
    for frame, q in zip(frames, qs):
        scene.frame_set(frame)
        check(sc, q)


def test_each_bone_turns_only_about_its_joint_axis(scene):
    sc = build_cell(scene, Cell(load_robot("puma560")), load_probe("default"))
    for k in range(1, 7):
        pb = sc.robot.pose.bones[f"J{k}"]
        assert tuple(pb.lock_rotation) == (True, False, True)
        (limit,) = [c for c in pb.constraints if c.type == "LIMIT_ROTATION"]
        assert limit.use_limit_y and not limit.use_limit_x and not limit.use_limit_z
        assert limit.min_y == pytest.approx(sc.cell.robot.q_min_rad[k - 1])
        assert limit.max_y == pytest.approx(sc.cell.robot.q_max_rad[k - 1])


def test_sliding_joints_move_their_bones_along_the_axis_within_limits(scene):
    """The gantry's first three joints slide (mm in the property, metres in Blender)."""
    pytest.importorskip("yourdfpy", reason="installed by the README's set-up")
    sc = build_cell(scene, Cell(load_robot(GANTRY)), load_probe("default"))
    robot = sc.cell.robot
    for k in range(1, 4):
        pb = sc.robot.pose.bones[f"J{k}"]
        assert tuple(pb.lock_location) == (True, False, True) and tuple(pb.lock_rotation) == (True, True, True)
        (limit,) = [c for c in pb.constraints if c.type == "LIMIT_LOCATION"]
        assert limit.min_y == pytest.approx(robot.q_min_rad[k - 1] * 1e-3)
        assert limit.max_y == pytest.approx(robot.q_max_rad[k - 1] * 1e-3)
    q = np.array([250.0, -120.0, -300.0, 0.4, -0.8, 1.2])
    sc.pose(q)
    check(sc, q)
    beyond = q.copy()
    beyond[0] = 900.0  # travel ends at 600 mm: Blender's constraint holds the bridge there
    sc.pose(beyond)
    beyond[0] = 600.0
    np.testing.assert_allclose(sc.dh_frames_mm(), robot.link_frames(beyond), atol=1e-3)


def test_limit_rotation_clamps_joints_beyond_their_limits(scene):
    sc = build_cell(scene, Cell(load_robot("adept_viper_s650")), load_probe("default"))
    q = np.radians([10, 60, -80, 30, 150, 40])  # J5 limit is ±120°
    sc.pose(q)
    clamped = q.copy()
    clamped[4] = np.radians(120)
    got = sc.dh_frames_mm()
    np.testing.assert_allclose(got, sc.cell.robot.link_frames(clamped), atol=1e-3)
    # Ranges wider than ±180° (J2: −45…190°, J3: −256…29°) are honoured, not folded.
    q = np.radians([0, 185, -250, 0, 10, 0])
    sc.pose(q)
    np.testing.assert_allclose(sc.dh_frames_mm(), sc.cell.robot.link_frames(q), atol=1e-3)


def test_joint_properties_carry_limits_for_the_ui(scene):
    sc = build_cell(scene, Cell(load_robot("ur5")), load_probe("default"))
    ui = sc.robot.id_properties_ui("q3").as_dict()
    assert ui["subtype"] == "ANGLE"
    assert ui["min"] == pytest.approx(-2 * np.pi) and ui["max"] == pytest.approx(2 * np.pi)
