"""URDF robots: the chain's DH form reproduces the file, the UR5 URDF matches the DH rig,
meshes land where the file puts them, and broken files give one clear error.

Ground truth: each URDF's forward kinematics is recomputed here from the XML alone
(ElementTree, xyz/rpy and axis-angle rotations written out), independently of the loader.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("yourdfpy", reason="installed by the README's set-up")

from addon.core.config.rigs import load_robot  # noqa: E402
from addon.core.errors import ConfigError  # noqa: E402
from addon.core.kinematics.ik import closed_form_arm  # noqa: E402
from addon.core.kinematics.ik_parallel import ParallelAxesArm  # noqa: E402
from addon.core.kinematics.link_shapes import link_mesh  # noqa: E402
from addon.core.kinematics.transforms import rot_z  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
UR5_URDF = REPO / "rigs" / "robots" / "urdf" / "ur5.urdf"


# -- an independent URDF forward kinematics ------------------------------------------------
def _rpy(r, p, y):
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def _rodrigues(axis, angle):
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def xml_fk(path: Path, q, tool_link: str) -> np.ndarray:
    """The tool link's pose (mm) from the XML: the product of joint origins and rotations."""
    root = ET.parse(path).getroot()
    joints = {j.find("child").get("link"): j for j in root.findall("joint")}
    chain = []
    link = tool_link
    while link in joints:
        chain.append(joints[link])
        link = joints[link].find("parent").get("link")
    T = np.eye(4)
    k = 0
    for j in reversed(chain):
        o = j.find("origin")
        xyz = [float(v) for v in (o.get("xyz", "0 0 0") if o is not None else "0 0 0").split()]
        rpy = [float(v) for v in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()]
        M = np.eye(4)
        M[:3, :3] = _rpy(*rpy)
        M[:3, 3] = np.array(xyz) * 1000.0
        T = T @ M
        a = j.find("axis")
        axis = [float(v) for v in (a.get("xyz") if a is not None else "1 0 0").split()]
        if j.get("type") in ("revolute", "continuous"):
            R = np.eye(4)
            R[:3, :3] = _rodrigues(axis, q[k])
            T = T @ R
            k += 1
        elif j.get("type") == "prismatic":  # q in mm along the unit axis
            S = np.eye(4)
            S[:3, 3] = np.array(axis) / np.linalg.norm(axis) * q[k]
            T = T @ S
            k += 1
    return T


def write_chain(path: Path, origins, axes, types=None, extra: str = "", tool_origin="0 0 0.05") -> Path:
    """A URDF of a serial chain: origins [(xyz, rpy) strings], axes [xyz strings]; a prismatic
    joint slides ±0.3 m, the others turn ±3.1 rad."""
    types = types or ["revolute"] * len(origins)
    links = "".join(f'<link name="l{i}"/>' for i in range(len(origins) + 2))
    joints = "".join(
        f'<joint name="j{i}" type="{t}"><parent link="l{i}"/><child link="l{i + 1}"/>'
        f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{ax}"/>'
        + ('<limit lower="-0.3" upper="0.3" effort="1" velocity="1"/>' if t == "prismatic" else
           '<limit lower="-3.1" upper="3.1" effort="1" velocity="1"/>') + '</joint>'
        for i, ((xyz, rpy), ax, t) in enumerate(zip(origins, axes, types)))
    n = len(origins)
    tool = (f'<joint name="tool" type="fixed"><parent link="l{n}"/><child link="l{n + 1}"/>'
            f'<origin xyz="{tool_origin}" rpy="0.1 0.2 0.3"/></joint>')
    path.write_text(f'<?xml version="1.0"?><robot name="chain">{links}{joints}{tool}{extra}</robot>')
    return path


def random_chain(rng, tmp: Path, name: str, types=None) -> Path:
    origins, axes = [], []
    for _ in range(6):
        xyz = " ".join(f"{v:.4f}" for v in rng.uniform(-0.3, 0.3, 3))
        rpy = " ".join(f"{v:.4f}" for v in rng.uniform(-np.pi, np.pi, 3))
        ax = rng.normal(size=3)
        origins.append((xyz, rpy))
        axes.append(" ".join(f"{v:.4f}" for v in ax / np.linalg.norm(ax)))
    return write_chain(tmp / name, origins, axes, types)


# -- the bundled UR5 ----------------------------------------------------------------------
def test_ur5_urdf_matches_the_dh_rig_to_a_nanometre():
    urdf, dh = load_robot(UR5_URDF), load_robot("ur5")
    q = dh.random_q(2000, np.random.default_rng(1))
    Tu, Td = urdf.fk(q), dh.fk(q)
    # The two descriptions differ by a half turn of the base about joint 1 (ROS's base_link);
    # the tool link, tool0 (ROS-Industrial's flange), is the DH flange frame itself.
    B = rot_z(np.pi)
    assert np.abs(Tu[:, :3, 3] - (B @ Td)[:, :3, 3]).max() < 1e-9
    assert np.abs(Tu[:, :3, :3] - (B @ Td)[:, :3, :3]).max() < 1e-12
    # ee_link, the older convention, is the same flange point with its x axis out of the flange.
    ee = load_robot(UR5_URDF, tool_link="ee_link").fk(q)
    assert np.abs(ee[:, :3, 3] - Tu[:, :3, 3]).max() < 1e-9
    assert np.abs(np.einsum("ni,ni->n", ee[:, :3, 0], Tu[:, :3, 2]) - 1.0).max() < 1e-12


def test_ur5_urdf_matches_its_own_xml_and_gets_the_closed_form():
    robot = load_robot(UR5_URDF)
    rng = np.random.default_rng(2)
    for q in robot.random_q(50, rng):
        np.testing.assert_allclose(robot.fk(q), xml_fk(UR5_URDF, q, "tool0"), atol=1e-9)
    assert isinstance(closed_form_arm(robot)[0], ParallelAxesArm)
    qs = robot.random_q(500, rng)
    batch = robot.ik_batch(robot.fk(qs))
    assert batch.method == "analytic" and batch.success.all()


@pytest.mark.parametrize("tilt", ["0.1", "1e-3", "1e-8"])
def test_nearly_parallel_axes_load_exactly_or_are_refused_naming_the_joints(tilt, tmp_path):
    """The UR5's elbow frame turned about x (as a calibrated arm's file has it): axes 2 and 3
    are then skew, their common normal 4.2 m away at 0.1 rad, which a DH table holds, exactly
    as the XML says; at 1e-3 rad it is 425 m away (at 1e-8 past computing). The common
    normal's direction was taken from its two feet, rounding noise for axes nearly parallel:
    "the chain's DH form does not reproduce it (1.25e+05 mm off); please report this file",
    or a NaN length."""
    text = UR5_URDF.read_text().replace('<origin xyz="0 -0.1197 0.425" rpy="0 0 0"/>',
                                        f'<origin xyz="0 -0.1197 0.425" rpy="{tilt} 0 0"/>')
    assert f'rpy="{tilt} 0 0"' in text
    path = tmp_path / "ur5_calibrated.urdf"
    path.write_text(text)
    if tilt == "0.1":
        robot = load_robot(path)
        assert 1000.0 < np.abs(robot.d_mm).max() < 10_000.0
        for q in robot.random_q(30, np.random.default_rng(4)):
            np.testing.assert_allclose(robot.fk(q), xml_fk(path, q, "tool0"), atol=1e-7)
        return
    with pytest.raises(ConfigError, match=r"joints 'shoulder_lift_joint' and 'elbow_joint' are [0-9.e-]+° from "
                                          r"parallel.*Make the two axes parallel") as err:
        load_robot(path)
    assert "report" not in str(err.value) and "nan" not in str(err.value)


def test_ur5_urdf_links_carry_its_cylinders():
    """Link 2 (the upper arm) is a 425 mm cylinder along the arm from the shoulder joint."""
    robot = load_robot(UR5_URDF)
    q = np.radians([20, -50, 40, -30, 60, 10])
    upper = link_mesh(robot, 1)
    frames = robot.link_frames(q)
    world = upper.vertices @ frames[2][:3, :3].T + frames[2][:3, 3]
    # Independently: the upper arm link's frame from the XML, its cylinder centred 212.5 mm up its z.
    T = xml_fk(UR5_URDF, q, "upper_arm_link")
    centre = T[:3, :3] @ [0, 0, 212.5] + T[:3, 3]
    np.testing.assert_allclose(world.mean(axis=0), centre, atol=1e-6)
    along = T[:3, 2]
    extent = (world - centre) @ along
    assert extent.max() == pytest.approx(212.5, abs=1e-6) and extent.min() == pytest.approx(-212.5, abs=1e-6)


def test_a_pose_only_a_joint_limit_keeps_out_of_reach_names_that_limit(tmp_path):
    """A chain whose third joint turns only ±0.3 rad, asked for the pose it has at q3 = 1.2 rad:
    the refusal names J3 and the angle that would reach it (a URDF engineer's trial: the
    message said only "outside the workspace or needs joints beyond their limits")."""
    from addon.core.kinematics import ik

    path = random_chain(np.random.default_rng(3), tmp_path, "arm.urdf")
    head, rest = path.read_text().split('<joint name="j2"', 1)
    path.write_text(head + '<joint name="j2"' + rest.replace('lower="-3.1" upper="3.1"', 'lower="-0.3" upper="0.3"', 1))
    robot = load_robot(path)
    q = np.array([0.4, -0.6, 1.2, 0.5, -0.7, 0.3])
    res = ik.solve(robot, robot.fk(q[None])[0], np.zeros(6))
    assert not res.success
    angle = float(res.message.split("J3 (j2) = ")[1].split("°")[0])  # the file's name for it beside its number
    assert "without the limits it is reached with J3 (j2) = " in res.message and "outside [-17.1887°, 17.1887°]" in res.message
    assert abs(angle) > 17.19  # beyond the limit (1.2 rad = 68.75° is one such solution)
    assert res.message.count("outside [") == 1  # J3 alone: the other joints are put back by whole turns
    # A path through the pose: only its first miss is explained (a second solve each would
    # double the time a refused path takes), and that one names J3 too.
    from addon.core.kinematics.cell import Cell
    from addon.core.kinematics.path import Waypoints, solve_path
    from addon.core.kinematics.turntable import Turntable

    cell = Cell(robot, Turntable())
    T = robot.fk(q[None])[0]
    poses = cell.table.base2table(np.zeros(3)) @ np.stack([T, T, T])
    sol = solve_path(cell, Waypoints(poses, np.zeros(3), np.zeros(3, int)), np.zeros(6))
    assert not sol.ok.any()
    assert "J3 (j2) = " in sol.messages[0] and all("without the limits" not in m for m in sol.messages[1:])


def test_a_chain_of_sliding_joints_only_solves_a_path(tmp_path):
    """Six sliding joints (an x-y-z slide stack, each axis twice): nothing turns, so no step can
    be a flip; the path's solver took the largest turn over no joint (numpy's error, a
    traceback from the scan)."""
    from addon.core.kinematics.cell import Cell
    from addon.core.kinematics.path import Waypoints, solve_path
    from addon.core.kinematics.turntable import Turntable

    origins = [("0 0 0.1", "0 0 0")] * 6
    path = write_chain(tmp_path / "slides.urdf", origins, ["1 0 0", "0 1 0", "0 0 1"] * 2, types=["prismatic"] * 6)
    robot = load_robot(path)
    assert all(robot.prismatic)
    cell = Cell(robot, Turntable())
    q = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 0.0], [20.0, 10.0, -5.0, 0.0, 0.0, 0.0], [40.0, 20.0, -10.0, 0.0, 0.0, 0.0]])
    poses = cell.table.base2table(np.zeros(3)) @ robot.fk(q)
    sol = solve_path(cell, Waypoints(poses, np.zeros(3), np.zeros(3, int)), np.zeros(6))
    assert sol.ok.all() and sol.jumps == [] and not sol.max_step_rad.any()
    np.testing.assert_allclose(robot.fk(sol.q)[:, :3, 3], robot.fk(q)[:, :3, 3], atol=1e-6)


def test_a_urdf_under_another_name_is_read_as_urdf_where_a_config_says_urdf(tmp_path):
    """``.xml`` is read as URDF by name; a scan config's ``urdf =`` key reads any name as URDF."""
    from addon.core.config.scan import load_scan_config

    text = UR5_URDF.read_text()
    # xacro's own output keeps the source's comments: a URDF already expanded loads ...
    expanded = text.replace("<robot ", '<!-- from ur5.urdf.xacro: <xacro:include filename="$(find ur)/x.xacro"/> -->'
                                       '\n<robot ', 1)
    (tmp_path / "expanded.urdf").write_text(expanded)
    assert load_robot(tmp_path / "expanded.urdf").name == load_robot(UR5_URDF).name
    # ... and one with a macro left in a value is named as xacro
    (tmp_path / "left.urdf").write_text(text.replace('<robot name="', '<robot name="${prefix}', 1))
    with pytest.raises(ConfigError, match="holds xacro macros"):
        load_robot(tmp_path / "left.urdf")
    (tmp_path / "arm.xml").write_text(text)
    (tmp_path / "arm.description").write_text(text)
    assert load_robot(tmp_path / "arm.xml").name == load_robot(UR5_URDF).name
    scene = (REPO / "rigs" / "scenes" / "ur5_urdf.toml").read_text()
    scene = scene.replace('urdf = "../robots/urdf/ur5.urdf"', 'urdf = "arm.description"')
    assert 'urdf = "arm.description"' in scene
    (tmp_path / "scan.toml").write_text(scene)
    config = load_scan_config(tmp_path / "scan.toml")
    np.testing.assert_allclose(config.robot.a_mm, load_robot(UR5_URDF).a_mm)


def test_the_base_link_and_what_is_fixed_to_it_make_the_robots_base_and_the_probe_may_not_enter_it(tmp_path):
    """The UR5's base_link carries a cylinder 150 mm across and 80 mm high on the floor: it
    becomes the robot's base (drawn and collision-checked). A gantry's frame fixed to its base
    link is a base too; a link off the chain is not. The probe driven into the base is a
    collision; a pose with the probe clear of it is not (the base's geometry from the file)."""
    from dataclasses import replace

    import trimesh

    from addon.core.config.rigs import load_probe
    from addon.core.kinematics.link_shapes import base_mesh
    from addon.core.kinematics.turntable import Turntable
    from addon.core.safety import CollisionModel

    robot = load_robot(UR5_URDF)
    base = base_mesh(robot, collision=True)
    frame0 = robot.link_frames(np.zeros(6))[0]
    world = base.vertices @ frame0[:3, :3].T + frame0[:3, 3]
    np.testing.assert_allclose(world.min(axis=0), [-75.0, -75.0, 0.0], atol=0.5)  # a 64-gon's corners
    np.testing.assert_allclose(world.max(axis=0), [75.0, 75.0, 80.0], atol=0.5)
    gantry = load_robot(REPO / "rigs" / "robots" / "urdf" / "gantry.urdf")
    assert base_mesh(gantry) is not None and np.ptp(base_mesh(gantry).vertices, axis=0).max() == pytest.approx(1600.0)

    # A DH robot with a pedestal put around where the probe is at one pose: touching, then clear.
    probe = load_probe("default")
    arm = load_robot("adept_viper_s650").with_tool(probe.mount)
    q = np.radians([0, 30, -15, 0, 75, 90])
    probe2base = arm.fk(q[None])[0]
    housing_extents, housing_centre = probe.body_boxes()[0][1:]
    for gap, touches in ((-5.0, True), (10.0, False)):
        # A 40 mm cube beside the housing along the probe's x, ``gap`` mm from its side.
        cube = trimesh.creation.box([40.0, 40.0, 40.0])
        side = housing_centre + [housing_extents[0] / 2 + gap + 20.0, 0.0, 0.0]
        cube.apply_transform(np.linalg.inv(frame0 := arm.link_frames(q[None])[0, 0]) @ probe2base
                             @ np.array([[1, 0, 0, side[0]], [0, 1, 0, side[1]], [0, 0, 1, side[2]], [0, 0, 0, 1]]))
        model = CollisionModel(replace(arm, base_mesh=(cube, np.eye(4))), probe, Turntable())
        found = model.clearance_at(q, 0.0)
        hits = {(c.body_a, c.body_b) for c, _ in found.collisions}
        assert (("probe", "robot base") in hits or ("robot base", "probe") in hits) == touches, (gap, hits)


def test_a_pedestal_drawn_only_beside_a_base_link_with_a_collision_body_is_still_checked(tmp_path):
    """Each URDF link fixed to the base has its collision geometry, or without any its visual
    one, as the arm's links do: a post drawn only (a visual box 100 × 100 × 600 mm, 500 mm out
    along x) beside the UR5's base link, which has a collision cylinder, was left out of the
    base's collision body, so nothing stopped the arm driving into it."""
    from addon.core.kinematics.link_shapes import base_mesh

    post = ('  <link name="post"><visual><origin xyz="0.5 0 0.3"/><geometry><box size="0.1 0.1 0.6"/>'
            '</geometry></visual></link>\n  <joint name="post_fixed" type="fixed"><parent link="base_link"/>'
            '<child link="post"/><origin xyz="0 0 0"/></joint>\n')
    drawn = '<visual><origin xyz="0 0 0.04" rpy="0 0 0"/><geometry><cylinder radius="0.075" length="0.08"/></geometry></visual>'
    text = UR5_URDF.read_text()
    assert drawn in text
    text = text.replace(drawn, drawn + drawn.replace("visual", "collision"), 1)  # the base link gets a collision body
    path = tmp_path / "ur5_post.urdf"
    path.write_text(text.replace("</robot>", post + "</robot>"))
    robot = load_robot(path)
    base = base_mesh(robot, collision=True)
    frame0 = robot.link_frames(np.zeros(6))[0]
    world = base.vertices @ frame0[:3, :3].T + frame0[:3, 3]
    np.testing.assert_allclose(world.max(axis=0), [550.0, 75.0, 600.0], atol=0.5)  # the post's far corner
    np.testing.assert_allclose(world.min(axis=0), [-75.0, -75.0, 0.0], atol=0.5)   # the base's cylinder


def test_messages_name_a_urdfs_joints_and_links_as_the_file_does():
    """A URDF engineer reads "J3 (elbow_joint)" and "link 3 (forearm_link)", not numbers alone:
    the names are the file's moving joints from the base to the tool and the links they move
    (read here from the XML), quoted by the joint-limit and collision messages."""
    from addon.core.config.rigs import load_probe
    from addon.core.kinematics.turntable import Turntable
    from addon.core.safety import CollisionModel

    root = ET.parse(UR5_URDF).getroot()
    by_child = {j.find("child").get("link"): j for j in root.findall("joint")}
    link, chain = "ee_link", []
    while link in by_child:
        chain.append(by_child[link])
        link = by_child[link].find("parent").get("link")
    moving = [j for j in reversed(chain) if j.get("type") != "fixed"]
    joint_names = [j.get("name") for j in moving]
    link_names = [j.find("child").get("link") for j in moving]
    assert len(joint_names) == 6

    probe = load_probe("default")
    arm = load_robot(UR5_URDF).with_tool(probe.mount)
    q = np.zeros(6)
    q[2] = arm.q_max_rad[2] + 0.5
    (violation,) = arm.limit_violations(q)
    assert violation.startswith(f"J3 ({joint_names[2]}) = ")

    model = CollisionModel(arm, probe, Turntable())
    named = set()
    for q in arm.random_q(60, np.random.default_rng(0)):
        found = model.clearance_at(q, 0.0)
        if not found.collisions:
            continue
        contact = found.first_collision[0]
        for body in (contact.body_a, contact.body_b):
            if body.startswith("link "):
                k = int(body.split()[1])
                assert f"link {k} ({link_names[k - 1]})" in found.message(), found.message()
                named.add(k)
    assert len(named) >= 2  # links met in collisions: the search found some

    # A DH table has no names: the numbers alone, as before.
    dh = load_robot("ur5").with_tool(probe.mount)
    assert dh.joint_names == () and dh.limit_violations(q * 0 + 20.0)[0].startswith("J1 = ")


# -- any chain ----------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(6))
def test_random_chains_keep_their_kinematics(seed, tmp_path):
    rng = np.random.default_rng(100 + seed)
    path = random_chain(rng, tmp_path, f"chain{seed}.urdf")
    robot = load_robot(path)
    for q in robot.random_q(30, rng):
        np.testing.assert_allclose(robot.fk(q), xml_fk(path, q, "l7"), atol=1e-9)
    q = robot.random_q(3, rng)
    res = robot.ik_batch(robot.fk(q), q + 0.05)
    assert res.success.all()


@pytest.mark.parametrize("seed", range(4))
def test_chains_with_prismatic_joints(seed, tmp_path):
    """Sliding joints (q in mm) anywhere in the chain: FK as the XML says, the Jacobian as finite
    differences of FK, no closed form, and the numeric IK reaches poses from afar."""
    rng = np.random.default_rng(200 + seed)
    types = list(rng.permutation(["prismatic"] * (1 + seed % 3) + ["revolute"] * (5 - seed % 3)))
    path = random_chain(rng, tmp_path, f"slide{seed}.urdf", types)
    robot = load_robot(path)
    assert robot.prismatic == tuple(t == "prismatic" for t in types)
    slides = np.array(robot.prismatic)
    np.testing.assert_allclose(robot.q_max_rad[slides], 300.0)  # 0.3 m
    for q in robot.random_q(30, rng):
        np.testing.assert_allclose(robot.fk(q), xml_fk(path, q, "l7"), atol=1e-9)
    q = robot.random_q(1, rng)[0]
    J = robot.jacobian(q)
    h = 1e-6
    for i in range(6):
        dq = np.zeros(6)
        dq[i] = h
        Tp, Tm = xml_fk(path, q + dq, "l7"), xml_fk(path, q - dq, "l7")
        np.testing.assert_allclose(J[:3, i], (Tp[:3, 3] - Tm[:3, 3]) / (2 * h), atol=1e-5)
        dR = (Tp[:3, :3] - Tm[:3, :3]) / (2 * h) @ xml_fk(path, q, "l7")[:3, :3].T
        np.testing.assert_allclose(J[3:, i], [dR[2, 1], dR[0, 2], dR[1, 0]], atol=1e-6)
    assert closed_form_arm(robot)[0] is None
    q = robot.random_q(4, rng)
    res = robot.ik_batch(robot.fk(q), robot.random_q(4, rng))
    assert res.success.all()
    np.testing.assert_allclose(robot.fk(res.q)[:, :3, 3], robot.fk(q)[:, :3, 3], atol=1e-6)
    # The sliding joints' limits hold: a pose needing 0.5 m of travel is refused.
    far = q[0].copy()
    far[np.argmax(slides)] = 500.0
    assert not robot.ik(robot.fk(far), q[0]).success


def test_parallel_intersecting_and_collinear_axes(tmp_path):
    """Axes 2-3 parallel, 4-5 meeting, 5-6 on one line: the DH form's special cases."""
    origins = [("0 0 0.1", "0 0 0"), ("0 0.1 0", "1.5707963 0 0"), ("0.4 0 0", "0 0 0"),
               ("0.3 0 0.05", "0 1.5707963 0"), ("0 0 0", "0 -1.5707963 0"), ("0 0 0.2", "0 0 0")]
    axes = ["0 0 1", "0 0 1", "0 0 1", "0 0 -1", "0 0 1", "0 0 1"]
    path = write_chain(tmp_path / "special.urdf", origins, axes)
    robot = load_robot(path)
    rng = np.random.default_rng(3)
    for q in robot.random_q(30, rng):
        np.testing.assert_allclose(robot.fk(q), xml_fk(path, q, "l7"), atol=1e-9)


@pytest.mark.parametrize("metre, size", [("0.001", 100.0), ("1", 0.1), ("0.0254", 100.0 / 25.4)])
def test_a_collada_mesh_is_read_in_the_unit_its_file_states(metre, size, tmp_path):
    """A COLLADA file says what one of its units is in metres (<unit meter="0.001"/>: its numbers
    are millimetres), as RViz and Gazebo read it: a 100 mm box, however written, is 100 mm (a
    box written in millimetres came out 100 m)."""
    import re

    import trimesh

    from addon.core.kinematics.link_shapes import base_mesh

    text = trimesh.exchange.dae.export_collada(trimesh.creation.box((size, size, size)))
    text = text.decode() if isinstance(text, bytes) else text
    unit = f'<unit meter="{metre}" name="unit"/>'
    text = re.sub(r"<unit[^>]*/>", unit, text) if "<unit" in text else text.replace("<asset>", "<asset>" + unit, 1)
    (tmp_path / "box.dae").write_text(text)
    drawn = '<visual><origin xyz="0 0 0.04" rpy="0 0 0"/><geometry><cylinder radius="0.075" length="0.08"/></geometry></visual>'
    urdf = UR5_URDF.read_text()
    assert drawn in urdf
    (tmp_path / "ur5.urdf").write_text(urdf.replace(drawn, '<visual><geometry><mesh filename="box.dae"/></geometry></visual>'))
    np.testing.assert_allclose(base_mesh(load_robot(tmp_path / "ur5.urdf")).extents, 100.0, rtol=1e-6)


def test_mesh_file_through_package_path_and_scale(tmp_path):
    import trimesh

    pkg = tmp_path / "share" / "my_robot" / "meshes"
    pkg.mkdir(parents=True)
    box = trimesh.creation.box((40.0, 20.0, 10.0))  # millimetres in the file, scale 0.001
    box.apply_translation((100.0, 0, 0))
    (pkg / "link3.stl").write_bytes(box.export(file_type="stl"))
    rng = np.random.default_rng(4)
    origins = [(" ".join(f"{v:.3f}" for v in rng.uniform(-0.2, 0.2, 3)), "0.3 -0.2 0.1") for _ in range(6)]
    axes = ["0 0 1", "0 1 0", "0 1 0", "1 0 0", "0 1 0", "1 0 0"]
    path = write_chain(tmp_path / "robot.urdf", origins, axes)
    text = path.read_text().replace(
        '<link name="l3"/>',
        '<link name="l3"><visual><origin xyz="0.01 0 0" rpy="0 0 0.5"/><geometry>'
        '<mesh filename="package://my_robot/meshes/link3.stl" scale="0.001 0.001 0.001"/></geometry></visual></link>')
    path.write_text(text)
    with pytest.raises(ConfigError, match="package_dirs"):
        load_robot(path)
    robot = load_robot(path, package_dirs=[tmp_path / "share"])
    q = robot.random_q(1, rng)[0]
    mesh = link_mesh(robot, 2)  # l3 hangs on joint 3
    frames = robot.link_frames(q)
    world = mesh.vertices @ frames[3][:3, :3].T + frames[3][:3, 3]
    T = xml_fk(path, q, "l3")
    V = np.eye(4)
    V[:3, :3] = _rpy(0, 0, 0.5)
    V[:3, 3] = [10.0, 0, 0]
    expected = (T @ V @ np.c_[box.vertices, np.ones(len(box.vertices))].T).T[:, :3]
    corners = np.unique(np.round(world, 6), axis=0)
    assert len(corners) == 8
    np.testing.assert_allclose(np.unique(np.round(expected, 6), axis=0), corners, atol=1e-5)


# -- broken files ---------------------------------------------------------------------------
def _six(tmp_path, **kw):
    origins = [("0 0 0.1", "0 0 0")] * 6
    return write_chain(tmp_path / "r.urdf", origins, ["0 0 1", "0 1 0", "0 1 0", "1 0 0", "0 1 0", "1 0 0"], **kw)


@pytest.mark.parametrize("case,words", [
    ("planar", "planar"),
    ("prismatic without limits", "needs <limit"),
    ("five", "5 moving joints"),
    ("not xml", "not a readable URDF"),
    ("two leaves", "tool_link"),
    ("unknown tool", "not a link"),
    ("missing mesh", "not found"),
    ("limits inverted", "limits"),
    ("no such file", "no such file"),
    ("xacro named .urdf", "holds xacro macros.*expand it first"),
    ("xacro file", "a xacro file.*expand it first"),
    ("a link twice", "link 'l2' is defined 2 times"),
    ("a joint twice", "joint 'extra' is defined 2 times"),
    # (a cylinder of radius 0 crashed the process in the collision library; the others were
    # tracebacks; a cycle hung the loader)
    ("cylinder of radius 0", "a cylinder's radius and length must be 2 finite number"),
    ("sphere of radius 0", "a sphere's radius must be 1 finite number"),
    ("box of two sizes", "a box's size must be 3 finite number"),
    ("geometry origin nan", "link 'l2': the origin of one of its visuals is not finite"),
    ("a cycle", "form a cycle"),
    ("a joint without a parent", "joint 'j2' has no <parent"),
    ("a visual without geometry", "link 'l2' has a <visual> with no shape"),
    # (a traceback, KeyErrors, "joint 'j3' is None", a second shape dropped without a word, and
    # "please report this file" for a unit slip)
    ("a mesh without a filename", "link 'l2': the <mesh> of a <visual> has no filename"),
    ("a cylinder without a length", "the <cylinder> of a <visual> has no length; a cylinder needs radius and length"),
    ("two shapes in one geometry", "link 'l2' has a <visual> with 2 shapes in its <geometry>"),
    ("a joint without a name", "<joint> number 3 has no name"),
    ("a link without a name", "<link> number 3 has no name"),
    ("a joint without a type", "joint 'j3' has no type"),
    ("a robot without a name", "the <robot> has no name"),
    ("not a robot", "its root element is <foo>"),
    ("an origin in millimetres", r"joint 'j1' origin xyz: 100000 is beyond ±1000 m"),
    ("limits in degrees", r"joint 'j0' has limits \[-1000, 1000\]; give them within ±12.57 rad"),
    ("sliding limits in micrometres", r"joint 'j1' has limits \[-3e\+06, 3e\+06\]; give them within ±1000 m"),
])
def test_broken_urdf_files_give_one_clear_error(case, words, tmp_path):
    kw = {}
    if case == "planar":
        path = _six(tmp_path, types=["revolute", "planar"] + ["revolute"] * 4)
    elif case == "prismatic without limits":
        path = _six(tmp_path, types=["revolute", "prismatic"] + ["revolute"] * 4)
        path.write_text(path.read_text().replace('<limit lower="-0.3" upper="0.3" effort="1" velocity="1"/>', ""))
    elif case == "five":
        path = write_chain(tmp_path / "r.urdf", [("0 0 0.1", "0 0 0")] * 5, ["0 0 1"] * 5)
    elif case == "not xml":
        path = tmp_path / "r.urdf"
        path.write_text("<robot name='x'><link name='a'>")
    elif case == "two leaves":
        path = _six(tmp_path, extra='<link name="cam"/><joint name="c" type="fixed"><parent link="l2"/>'
                                    '<child link="cam"/></joint>')
    elif case == "unknown tool":
        path = _six(tmp_path)
        kw = {"tool_link": "gripper"}
    elif case == "missing mesh":
        path = _six(tmp_path)
        path.write_text(path.read_text().replace(
            '<link name="l2"/>', '<link name="l2"><visual><geometry><mesh filename="meshes/gone.stl"/></geometry>'
                                 '</visual></link>'))
    elif case == "limits inverted":
        path = _six(tmp_path)
        path.write_text(path.read_text().replace('lower="-3.1" upper="3.1"', 'lower="3.1" upper="-3.1"', 1))
    elif case == "xacro named .urdf":
        path = _six(tmp_path)
        path.write_text(path.read_text().replace(
            "<robot ", '<robot xmlns:xacro="http://www.ros.org/wiki/xacro" ', 1).replace(
            '<link name="l2"/>', '<xacro:property name="r" value="0.05"/><link name="l2"/>'))
    elif case == "a link twice":
        path = _six(tmp_path)
        path.write_text(path.read_text().replace('<link name="l2"/>', '<link name="l2"/><link name="l2"/>', 1))
    elif case == "a joint twice":
        extra = '<link name="cam{k}"/><joint name="extra" type="fixed"><parent link="l2"/><child link="cam{k}"/></joint>'
        path = _six(tmp_path, extra=extra.format(k=1) + extra.format(k=2))
        kw = {"tool_link": "l6"}
    elif case in ("cylinder of radius 0", "sphere of radius 0", "box of two sizes", "geometry origin nan"):
        geometry, origin = {"cylinder of radius 0": ('<cylinder radius="0" length="0.1"/>', ""),
                            "sphere of radius 0": ('<sphere radius="0"/>', ""),
                            "box of two sizes": ('<box size="0.1 0.1"/>', ""),
                            "geometry origin nan": ('<box size="0.1 0.1 0.1"/>', '<origin xyz="0 nan 0"/>')}[case]
        path = _six(tmp_path)
        path.write_text(path.read_text().replace(
            '<link name="l2"/>', f'<link name="l2"><visual>{origin}<geometry>{geometry}</geometry></visual></link>'))
    elif case == "a joint without a parent":
        path = _six(tmp_path)
        text = path.read_text()
        at = text.index('<joint name="j2"')
        end = text.index("</joint>", at)
        block = text[at:end]
        start = block.index("<parent ")
        path.write_text(text[:at] + block[:start] + block[block.index("/>", start) + 2:] + text[end:])
    elif case == "a visual without geometry":
        path = _six(tmp_path)
        path.write_text(path.read_text().replace('<link name="l2"/>', '<link name="l2"><visual></visual></link>'))
    elif case in ("a mesh without a filename", "a cylinder without a length", "two shapes in one geometry"):
        geometry = {"a mesh without a filename": '<mesh scale="1 1 1"/>',
                    "a cylinder without a length": '<cylinder radius="0.05"/>',
                    "two shapes in one geometry": '<box size="0.1 0.1 0.1"/><sphere radius="0.05"/>'}[case]
        path = _six(tmp_path)
        path.write_text(path.read_text().replace(
            '<link name="l2"/>', f'<link name="l2"><visual><geometry>{geometry}</geometry></visual></link>'))
    elif case in ("a joint without a name", "a link without a name", "a joint without a type", "a robot without a name",
                  "not a robot", "an origin in millimetres", "limits in degrees", "sliding limits in micrometres"):
        path = _six(tmp_path, types=["revolute", "prismatic"] + ["revolute"] * 4)
        text = path.read_text()
        old, new = {"a joint without a name": ('<joint name="j2" ', "<joint "),
                    "a link without a name": ('<link name="l2"/>', "<link/>"),
                    "a joint without a type": ('<joint name="j3" type="revolute"', '<joint name="j3"'),
                    "a robot without a name": (text[text.index("<robot "):text.index(">", text.index("<robot ")) + 1],
                                               "<robot>"),
                    "not a robot": (None, None),
                    "an origin in millimetres": ('<joint name="j1" type="prismatic"><parent link="l1"/><child link="l2"/>'
                                                 '<origin xyz="0 0 0.1"',
                                                 '<joint name="j1" type="prismatic"><parent link="l1"/><child link="l2"/>'
                                                 '<origin xyz="0 0 100000"'),
                    "limits in degrees": ('lower="-3.1" upper="3.1"', 'lower="-1000" upper="1000"'),
                    "sliding limits in micrometres": ('lower="-0.3" upper="0.3"', 'lower="-3e6" upper="3e6"')}[case]
        if old is None:
            text = '<?xml version="1.0"?><foo/>'
        else:
            assert old in text, (case, old)
            text = text.replace(old, new, 1)
        path.write_text(text)
    elif case == "a cycle":
        path = _six(tmp_path)
        text = path.read_text()
        at = text.index('<joint name="j1"')
        end = text.index("</joint>", at)
        parent = text[at:end][text[at:end].index('<parent link="') + 14:]
        parent = parent[:parent.index('"')]
        path.write_text(text[:at] + text[at:end].replace(f'<parent link="{parent}"/>', '<parent link="l6"/>', 1)
                        + text[end:])
        kw = {"tool_link": "l6"}
    elif case == "xacro file":
        path = tmp_path / "arm.urdf.xacro"
        path.write_text(_six(tmp_path).read_text())
    else:
        path = tmp_path / "none.urdf"
    with pytest.raises(ConfigError, match=words) as info:
        load_robot(path, **kw)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("limit", ["", '<limit effort="1" velocity="1"/>'], ids=["no limit element", "no lower/upper"])
def test_a_revolute_joint_without_limits_is_refused_naming_it(limit, tmp_path):
    # The URDF specification makes <limit> compulsory for revolute joints; none is not ±360°.
    path = _six(tmp_path)
    text = path.read_text()
    j2 = text.index('<joint name="j2"')
    path.write_text(text[:j2] + text[j2:].replace('<limit lower="-3.1" upper="3.1" effort="1" velocity="1"/>',
                                                  limit, 1))
    with pytest.raises(ConfigError) as info:
        load_robot(path)
    message = str(info.value)
    assert "\n" not in message
    assert str(path) in message and "revolute joint 'j2' has no limits" in message
    assert 'lower="..." upper="..."' in message and "radians" in message and "continuous" in message


def test_a_continuous_joint_needs_no_limits_and_turns_a_full_turn_either_way(tmp_path):
    path = _six(tmp_path, types=["revolute", "continuous"] + ["revolute"] * 4)
    path.write_text(path.read_text().replace('<limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>'
                                             '<joint name="j2"', '</joint><joint name="j2"', 1))
    assert '<joint name="j1" type="continuous"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.1" ' \
           'rpy="0 0 0"/><axis xyz="0 1 0"/></joint>' in path.read_text()
    robot = load_robot(path)
    np.testing.assert_allclose(robot.q_min_rad, [-3.1, -2 * np.pi, -3.1, -3.1, -3.1, -3.1])
    np.testing.assert_allclose(robot.q_max_rad, [3.1, 2 * np.pi, 3.1, 3.1, 3.1, 3.1])


@pytest.mark.parametrize("joint,tag,old,new,words", [
    ("j5", "origin", 'xyz="0 0 0.1"', 'xyz="0 nan 0.1"', "joint 'j5' origin xyz: 'nan' is not a finite number"),
    ("j1", "origin", 'rpy="0 0 0"', 'rpy="0 inf 0"', "joint 'j1' origin rpy: 'inf' is not a finite number"),
    ("j3", "axis", 'xyz="1 0 0"', 'xyz="NaN 0 0"', "joint 'j3' axis xyz: 'NaN' is not a finite number"),
    ("j2", "origin", 'xyz="0 0 0.1"', 'xyz="0 0.1"', "joint 'j2' origin xyz: '0 0.1' has 2 numbers; give three"),
])
def test_a_non_finite_joint_origin_or_axis_is_named_where_it_was_written(joint, tag, old, new, words, tmp_path):
    path = _six(tmp_path)
    text = path.read_text()
    at = text.index(f'<joint name="{joint}"')
    end = text.index("</joint>", at)
    assert old in text[at:end]
    path.write_text(text[:at] + text[at:end].replace(old, new, 1) + text[end:])
    with pytest.raises(ConfigError) as info:
        load_robot(path)
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"{path}: ") and words in message, message
    assert "a_mm" not in message and "NaN or inf" not in message


def test_a_link_without_collision_geometry_is_checked_with_its_visual_one(tmp_path):
    """Where some links of a URDF have collision geometry and another only a visual mesh, that
    link is checked as its visual mesh, not as the cylinders of a link with no geometry (the
    fallback went by the whole robot: one link's collision geometry turned every other link's
    visual mesh into cylinders for the checks)."""
    import trimesh

    from addon.core.kinematics.link_shapes import link_mesh

    for name, size in (("link2.stl", 20.0), ("link3.stl", 30.0)):
        (tmp_path / name).write_bytes(trimesh.creation.box((size, 10.0, 10.0)).export(file_type="stl"))
    origins = [("0 0 0.1", "0 0 0")] * 6
    path = write_chain(tmp_path / "robot.urdf", origins, ["0 0 1", "0 1 0", "0 1 0", "1 0 0", "0 1 0", "1 0 0"])
    path.write_text(path.read_text().replace(
        '<link name="l2"/>', '<link name="l2"><collision><geometry><mesh filename="link2.stl" scale="0.001 0.001 0.001"/>'
        '</geometry></collision></link>').replace(
        '<link name="l3"/>', '<link name="l3"><visual><geometry><mesh filename="link3.stl" scale="0.001 0.001 0.001"/>'
        '</geometry></visual></link>'))
    robot = load_robot(path)
    extent = lambda mesh: float(np.ptp(mesh.vertices, axis=0).max())
    assert extent(link_mesh(robot, 1, collision=True)) == pytest.approx(20.0, abs=1e-6)  # its own collision box
    assert extent(link_mesh(robot, 2, collision=True)) == pytest.approx(30.0, abs=1e-6)  # its visual box
    assert link_mesh(robot, 0, collision=True) is None  # neither: cylinders
    assert link_mesh(robot, 1) is None  # drawn: no visual geometry of its own


def test_a_mesh_file_edited_after_loading_is_read_again(tmp_path):
    """The loaded robot is cached; the cache must not outlive an edit of a mesh the URDF names
    (the collision checks would run on the old shape)."""
    import os

    import trimesh

    def write_box(size_mm, when_ns):
        mesh_file = tmp_path / "link2.stl"
        mesh_file.write_bytes(trimesh.creation.box((size_mm, 10.0, 10.0)).export(file_type="stl"))
        os.utime(mesh_file, ns=(when_ns, when_ns))

    write_box(20.0, 1_000_000_000_000_000_000)
    origins = [("0 0 0.1", "0 0 0")] * 6
    path = write_chain(tmp_path / "robot.urdf", origins, ["0 0 1", "0 1 0", "0 1 0", "1 0 0", "0 1 0", "1 0 0"])
    path.write_text(path.read_text().replace(
        '<link name="l2"/>', '<link name="l2"><collision><geometry><mesh filename="link2.stl" scale="0.001 0.001 0.001"/>'
        '</geometry></collision></link>'))

    def extent_mm(robot):
        return float(np.ptp(robot.collision_meshes[1][0].vertices, axis=0).max())  # the box's long side

    first = load_robot(path)
    assert load_robot(path) is first  # unchanged files: the cached robot
    assert extent_mm(first) == pytest.approx(20.0, abs=1e-6)
    write_box(30.0, 1_000_000_100_000_000_000)  # edited later (a box's binary STL keeps its byte count)
    assert extent_mm(load_robot(path)) == pytest.approx(30.0, abs=1e-6)
    (tmp_path / "link2.stl").unlink()
    with pytest.raises(ConfigError, match="link2.stl"):
        load_robot(path)


def test_each_urdf_link_without_collision_geometry_keeps_its_visual_one_within_a_dh_link(tmp_path):
    """wrist_3_link has only a visual (its 75 mm cylinder); ee_link, fixed to it and so in the
    same DH link, is given a 10 mm collision box: link 6's collision body is both, not the box
    alone (the fallback went by DH link)."""
    from addon.core.kinematics.link_shapes import link_mesh

    text = UR5_URDF.read_text()
    assert '<link name="ee_link"/>' in text
    edited = tmp_path / "ur5.urdf"
    edited.write_text(text.replace('<link name="ee_link"/>', '<link name="ee_link"><collision><geometry>'
                                   '<box size="0.01 0.01 0.01"/></geometry></collision></link>'))
    for mesh_dir in ("meshes",):
        if (UR5_URDF.parent / mesh_dir).is_dir():
            (tmp_path / mesh_dir).symlink_to(UR5_URDF.parent / mesh_dir)
    original = link_mesh(load_robot(UR5_URDF), 5, collision=True)
    body = link_mesh(load_robot(edited), 5, collision=True)
    assert body.extents.max() >= original.extents.max() - 1e-6 > 50.0


def test_a_path_solve_can_stop_at_its_first_pose_out_of_reach(tmp_path):
    """Asked only whether a path can be done, the solve stops at the first pose out of reach
    (a numeric IK's failure costs its restarts at every pose after it: 14-64 s for each view
    of the URDF gantry's that the planner could not do); the poses after it are 'not tried'."""
    from addon.core.kinematics.cell import Cell
    from addon.core.kinematics.path import Waypoints, solve_path
    from addon.core.kinematics.turntable import Turntable

    gantry = load_robot(REPO / "rigs" / "robots" / "urdf" / "gantry.urdf")
    cell = Cell(gantry, Turntable())
    q = gantry.random_q(6, np.random.default_rng(1))
    poses = cell.table.base2table(np.zeros(6)) @ gantry.fk(q)
    poses[2, :3, 3] += [0.0, 0.0, 10_000.0]  # ten metres up: out of the slides' reach
    wp = Waypoints(poses, np.zeros(6), np.zeros(6, int))
    whole, first = solve_path(cell, wp, q[0]), solve_path(cell, wp, q[0], stop_at_miss=True)
    assert whole.unreachable == [2] and whole.ok[3:].all()
    assert first.unreachable == [2, 3, 4, 5] and first.ok[:2].all()
    assert all(m.startswith("not tried") for m in first.messages[3:]) and first.messages[2] == whole.messages[2]


def test_a_urdf_with_transmissions_loads(tmp_path):
    """ROS descriptions (ros_control, ur_description) carry <transmission> blocks whose <joint>
    elements name a joint and have no type, origin or parent: the checks took them for the
    robot's joints ("joint 'shoulder_pan_joint' has no type"; before, "has no <parent link>")."""
    transmission = ('  <transmission name="shoulder_pan_trans"><type>transmission_interface/SimpleTransmission</type>'
                    '<joint name="shoulder_pan_joint"><hardwareInterface>hardware_interface/PositionJointInterface'
                    '</hardwareInterface></joint><actuator name="shoulder_pan_motor"><mechanicalReduction>1'
                    '</mechanicalReduction></actuator></transmission>\n')
    path = tmp_path / "ur5_ros.urdf"
    path.write_text(UR5_URDF.read_text().replace("</robot>", transmission + "</robot>"))
    q = np.radians([10.0, -40.0, 60.0, 20.0, 30.0, 40.0])
    np.testing.assert_allclose(load_robot(path).fk(q), load_robot(UR5_URDF).fk(q), atol=1e-12)
