"""Rotary table (Eq. 4–5) and the probe-to-table transform of Eq. 8, settled by round trips."""

import numpy as np
import pytest

from addon.core.kinematics.cell import Cell
from addon.core.errors import InputError
from addon.core.kinematics.euler import pose_from_xyz_yzz
from addon.core.config.rigs import load_robot
from addon.core.kinematics.transforms import rigid_inverse, rot_z, transform_points, trans
from addon.core.kinematics.turntable import Turntable


def test_eq4_and_eq5_are_inverse_and_match_the_paper():
    table = Turntable()
    assert (table.a_mm, table.d_mm) == (-500.0, -200.0)
    for theta in (0.0, 0.4, -2.0, 7.5):
        np.testing.assert_allclose(table.base2table(theta) @ table.table2base(theta), np.eye(4), atol=1e-13)
        # Eq. 5 written out: T(500, 0, 200)·R_Z(θ).
        np.testing.assert_allclose(table.table2base(theta), trans(500, 0, 200) @ rot_z(theta), atol=1e-13)
        np.testing.assert_allclose(table.base2table(theta), rigid_inverse(trans(500, 0, 200) @ rot_z(theta)), atol=1e-13)


def test_table_turns_points_counter_clockwise_about_its_centre():
    table = Turntable()
    p = transform_points(table.table2base(np.pi / 2), [100.0, 0.0, 10.0])
    np.testing.assert_allclose(p, [500.0, 100.0, 210.0], atol=1e-12)


def test_placement_is_configurable_and_batched():
    table = Turntable(a_mm=-700, d_mm=50)
    np.testing.assert_allclose(table.table2base(0.0)[:3, 3], [700, 0, -50])
    thetas = np.linspace(0, 2 * np.pi, 5)
    assert table.base2table(thetas).shape == (5, 4, 4)


@pytest.mark.parametrize("kwargs", [dict(a_mm=np.nan), dict(d_mm="far"), dict(a_mm=True)])
def test_bad_placement(kwargs):
    with pytest.raises(InputError, match="turntable"):
        Turntable(**kwargs)


def test_bad_angle():
    with pytest.raises(InputError, match="table angle"):
        Turntable().base2table(np.nan)


def looking_down_at(point_table, theta, stand_off=150.0, yaw=0.3):
    """Probe pose in the table frame with its beam (+Z) pointing down at a table point."""
    return pose_from_xyz_yzz(np.asarray(point_table) + [0, 0, stand_off], [yaw, np.pi, 0.0])


@pytest.mark.parametrize("robot_name", ["adept_viper_s650", "puma560", "ur5"])
def test_eq8_round_trip_table_point_to_probe_and_back(robot_name):
    """A point fixed on the workpiece, seen by the probe, must come back to the same table coordinates.

    The probe measures the point in its own frame; which transform takes that
    measurement back to the table settles the reading of Eq. 8.
    """
    cell = Cell(load_robot(robot_name))
    point_table = np.array([40.0, -25.0, 30.0])
    for theta in (0.0, 0.9, -2.4):
        res = cell.ik(looking_down_at(point_table, theta), relative_to="table", table_angle_rad=theta)
        assert res.success, res.message
        # Physics: where the point is in the world, and where it is seen from the probe.
        world = transform_points(cell.table.table2base(theta), point_table)
        seen = transform_points(rigid_inverse(cell.probe2base(res.q)), world)
        np.testing.assert_allclose(seen, [0, 0, 150], atol=1e-6)  # on the beam, 150 mm out
        # Eq. 8 done right: T_0^R · T_DK.
        back = transform_points(cell.probe2table(res.q, theta), seen)
        np.testing.assert_allclose(back, point_table, atol=1e-6)
        # The product as printed in the paper, T_R^0 · T_DK, lands elsewhere.
        printed = transform_points(cell.table.table2base(theta) @ cell.probe2base(res.q), seen)
        assert np.linalg.norm(printed - point_table) > 100.0


def test_turning_the_table_does_not_move_the_workpiece_frame():
    cell = Cell(load_robot("adept_viper_s650"))
    point_table = np.array([-30.0, 55.0, 20.0])
    recovered = []
    for theta in np.linspace(0, 2 * np.pi, 7)[:-1]:
        # Probe fixed in the world; the point comes round with the table.
        world = transform_points(cell.table.table2base(theta), point_table)
        T = pose_from_xyz_yzz(world + [0, 0, 150], [0.0, np.pi, 0.0])
        res = cell.ik(T)
        assert res.success, res.message
        seen = transform_points(rigid_inverse(cell.probe2base(res.q)), world)
        recovered.append(transform_points(cell.probe2table(res.q, theta), seen))
    np.testing.assert_allclose(recovered, np.tile(point_table, (6, 1)), atol=1e-6)


def test_probe2table_batches_over_joint_vectors_and_angles():
    cell = Cell(load_robot("puma560"))
    rng = np.random.default_rng(4)
    qs = cell.robot.random_q(5, rng)
    thetas = rng.uniform(-3, 3, 5)
    batch = cell.probe2table(qs, thetas)
    for q, th, T in zip(qs, thetas, batch):
        np.testing.assert_allclose(T, cell.probe2table(q, th), atol=1e-10)


def test_cartesian_target_frames():
    cell = Cell(load_robot("puma560"))
    T = looking_down_at([0, 0, 0], 0.5)
    np.testing.assert_allclose(cell.target_in_base(T, "table", 0.5), cell.table.table2base(0.5) @ T)
    np.testing.assert_array_equal(cell.target_in_base(T, "base"), T)
    with pytest.raises(InputError, match="relative_to"):
        cell.target_in_base(T, "world")


def test_how_near_a_mesh_comes_to_the_table_axis_counts_its_faces_not_only_its_corners():
    import math

    import trimesh

    from addon.core.kinematics.turntable import nearest_to_axis_mm

    bar = trimesh.creation.box([400.0, 20.0, 20.0])  # across the table, its ends beyond the rim
    bar.apply_translation([0.0, 60.0, 10.0])
    assert nearest_to_axis_mm(bar) == pytest.approx(50.0)  # its near side, y = 50; every corner is > 200 away
    far = trimesh.creation.box([40.0, 40.0, 40.0])
    far.apply_translation([400.0, 0.0, 20.0])
    assert nearest_to_axis_mm(far) == pytest.approx(380.0)
    assert nearest_to_axis_mm(trimesh.creation.box([40.0, 40.0, 40.0])) == 0.0  # over the axis
    ring = trimesh.creation.annulus(r_min=50.0, r_max=60.0, height=10.0, sections=64)
    assert nearest_to_axis_mm(ring) == pytest.approx(50.0 * math.cos(math.pi / 64), abs=1e-6)  # the inner chords


@pytest.mark.parametrize("libigl", [True, False])
def test_points_are_measured_against_the_whole_drawn_disc_top_side_and_bottom(libigl, monkeypatch):
    """The side's points were measured against the top's plane (13 mm off for a point 13 mm
    down the rim). Ground truth: the drawn disc is a prism on a regular 128-gon of radius
    150 mm, 20 mm thick, whose flat sides lie at R cos(π/128) through their middles."""
    from addon.core.kinematics.turntable import TABLE_RADIUS_MM, TABLE_SECTIONS, TABLE_THICKNESS_MM
    from addon.core.scan.outputs import table_distances

    if not libigl:  # a Python without it (distances unsigned): the side's inner points kept their sign
        from addon.core.geometry import metrics

        monkeypatch.setattr(metrics, "has_inside", lambda mesh: False)

    R, T = TABLE_RADIUS_MM, TABLE_THICKNESS_MM
    inner = R * np.cos(np.pi / TABLE_SECTIONS)
    # The middle of one side face: find its direction from the drawn mesh's vertices.
    from addon.core.kinematics.turntable import table_top_mesh

    v = table_top_mesh().vertices
    rim = v[np.isclose(np.hypot(v[:, 0], v[:, 1]), R)]
    a0 = np.sort(np.unique(np.round(np.arctan2(rim[:, 1], rim[:, 0]), 9)))[:2].mean()  # between two corners
    side = np.array([np.cos(a0), np.sin(a0)])
    pts = np.array([
        [10.0, -20.0, 0.3],                       # above the top: 0.3
        [40.0, 30.0, -0.002],                     # just inside the top: -0.002
        [*(side * (inner + 0.004)), -13.0],       # 4 µm outside the side, 13 mm down
        [*(side * (inner - 0.003)), -7.0],        # 3 µm inside the side
        [0.0, 50.0, -T - 0.01],                   # 10 µm under the bottom
        [*(side * (inner + 0.2)), 0.2],           # beyond the top's edge, outside: to the edge
        [*(side * (R + 5.0)), -5.0],              # beyond the rim: not the table's
    ])
    unsigned, signed = table_distances(pts)
    expect = np.array([0.3, -0.002, 0.004, -0.003, 0.01, np.hypot(0.2, 0.2)])
    np.testing.assert_allclose(signed[:6], expect, atol=1e-9)
    np.testing.assert_allclose(unsigned[:6], np.abs(expect), atol=1e-9)
    assert np.isinf(unsigned[6])


@pytest.mark.parametrize("probe_mm, beam", [
    ([12.0, 0.0, 210.0], [0.0, 0.0, -1.0]),        # from above, a little off the axis
    ([200.0, 120.0, 60.0], [-200.0, -120.0, 0.0]),  # level, aimed at the axis (its line fell back to x: a ring)
    ([300.0, 0.0, 60.0], [-1.0, 0.0, 0.0]),         # level along x (x was the beam itself: refused)
    ([150.0, -90.0, 200.0], [-150.0, 90.0, -140.0]),  # tilted, aimed at the axis
])
def test_a_turns_default_laser_plane_holds_the_tables_axis(probe_mm, beam):
    """docs/scans.md: without `line`, a turn's laser plane holds the table's axis, so each
    profile is a meridian. Ground truth: the plane through the laser (the probe's origin)
    spanned by the beam and the line contains the points (0, 0, z) of the axis."""
    from addon.core.kinematics.path import turntable

    wp = turntable(4, probe_mm, beam=beam, turn_rad=np.pi / 2, table=Turntable())
    for pose in wp.probe2table:
        normal = pose[:3, 0]  # the probe's x: across the laser plane (y the line, z the beam)
        for z in (-50.0, 0.0, 100.0):
            assert abs(np.dot(np.array([0.0, 0.0, z]) - pose[:3, 3], normal)) < 1e-9
