"""Collision checks with answers from geometry: gaps to a block, a sweep that dips into it, a
link driven into the table, fixtures, and every bundled scene clear."""

import math

import numpy as np
import pytest
import trimesh

pytest.importorskip("fcl", reason="collision checks need python-fcl (installed by the README's set-up)")

from addon.core.config.scan import load_scan_config  # noqa: E402
from addon.core.errors import CollisionError, ConfigError, InputError  # noqa: E402
from addon.core.geometry.workpiece import Workpiece  # noqa: E402
from addon.core.kinematics.link_shapes import link_cylinders  # noqa: E402
from addon.core.kinematics.turntable import TABLE_RADIUS_MM, TABLE_THICKNESS_MM  # noqa: E402
from addon.core.safety import CollisionModel  # noqa: E402
from addon.core.scan.plan import check_motion, plan_scan  # noqa: E402
from addon.scanner import Scanner  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

REPO = Path(__file__).resolve().parents[2]

# The probe's body reaches 2 mm beyond its origin along the beam (the camera and laser heads).
HEAD_REACH_MM = 2.0
HEAD_X_MM = 60.0 + 12.0  # the camera heads' far edges, along the probe's x


def block_part(top=30.0):
    box = trimesh.creation.box([60.0, 40.0, top])
    box.apply_translation([0.0, 0.0, top / 2])
    return Workpiece("block", box, box, "test block", np.eye(4))


def demo_with(workpiece, **changes):
    return replace(load_scan_config("demo"), workpiece=workpiece, **changes)


def test_the_clearance_above_a_block_is_the_gap_geometry_gives():
    cfg = demo_with(block_part())
    model = CollisionModel(cfg.cell.robot, cfg.probe, cfg.table, cfg.workpiece.mesh)
    for gap in (10.0, 25.0, 3.5):
        height = 30.0 + HEAD_REACH_MM + gap
        T = np.eye(4)
        T[:3, :3] = np.diag([1.0, -1.0, -1.0])  # beam straight down
        T[:3, 3] = [5.0, -3.0, height]
        res = cfg.cell.ik(T, cfg.q_start, relative_to="table", table_angle_rad=0.0)
        assert res.success
        c = model.clearance_at(res.q, 0.0).nearest[0]
        assert c.distance_mm == pytest.approx(gap, abs=0.1)
        assert (c.body_a, c.body_b) == ("probe", "workpiece")
        assert c.point_a[2] == pytest.approx(30.0 + gap, abs=0.1)  # on the probe's heads
        assert c.point_b[2] == pytest.approx(30.0, abs=0.1)        # on the block's top


def test_the_smallest_clearance_of_a_path_is_the_gap_geometry_gives_with_few_exact_distances():
    """A table turn with the probe held above a round part's top (every pose as near as the
    best) and a sweep dipping to its lowest in the middle: the smallest clearance is the
    gap, at the pose geometry says, and the search takes few exact distances (hulls are a
    hair thick: an exact search took one at every pose of the turn)."""
    disc = trimesh.creation.cylinder(radius=40.0, height=30.0, sections=64)
    disc.apply_translation([0.0, 0.0, 15.0])
    cfg = demo_with(Workpiece("disc", disc, disc, "test disc", np.eye(4)))
    model = CollisionModel(cfg.cell.robot, cfg.probe, cfg.table, cfg.workpiece.mesh)

    def q_at(height):
        T = np.eye(4)
        T[:3, :3] = np.diag([1.0, -1.0, -1.0])  # beam straight down, over the axis
        T[:3, 3] = [0.0, 0.0, height]
        res = cfg.cell.ik(T, cfg.q_start, relative_to="table", table_angle_rad=0.0)
        assert res.success
        return res.q

    gap = 12.0
    turn = np.linspace(0.0, 2 * np.pi, 400, endpoint=False)
    found = model.check(np.repeat(q_at(30.0 + HEAD_REACH_MM + gap)[None], len(turn), axis=0), turn)
    nearest = found.nearest[0]
    assert nearest.distance_mm == pytest.approx(gap, abs=0.1)
    assert (nearest.body_a, nearest.body_b) == ("probe", "workpiece")
    assert found.exact_queries < 40, found.exact_queries  # far fewer than the 400 poses

    lows = 5.0 + 10.0 * np.abs(np.linspace(-1.0, 1.0, 21))  # 15 mm down to 5 at frame 10 and up
    q = np.array([q_at(30.0 + HEAD_REACH_MM + g) for g in lows])
    nearest = model.check(q, np.zeros(len(q))).nearest[0]
    assert nearest.distance_mm == pytest.approx(5.0, abs=0.1) and nearest.position == pytest.approx(10.0)


def test_a_sweep_dipping_2_mm_into_a_block_is_refused_at_the_frame_geometry_gives():
    scanner = Scanner(workpiece=block_part())
    start = -110.0
    scanner.move_to(((0.0, start, 60.0), (0.0, 180.0, 0.0)))
    scanner.move_to(((0.0, start, 30.0), (0.0, 180.0, 0.0)))  # heads at 28 mm: 2 mm below the top
    q_before = scanner.q
    step = 5.0
    with pytest.raises(CollisionError) as err:
        scanner.sweep([0.0, start, 30.0], [0.0, -start, 30.0], 45)
    # The leading camera head (72 mm ahead along the motion) comes within the 2 mm clearance of the
    # block's side at y = -20 once the probe passes y = -20 - 2 - 72 = -94: between frames 3 and 4.
    first = math.ceil((-20.0 - 2.0 - HEAD_X_MM - start) / step)
    msg = str(err.value)
    assert f"moving to frames {first}-" in msg and "probe" in msg and "workpiece" in msg, msg
    np.testing.assert_array_equal(scanner.q, q_before)  # nothing moved


def test_a_move_down_into_a_block_is_reported_at_its_deepest_not_where_it_first_passes_the_limit():
    # The probe lowered straight down to 20 mm above the table, its heads 10 mm inside a 30 mm
    # block: the motion first passes the 2 mm limit at about 2 mm, but ends inside. The message
    # gives the nearest the motion comes (touching), and so does the record.
    scanner = Scanner(workpiece=block_part())
    scanner.move_to(((0.0, 0.0, 60.0), (0.0, 180.0, 0.0)))
    with pytest.raises(CollisionError) as err:
        scanner.move_to(((0.0, 0.0, 20.0), (0.0, 180.0, 0.0)))
    # A step of the Scanner has no frames to name: the motion is "on the way there", and the
    # pose it ends at, 10 mm inside the block, collides too (a cell designer's trial: the
    # message said only "on the way there" of a target inside the part).
    assert ("move refused, nothing moved: on the way there and at the pose moved to: the probe touches the "
            "workpiece") in str(err.value), str(err.value)
    assert "the arm itself" not in str(err.value)  # the probe's own clearance is the knob there
    cfg = scanner.config
    model = CollisionModel(cfg.cell.robot, cfg.probe, cfg.table, cfg.workpiece.mesh)
    down = [cfg.cell.ik(_beam_down_at(z), scanner.q, relative_to="table", table_angle_rad=0.0).q for z in (60.0, 20.0)]
    found = model.check(np.array(down), np.zeros(2))
    (first, _), deepest = found.collisions[0], found.deepest[0]
    assert 0.0 < first.distance_mm < 2.0 and deepest.distance_mm <= 0.0


def _beam_down_at(z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])
    T[:3, 3] = [0.0, 0.0, z]
    return T


def _inside_the_table(points_table: np.ndarray) -> np.ndarray:
    r = np.hypot(points_table[:, 0], points_table[:, 1])
    return (r <= TABLE_RADIUS_MM) & (points_table[:, 2] <= 0.0) & (points_table[:, 2] >= -TABLE_THICKNESS_MM)


def test_a_pose_with_a_link_in_the_table_is_refused_naming_that_link():
    scanner = Scanner()
    cfg = scanner.config
    q = np.radians([-18.7, 125.3, -99.6, -49.3, 39.5, 148.1])
    # The premise, from geometry alone: link 4's cylinders reach into the table's disc.
    frames = cfg.cell.robot.link_frames(q)
    base2table = cfg.table.base2table(0.0)
    pts = []
    for c in link_cylinders(cfg.cell.robot)[3]:
        mesh = trimesh.creation.cylinder(radius=c.radius_mm, segment=np.array([c.p0, c.p1]), sections=32)
        surface = trimesh.sample.sample_surface_even(mesh, 4000, seed=1)[0]
        world = surface @ frames[4][:3, :3].T + frames[4][:3, 3]
        pts.append(world @ base2table[:3, :3].T + base2table[:3, 3])
    assert _inside_the_table(np.vstack(pts)).any()
    # The pose itself is refused naming the link.
    with pytest.raises(CollisionError, match="at frame 0: link 4 touches the table") as arm:
        check_motion(cfg, q[None, :], np.zeros(1))
    # The arm, not the probe: the message points to its posture as well as to the clearance.
    assert "the arm itself is in the way: another posture" in str(arm.value) and "start_deg" in str(arm.value)
    # A scanner refuses to move there (the probe sweeps through the table on the way first) and
    # stays where it was, clear.
    q_before = scanner.q
    with pytest.raises(CollisionError, match="move refused, nothing moved"):
        scanner.move_joints(q)
    np.testing.assert_array_equal(scanner.q, q_before)
    assert not scanner.clearance().collisions


def test_a_probe_wholly_inside_a_closed_part_touches_it():
    big = trimesh.creation.box([400.0, 400.0, 400.0])
    big.apply_translation([0.0, 0.0, 200.0])
    cfg = demo_with(Workpiece("crate", big, big, "test", np.eye(4)))
    model = CollisionModel(cfg.cell.robot, cfg.probe, cfg.table, cfg.workpiece.mesh)
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])
    T[:3, 3] = [0.0, 0.0, 210.0]  # the probe sits 190 mm deep inside the 400 mm crate
    res = cfg.cell.ik(T, cfg.q_start, relative_to="table", table_angle_rad=0.0)
    found = model.clearance_at(res.q, 0.0)
    assert any(a.body_a == "probe" and a.body_b == "workpiece" and a.distance_mm <= 0 for a, _ in found.collisions)


def test_every_bundled_scene_is_clear_and_reports_its_clearance():
    from addon.core.config.toml import RIGS_DIR

    for path in sorted((RIGS_DIR / "scenes").glob("*.toml")):
        plan = plan_scan(load_scan_config(path))
        rep = plan.clearance.report()
        assert rep["nearest"]["clearance_mm"] > rep["min_clearance_mm"], path.name
        assert set(rep["per_path"]) == {str(k) for k in np.unique(load_scan_config(path).waypoints.segment)}


def test_a_fixture_in_the_way_is_refused_before_the_range_check(tmp_path):
    clamp = trimesh.creation.box([20.0, 20.0, 300.0])  # a post 300 mm tall beside the sphere: into the probe
    clamp.apply_translation([0.0, 45.0, 150.0])
    clamp.export(tmp_path / "post.stl")
    text = open(load_scan_config("demo").source).read()
    cfg_file = tmp_path / "scan.toml"
    cfg_file.write_text(text.replace("[[path]]", '[[fixture]]\nname = "post"\nfile = "post.stl"\n\n[[path]]', 1))
    cfg = load_scan_config(cfg_file)
    assert cfg.fixtures and cfg.fixtures[0].name == "fixture post"
    with pytest.raises(CollisionError, match="fixture post"):
        plan_scan(cfg)
    # Checks off: the same path plans (and its range check passes).
    assert plan_scan(replace(cfg, safety=replace(cfg.safety, check=False))).clearance is None


def test_a_config_asks_for_its_clearance_and_bad_values_are_refused(tmp_path):
    text = open(load_scan_config("demo").source).read()
    for value, ok in (("5.0", True), ("-1", False), ('"two"', False)):
        f = tmp_path / "c.toml"
        f.write_text(text + f"\n[safety]\nmin_clearance_mm = {value}\n")
        if ok:
            assert load_scan_config(f).safety.min_clearance_mm == 5.0
        else:
            with pytest.raises(ConfigError, match="min_clearance_mm"):
                load_scan_config(f)
    with pytest.raises(InputError):
        CollisionModel(load_scan_config("demo").cell.robot, load_scan_config("demo").probe,
                       load_scan_config("demo").table, None, min_clearance_mm=float("nan"))


def test_neighbouring_links_are_not_pairs_but_distant_ones_are():
    cfg = load_scan_config("demo")
    model = CollisionModel(cfg.cell.robot, cfg.probe, cfg.table, cfg.workpiece.mesh)
    names = {(model.bodies[i].name, model.bodies[j].name) for i, j, _ in model.pairs}
    assert ("link 1", "link 2") not in names and ("link 2", "link 1") not in names
    assert ("probe", "link 6") not in names
    assert ("link 1", "link 4") in names and ("probe", "table") in names and ("link 3", "workpiece") in names


def test_a_world_fixture_in_the_lasers_way_is_warned_of_and_a_table_fixture_is_not():
    """World fixtures are collision bodies only (no engine renders them), so one the laser
    meets before the part would not hide it: the plan says so, naming the fixture and the
    frames. A post over the sphere's top given in the robot base's frame at the table's axis,
    and one out of the laser's reach. The same post on the table is rendered with the part:
    nothing to warn of."""
    from addon.core.safety import Fixture
    from addon.core.scan.plan import fixture_warnings

    demo = load_scan_config("demo")
    post = trimesh.creation.box([40.0, 40.0, 116.0])
    # 64..180 mm over the table, 4 mm over the sphere's top (a post down to the table would
    # stand in the part, which is refused): the probe passes 28 mm above it.
    post.apply_translation([0.0, 0.0, 122.0])
    axis = demo.cell.table.table2base(0.0)
    world_post = post.copy()
    world_post.apply_transform(axis)
    aside = world_post.copy()
    aside.apply_translation([200.0, 0.0, 0.0])
    plan = plan_scan(replace(demo, fixtures=(Fixture("fixture post", world_post, "world"),
                                             Fixture("fixture aside", aside, "world"))))
    met = fixture_warnings(plan.fixture_frames, len(plan.q))
    assert len(met) == 1 and "fixture post" in met[0] and "not rendered" in met[0], met
    # The demo's beam points at the sphere for most of its 180 frames: the post is in its way there.
    assert set(plan.fixture_frames) == {"fixture post"} and len(plan.fixture_frames["fixture post"]) > 90
    assert not plan_scan(demo).fixture_frames
    low = trimesh.creation.box([40.0, 40.0, 100.0])  # on the table: rendered (100 mm tall: inside the range)
    low.apply_translation([0.0, 0.0, 50.0])
    assert not plan_scan(replace(demo, fixtures=(Fixture("fixture post", low, "table"),))).fixture_frames
    # Step by step, the Scanner's report says the same, once per fixture however many moves:
    # of each sweep's 4 frames (y = -40, -13, 13, 40 mm; the line across the motion, along x),
    # the laser meets the two over the post's 40 mm, and at the two others the post stands
    # between the table it lights and a camera (camera 0 sits 60 mm on the +y side of the
    # line, camera 1 60 mm on the -y side, both at z = 215 mm: from (0, -40, 0) camera 0's
    # sight line crosses y = -20 at z = 72 mm, inside the 180 mm post).
    cfg = replace(demo, render=replace(demo.render, engine="raycast"),
                  fixtures=(Fixture("fixture post", world_post, "world"),))
    s = Scanner(config=cfg)
    for _ in range(2):
        s.sweep([-20.0, -40.0, 215.0], [-20.0, 40.0, 215.0], 4, table_deg=0.0)
    met = [w for w in s.report().to_dict()["warnings"] if "stands in the laser's way" in w]
    assert len(met) == 1 and "at 8 of 8 frames (0-7)" in met[0], met
    # A configured path run after them counts on from there, in the same one warning.
    path = replace(cfg, waypoints=cfg.waypoints.select(np.arange(10)))
    s2 = Scanner(config=path)
    s2.sweep([-20.0, -140.0, 215.0], [-20.0, -100.0, 215.0], 4)  # well clear of the post, laser and cameras
    s2.run()
    met = [w for w in s2.report().to_dict()["warnings"] if "stands in the laser's way" in w]
    assert len(met) == 1 and "of 14 frames (4-" in met[0], met


def test_a_fixture_that_hides_the_line_from_a_camera_only_is_warned_of_too():
    """A small world fixture halfway along camera 0's sight line to the spot the laser's centre
    lights on the table (30 mm off the laser plane, so the fan never meets it) hides that spot
    from the camera: warned. The same cube beyond the camera, or 15 mm off the plane that every
    sight line from the line to the camera lies in, hides nothing; nor does it where a table
    fixture (rendered) already hides the spot from that camera nearer the table."""
    from addon.core.kinematics.path import sweep
    from addon.core.safety import Fixture
    from addon.core.scan.plan import cell_surfaces, fixtures_in_the_way

    demo = load_scan_config("demo")
    # one pose of a sweep along y: the line along x, the beam straight down from (-20, -140, 215)
    probe2table = sweep(2, [-20.0, -140.0, 215.0], [-20.0, -100.0, 215.0], [0.0, 0.0, -1.0], None,
                        table_rad=0.0).probe2table[:1]
    spot = np.array([-20.0, -140.0, 0.0])  # the beam straight down onto the table top (z = 0)
    camera = (probe2table[0] @ demo.probe.cam2probe(0))[:3, 3]
    assert abs(camera[1] - spot[1]) > 30  # the camera's sight line leaves the laser plane (y = -140)
    # The plane of camera 0's sight lines: through the lit line (along x) and the camera.
    off = np.cross([1.0, 0.0, 0.0], camera - spot)
    off /= np.linalg.norm(off)

    def cube(at, on="world", size=(4.0, 4.0, 4.0)):
        c = trimesh.creation.box(size)
        c.apply_translation(at)
        if on == "world":
            c.apply_transform(demo.cell.table.table2base(0.0))  # given in the robot base's frame
        return c

    def found(*fixtures):
        cfg = replace(demo, fixtures=fixtures)
        hits = fixtures_in_the_way(cfg, probe2table, np.zeros(1), cell_surfaces(cfg))
        return {k: v.tolist() for k, v in hits.items()}

    halfway = Fixture("fixture halfway", cube(spot + 0.5 * (camera - spot)), "world")
    assert found(halfway, Fixture("fixture beyond", cube(spot + 1.3 * (camera - spot)), "world"),
                 Fixture("fixture aside", cube(spot + 0.5 * (camera - spot) + 15.0 * off), "world")) \
        == {"fixture halfway": [0]}
    # A table fixture a quarter of the way up the same sight line, 12 mm long along the line
    # (so it covers every sight line the cube halfway up crosses), hides those spots already.
    wall = Fixture("fixture wall", cube(spot + 0.25 * (camera - spot), on="table", size=(12.0, 4.0, 4.0)), "table")
    assert found(halfway, wall) == {}


@pytest.mark.parametrize("gap_mm, warned", [(-0.5, True), (-2.0, True), (0.0, False), (1.0, False)])
def test_a_table_fixture_reaching_into_the_part_is_warned_of_and_one_that_touches_it_is_not(gap_mm, warned):
    """A 20 mm jaw beside the demo's sphere (radius 30 mm, centre 30 mm up), its face at
    30 + gap_mm from the axis: pressed into the sphere it is warned of, with the depth (the
    sphere's mesh vertices inside the jaw, so at most the true 0.5 or 2 mm); touching or
    standing clear it is not."""
    from addon.core.safety import Fixture
    from addon.core.scan.plan import fixtures_in_the_part

    jaw = trimesh.creation.box([20.0, 20.0, 20.0])
    jaw.apply_translation([40.0 + gap_mm, 0.0, 30.0])
    cfg = replace(load_scan_config("demo"), fixtures=(Fixture("fixture jaw", jaw, "table"),))
    said = fixtures_in_the_part(cfg)
    if not warned:
        assert said == []
        return
    (line,) = said
    depth = float(line.split(" reaches ")[1].split(" mm")[0])
    assert line.startswith("fixture jaw reaches") and 0.6 * -gap_mm <= depth <= -gap_mm + 1e-6


def test_the_fixture_check_sees_a_rod_through_the_part_and_names_an_open_mesh_and_turns_an_inside_out_one():
    """A 4 mm rod pushed through the middle of a 40 mm box part (no vertex of either inside the
    other): warned of, reaching 20 − √2 mm into it at most (its surface 45° round from the
    axis, nearest two faces), at least 18 mm, from the box's own geometry; an open
    fixture is named as unchecked; an inside-out jaw standing 0.5 mm clear is not warned of."""
    from addon.core.safety import Fixture
    from addon.core.scan.plan import fixtures_in_the_part

    box = trimesh.creation.box([40.0, 40.0, 40.0])
    box.apply_translation([0.0, 0.0, 20.0])
    cfg = replace(load_scan_config("demo"), workpiece=Workpiece("box", box, box, "test:box", np.eye(4)))
    rod = trimesh.creation.cylinder(radius=2.0, height=80.0, sections=32)
    rod.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    rod.apply_translation([0.0, 0.0, 20.0])
    (line,) = fixtures_in_the_part(replace(cfg, fixtures=(Fixture("fixture rod", rod, "table"),)))
    depth = float(line.split(" reaches ")[1].split(" mm")[0])
    assert 18.0 <= depth <= 20.0 - np.sqrt(2.0) + 1e-3
    open_plate = trimesh.Trimesh(vertices=[[30, -5, 0], [40, -5, 0], [40, 5, 0]], faces=[[0, 1, 2]])
    assert fixtures_in_the_part(replace(cfg, fixtures=(Fixture("fixture plate", open_plate, "table"),))) == [
        "fixture plate is not a closed mesh, so whether it reaches into the part was not checked"]
    jaw = trimesh.creation.box([20.0, 20.0, 20.0])
    jaw.apply_translation([30.5, 0.0, 20.0])  # its face 0.5 mm clear of the box's side at x = 20
    jaw.invert()
    assert jaw.volume < 0
    assert fixtures_in_the_part(replace(cfg, fixtures=(Fixture("fixture jaw", jaw, "table"),))) == []


def test_a_gantrys_frame_is_one_body_per_side_so_its_bounds_still_decide():
    """The gantry URDF's base is its two side frames, 1.4 m apart around the work area: as one
    body its bounds held the whole cell and every pose needed exact distances (57 357 on its
    scan); one body per side keeps them to a handful. The probe is still checked against them."""
    config = load_scan_config("gantry_urdf")
    model = CollisionModel(config.cell.robot, config.probe, config.table, config.workpiece.mesh)
    sides = [b for b in model.bodies if b.name.startswith("robot base")]
    assert len(sides) == 2 and all(b.radius < 1100.0 for b in sides)  # each a 1.6 × 1.3 m wall
    names = {(model.bodies[i].name, model.bodies[j].name) for i, j, _ in model.pairs}
    assert ("probe", sides[0].name) in names
    # A table turn swings the part round: it is checked against the frames too (their bounds decide it).
    assert {(side.name, "workpiece") for side in sides} <= names
    plan = plan_scan(config)
    assert plan.clearance.exact_queries < 500, plan.clearance.exact_queries


def test_a_base_whose_file_keeps_its_vertices_apart_is_still_one_body():
    """A pedestal box as a textured file stores it (every triangle its own three vertices) is
    one piece: split where the vertices are shared, not into a body per triangle."""
    from addon.core.config.rigs import load_probe, load_robot
    from addon.core.kinematics.turntable import Turntable

    box = trimesh.creation.box([200.0, 200.0, 300.0])
    loose = trimesh.Trimesh(box.vertices[box.faces].reshape(-1, 3), np.arange(3 * len(box.faces)).reshape(-1, 3),
                            process=False)
    assert len(loose.split(only_watertight=False)) == 12  # what a split without merging gives
    robot = replace(load_robot("adept_viper_s650"), base_mesh=(loose, np.eye(4)))
    model = CollisionModel(robot, load_probe("default"), Turntable())
    assert [b.name for b in model.bodies if b.name.startswith("robot base")] == ["robot base"]


def test_a_joint_turning_far_between_path_entries_is_said():
    """Two sweeps over the step block, the second back along the first with its laser line
    turned end for end: the probe turns half a turn about its beam between the entries, which
    the Viper's wrist does with its last joint, and the plan says so (a repositioning no path
    entry shows). A second sweep across the first, from its end, with its line turned a
    quarter turn, says nothing."""
    from addon.core.kinematics import path as kp

    base = load_scan_config("step_block")
    said = {}
    for name, line, to in (("half", (0.0, -1.0, 0.0), [-45.0, 0.0, 200.0]),
                           ("quarter", (1.0, 0.0, 0.0), [45.0, 40.0, 200.0])):
        a = kp.sweep(20, [-45.0, 0.0, 200.0], [45.0, 0.0, 200.0], line=(0.0, 1.0, 0.0), segment=0)
        b = kp.sweep(20, [45.0, 0.0, 200.0], to, line=line, segment=1)
        both = kp.Waypoints(np.concatenate([a.probe2table, b.probe2table]), np.concatenate([a.table_rad, b.table_rad]),
                            np.concatenate([a.segment, b.segment]))
        said[name] = [w for w in plan_scan(replace(base, waypoints=both)).warnings if "repositions" in w]
    assert said["quarter"] == []
    (line,) = said["half"]
    assert line.startswith("between path[1] and path[2] (before frame 20) the robot repositions: J6 by ")
    assert float(line.split("J6 by ")[1].split("°")[0]) == pytest.approx(180.0, abs=1.0)


def test_a_collision_on_the_way_from_the_start_pose_says_it_is_the_approach():
    """The probe looking at the demo's sphere from one side (the start pose) and then from the
    other (frame 0), 40 mm above the table: each pose is clear, the joint motion between them
    is not, and the refusal names the approach from the start pose, not frame 0 (a cell
    designer's trial: "moving to frame 0" read as frame 0 itself)."""
    from addon.core.scan.plan import check_motion

    cfg = load_scan_config("demo")

    def looking_across(y):
        T = np.eye(4)
        beam, x = np.array([0.0, -np.sign(y), 0.0]), np.array([1.0, 0.0, 0.0])
        T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, np.cross(beam, x), beam, [0.0, y, 40.0]
        return T

    q_start = cfg.cell.ik(looking_across(-110.0), cfg.q_start, relative_to="table", table_angle_rad=0.0).q
    q0 = cfg.cell.ik(looking_across(110.0), q_start, relative_to="table", table_angle_rad=0.0).q
    for q in (q_start, q0):
        assert check_motion(cfg, np.stack([q, q]), np.zeros(2), np.zeros(2, int)).ok
    with pytest.raises(CollisionError, match="^moving from the start pose to frame 0: "):
        check_motion(cfg, np.stack([q0, q0]), np.zeros(2), np.zeros(2, int), q_start)


def test_a_collision_on_a_configs_path_names_the_path_entry():
    """A post on the table 110-130 mm from the demo's axis, at the probe's height: the table
    turn (path[1]) keeps the probe's origin 12 mm from the axis, so its body (the boxes reach
    at most 77.6 mm across from the origin) stays 20 mm short; the sweep (path[2]) takes the
    origin to x = 40 mm and the housing's 75 mm half-length into the post. The refusal names
    the sweep's entry beside its frames."""
    from addon.core.config.rigs import load_probe
    from addon.core.safety import Fixture

    reach = max(float(np.hypot(abs(c[0]) + e[0] / 2, abs(c[1]) + e[1] / 2))
                for _, e, c in load_probe("default").body_boxes())
    assert 12.0 + reach < 110.0 - 2.0 < 40.0 + 75.0
    post = trimesh.creation.box([20.0, 40.0, 60.0])
    post.apply_translation([120.0, 0.0, 230.0])
    cfg = replace(load_scan_config("demo"), fixtures=(Fixture("fixture post", post, "table"),))
    with pytest.raises(CollisionError, match=r"^moving to frames \d+-179 \(path\[2\]\): the probe touches fixture post") as hit:
        plan_scan(cfg)
    # Over a run of frames the message names the worst one (the two nearest), inside the run.
    first = int(str(hit.value).split("frames ")[1].split("-")[0])
    nearest = int(str(hit.value).split("(worst ")[1].split("frame ")[1].split(")")[0])
    assert first <= nearest <= 179, str(hit.value)


def test_a_path_out_of_the_probes_range_is_told_which_way_to_move():
    """A probe looking down at the demo's table 50 mm below it, 100 mm from the sphere, sees its
    nearest surface 50 mm away, nearer than the 70 mm the probe's range starts at; over the
    sphere (its top 60 mm above the table) at 330 mm the nearest is 270 mm away, beyond the
    250 mm it ends at. Each refusal says which way to move."""
    from addon.core.errors import ScannerError
    from addon.core.kinematics import path as kp

    cfg = load_scan_config("demo")
    for y, z, said in ((100.0, 50.0, "the laser meets a surface 50 mm from the probe, nearer than its 70 mm: move "
                                     "the path away from it"),
                       (0.0, 330.0, "the nearest surface lies 270 mm away, beyond the probe's 250 mm: move the path "
                                    "closer")):
        wp = kp.sweep(2, [-0.5, y, z], [0.5, y, z])
        with pytest.raises(ScannerError, match="2 of 2 waypoints put no surface inside the probe's range 70-250 mm") as err:
            plan_scan(replace(cfg, waypoints=wp))
        assert said in str(err.value), str(err.value)


def test_merging_checks_keeps_every_count_and_collision_and_numbers_later_entries_on():
    """A Scanner's report merges its checks (one, for a scan of a config's path): the first
    keeps its path-entry numbers, later ones are numbered after them, and nothing else is lost."""
    from addon.core.safety.clearance import Contact, PathClearance

    def check(entries, samples, collide):
        p = PathClearance(2.0, samples=samples, exact_queries=samples // 2, bound_queries=samples)
        p.nearest = {k: Contact(10.0 + k, "probe", "table", float(k)) for k in entries}
        if collide:
            hit = Contact(0.0, "probe", "workpiece", 3.0)
            p.collisions, p.deepest = [(hit, hit)], [hit]
        return p

    merged = PathClearance.merge([check([1, 2], 40, True), check([0], 7, False)])
    assert sorted(merged.nearest) == [1, 2, 3] and merged.nearest[3].distance_mm == 10.0
    assert (merged.samples, merged.exact_queries, merged.bound_queries) == (47, 23, 47)
    assert len(merged.collisions) == len(merged.deepest) == 1 and not merged.ok
    single = PathClearance.merge([check([1], 62, False)])
    assert single.report()["samples_checked"] == 62 and list(single.report()["per_path"]) == ["1"]


def test_a_part_wholly_inside_a_closed_link_mesh_touches_it():
    """A 10 mm sphere inside the UR5 URDF's upper-arm cylinder (checked by trimesh: every
    vertex inside) is a collision, not 44 mm of clearance: the link's closed mesh is asked
    whether the part lies in it, at a point of the part (its frame's origin is the table's
    centre, far from it)."""
    import trimesh

    from addon.core.config.rigs import load_probe, load_robot
    from addon.core.config.toml import RIGS_DIR
    from addon.core.kinematics.link_shapes import link_mesh
    from addon.core.kinematics.turntable import Turntable
    from addon.core.safety.clearance import CollisionModel

    probe = load_probe("default")
    robot = load_robot(RIGS_DIR / "robots" / "urdf" / "ur5.urdf").with_tool(probe.mount)
    table = Turntable()
    q = np.radians([0, -90, 90, -90, -90, 0])
    frame = robot.link_frames(q)[2]
    upper = link_mesh(robot, 1, collision=True)
    centre = trimesh.transform_points(upper.bounds.mean(axis=0)[None], table.base2table(0.0) @ frame)[0]
    part = trimesh.creation.icosphere(subdivisions=3, radius=10.0)
    part.apply_translation(centre)
    in_link = trimesh.transform_points(part.vertices, np.linalg.inv(table.base2table(0.0) @ frame))
    assert upper.contains(in_link).all()  # the truth, from trimesh
    found = CollisionModel(robot, probe, table, part).clearance_at(q, 0.0)
    assert not found.ok and "link 2" in found.message() and "workpiece" in found.message()


def _with_clearance(scanner: Scanner, mm: float) -> None:
    cfg = scanner.config
    scanner.config = replace(cfg, safety=replace(cfg.safety, min_clearance_mm=mm))


def test_no_clearance_asked_for_still_refuses_touching():
    """min_clearance_mm = 0: bodies may come as near as they like, but an exact distance of 0
    (touching, or inside) was not below the limit of 0, and the probe went 10 mm into the part."""
    scanner = Scanner(workpiece=block_part())
    _with_clearance(scanner, 0.0)
    scanner.move_to(((0.0, 0.0, 60.0), (0.0, 180.0, 0.0)))
    with pytest.raises(CollisionError, match="the probe touches the workpiece; they must not touch"):
        scanner.move_to(((0.0, 0.0, 20.0), (0.0, 180.0, 0.0)))
    scanner.move_to(((0.0, 0.0, 30.0 + HEAD_REACH_MM + 0.5), (0.0, 180.0, 0.0)))  # 0.5 mm above: allowed
    assert scanner.clearance().nearest[0].distance_mm == pytest.approx(0.5, abs=0.01)


def test_a_robot_that_stands_too_near_can_back_away_but_come_no_nearer():
    """The clearance raised while the probe stands 1.5 mm above the part: every move was
    refused "at the start pose", backing away too. A single move that comes no nearer goes;
    one that comes nearer, and a sweep from there, do not."""
    scanner = Scanner(workpiece=block_part())
    _with_clearance(scanner, 1.0)
    scanner.move_to(((0.0, 0.0, 60.0), (0.0, 180.0, 0.0)))
    scanner.move_to(((0.0, 0.0, 30.0 + HEAD_REACH_MM + 1.5), (0.0, 180.0, 0.0)))
    _with_clearance(scanner, 2.0)
    with pytest.raises(CollisionError, match="comes within 0.50 mm of the workpiece"):
        scanner.move_to(((0.0, 0.0, 30.0 + HEAD_REACH_MM + 0.5), (0.0, 180.0, 0.0)))
    with pytest.raises(CollisionError, match="at the start pose"):
        scanner.plan_sweep([0.0, -10.0, 100.0], [0.0, 10.0, 100.0], 5)
    with pytest.raises(CollisionError, match="at the start pose"):  # a sweep of one frame is a sweep
        scanner.plan_sweep([0.0, 0.0, 100.0], [0.0, 10.0, 100.0], 1)
    scanner.move_to(((5.0, 0.0, 30.0 + HEAD_REACH_MM + 1.5), (0.0, 180.0, 0.0)))  # along, no nearer
    scanner.move_to(((0.0, 0.0, 150.0), (0.0, 180.0, 0.0)))  # away
    assert scanner.pose()[2, 3] == pytest.approx(150.0)


def test_a_table_turn_that_swings_the_part_into_a_world_fixture_is_refused():
    """A 300 mm bar on the table and a post standing in the world where the bar's end comes
    at a quarter turn: the table's part was checked against the robot only. The post is
    placed from the table's own pose, 10 mm into the bar's path; clear at the start."""
    from addon.core.safety import Fixture

    bar = trimesh.creation.box([300.0, 20.0, 20.0])
    bar.apply_translation([0.0, 0.0, 10.0])
    cfg = demo_with(Workpiece("bar", bar, bar, "test bar", np.eye(4)))
    end_at_quarter_turn = (cfg.table.table2base(math.pi / 2) @ np.array([140.0, 0.0, 10.0, 1.0]))[:3]
    post = trimesh.creation.box([20.0, 20.0, 100.0])
    post.apply_translation(end_at_quarter_turn + [0.0, 0.0, 45.0])  # 5 mm above the table top, which it
    # must not touch (a world fixture against the turning disc)
    scanner = Scanner(config=replace(cfg, fixtures=(Fixture("post", post, "world"),)))
    scanner.turn_table_to(30.0)
    with pytest.raises(CollisionError, match="post touches the workpiece"):
        scanner.turn_table_to(90.0)
    assert scanner.table_deg == pytest.approx(30.0)
    scanner.turn_table_to(-60.0)  # the other way round, clear of the post
    gantry = load_scan_config("gantry_urdf")
    model = CollisionModel(gantry.cell.robot, gantry.probe, gantry.table, gantry.workpiece.mesh)
    names = {(model.bodies[i].name, model.bodies[j].name) for i, j, _ in model.pairs}
    assert {("robot base (piece 1)", "workpiece"), ("robot base (piece 2)", "workpiece")} <= names


def test_a_fixture_made_in_code_keeps_the_clearance_whatever_its_name():
    """A Fixture named without the config loader's "fixture " prefix was taken for a robot
    body in the message ("they must not touch" where 2 mm are asked for)."""
    from addon.core.safety import Fixture

    clamp = trimesh.creation.box([20.0, 20.0, 20.0])
    clamp.apply_translation([0.0, 60.0, 10.0])
    scanner = Scanner(config=replace(load_scan_config("demo"), fixtures=(Fixture("clamp", clamp, "table"),)))
    with pytest.raises(CollisionError, match="of the clamp; at least 2 mm allowed"):
        scanner.move_to(((0.0, 60.0, 20.0 + HEAD_REACH_MM + 1.0), (0.0, 180.0, 0.0)))


@pytest.mark.parametrize("case", ["through the rim", "beside", "pedestal under it"])
def test_a_world_fixture_through_the_tables_disc_is_refused_and_one_beside_or_under_it_is_not(case):
    """A post standing in the world, reaching from below the disc to above its top: through the
    rim (10 mm in) it would stop the table turning, and was checked against the robot's moving
    bodies only; 5 mm beside the rim, or a pedestal touching the disc's underside (a user
    modelling the table's stand), the table turns."""
    from addon.core.kinematics.turntable import TABLE_RADIUS_MM, TABLE_THICKNESS_MM
    from addon.core.safety import Fixture

    cfg = load_scan_config("demo")
    if case == "pedestal under it":
        post = trimesh.creation.cylinder(radius=40.0, height=300.0, sections=48)
        post.apply_translation([0.0, 0.0, -TABLE_THICKNESS_MM - 150.0])  # its top on the disc's underside
    else:
        gap_mm = -10.0 if case == "through the rim" else 5.0
        post = trimesh.creation.box([20.0, 20.0, 100.0])
        post.apply_translation([TABLE_RADIUS_MM + gap_mm + 10.0, 0.0, 0.0])  # z -50..50 in the table frame
    post.apply_transform(cfg.table.table2base(0.0))  # a world fixture is given in the robot base's frame
    fixtures = (Fixture("fixture post", post, "world"),)
    if case == "through the rim":
        with pytest.raises(CollisionError, match=r"fixture post reaches (9\.9|10\.0) mm into the rotary table's disc"):
            Scanner(config=replace(cfg, fixtures=fixtures)).turn_table_to(30.0)
        return
    scanner = Scanner(config=replace(cfg, fixtures=fixtures))
    scanner.turn_table_to(30.0)
    assert scanner.table_deg == pytest.approx(30.0)


def test_a_breach_by_a_hair_is_not_shown_as_the_limit_it_breached(tmp_path):
    """A pose 1.9999 mm from the table was refused as "comes within 2.00 mm; at least 2 mm
    allowed" (a hunt). The probe's lowest point over the table top: 2 mm less 0.1 µm, from the
    geometry of a pose 2 mm clear moved down."""
    demo = (REPO / "rigs" / "scenes" / "demo.toml").read_text()
    config = tmp_path / "graze.toml"
    config.write_text(demo[:demo.index("[workpiece]")] + '[workpiece]\nshape = "sphere"\nradius_mm = 5.0\n'
                      '[workpiece.pose]\nxyz_mm = [0.0, 120.0, 0.0]\n' + demo[demo.index("[[path]]"):])
    s = Scanner.from_config(config, engine="raycast")
    s.move_to(([0.0, -40.0, 60.0], [90.0, 180.0, 0.0]))
    _, clear = s.check_move_to(([0.0, -40.0, 4.0], [90.0, 180.0, 0.0]))
    assert clear.report()["nearest"]["clearance_mm"] == pytest.approx(2.0, abs=1e-6)
    with pytest.raises(CollisionError, match=r"comes within 1\.9999\d* mm of the table; at least 2 mm allowed"):
        s.check_move_to(([0.0, -40.0, 4.0 - 1e-4], [90.0, 180.0, 0.0]))


def test_a_scan_with_the_checks_off_says_so(tmp_path, capsys):
    """[safety] check = false left no trace: report.json's clearance null as for a Scanner that
    never moved, no summary line (a hunt)."""
    import json

    from headless.cli import main

    demo = (REPO / "rigs" / "scenes" / "demo.toml").read_text()
    config = tmp_path / "off.toml"
    config.write_text(demo + "\n[safety]\ncheck = false\n")
    assert main(["scan", str(config), "--engine", "raycast", "--frames", "0:3", "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "clearance     not checked ([safety] check = false)" in out
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    assert report["clearance"] is None and any(w.startswith("collision checks were off") for w in report["warnings"])


def test_a_scanner_made_without_a_config_names_no_config_when_its_start_pose_collides(tmp_path):
    """A Scanner given only a part (no config file) whose start pose puts the probe in a tall
    part was told to mend "the config's [robot] start_deg", which it has none of; a config
    file's own start pose still names its key."""
    tall = trimesh.creation.box([300.0, 300.0, 400.0])
    tall.apply_translation([0.0, 0.0, 200.0])
    part = Workpiece("tall", tall, tall, "test tall box", np.eye(4))
    with pytest.raises(CollisionError) as err:
        Scanner(workpiece=part).adaptive(max_profiles=100)
    assert "at the start pose the probe touches the workpiece" in str(err.value)
    assert "config" not in str(err.value) and "start_deg" not in str(err.value)
    cfg = replace(load_scan_config("demo"), workpiece=part)  # from a file: its start_deg is named
    with pytest.raises(CollisionError, match=r"at the start pose \(the config's \[robot\] start_deg\)"):
        Scanner(config=cfg).adaptive(max_profiles=100)
