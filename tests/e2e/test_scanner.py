"""The Scanner API step by step, against the exact sphere of the demo cell."""

import json
import math
import os
import re
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("bpy", reason="scans render with bpy (installed by the README's set-up)")

from addon import Profile, Scanner, ScanReport, UnreachablePose, report_json  # noqa: E402
from addon.core.errors import InputError  # noqa: E402
from addon.core.config.scan import load_scan_config  # noqa: E402
from addon.core.kinematics import path as scanpath  # noqa: E402
from addon.core.kinematics.path import Waypoints  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
CENTRE, RADIUS = np.array([0.0, 0.0, 30.0]), 30.0  # the demo's sphere stands on the table


def sphere_error_um(points):
    return (np.linalg.norm(points - CENTRE, axis=1) - RADIUS) * 1000


@pytest.fixture(scope="module")
def scanner():
    return Scanner.from_config("demo")


def test_measure_puts_points_on_the_exact_sphere(scanner):
    scanner.move_to(([12.0, 0.0, 210.0], [90.0, 180.0, 0.0]))
    np.testing.assert_allclose(scanner.pose()[:3, 3], [12.0, 0.0, 210.0], atol=1e-6)
    p = scanner.measure()
    assert isinstance(p, Profile) and len(p) > 100
    on_sphere = p.points[p.points[:, 2] > 1.0]
    err = sphere_error_um(on_sphere)
    assert len(on_sphere) > 50 and np.sqrt(np.mean(err ** 2)) < 20 and np.abs(err).max() < 100
    assert p.points.shape[1] == 3 and p.sigma_mm.shape == (len(p),) and np.all(p.sigma_mm > 0)
    np.testing.assert_allclose(p.probe2table, scanner.pose(), atol=1e-9)
    assert p.codes.get("OK", 0) > 100
    # Every point lies in the laser plane: through the probe's origin, normal to its X axis.
    normal, origin = p.probe2table[:3, 0], p.probe2table[:3, 3]
    assert np.abs((p.points - origin) @ normal).max() < 0.05


def test_turning_the_table_moves_the_measured_meridian(scanner):
    scanner.move_to(([12.0, 0.0, 210.0], [90.0, 180.0, 0.0]))
    before = scanner.table_deg
    assert scanner.turn_table(90.0) == pytest.approx(before + 90.0)
    p = scanner.measure()
    # In the table frame the probe (and so the laser plane) has turned by -90 degrees about Z.
    expect = np.array([math.cos(math.radians(-90 - before)) * 12, math.sin(math.radians(-90 - before)) * 12])
    np.testing.assert_allclose(p.probe2table[:2, 3], expect, atol=1e-6)
    assert len(p) > 100 and np.sqrt(np.mean(sphere_error_um(p.points[p.points[:, 2] > 1]) ** 2)) < 20


def test_a_refused_move_raises_and_moves_nothing(scanner):
    q, table = scanner.q, scanner.table_deg
    with pytest.raises(UnreachablePose, match="cannot be reached"):
        scanner.move_to(([0.0, 0.0, 2000.0], [90.0, 180.0, 0.0]))
    with pytest.raises(UnreachablePose, match="outside"):
        scanner.move_joints(q + [0, 0, 0, 0, 0, 100.0])
    with pytest.raises(UnreachablePose, match="sweep cannot be reached"):
        scanner.sweep([0, 0, 210], [1500, 0, 210], 5)
    with pytest.raises(InputError):
        scanner.move_to(([0, 0, float("nan")], [90, 180, 0]))
    np.testing.assert_array_equal(scanner.q, q)
    assert scanner.table_deg == table


def test_a_pose_that_sees_nothing_gives_an_empty_profile_without_rendering():
    s = Scanner.from_config("demo")
    s.move_to(([12.0, 0.0, 320.0], [90.0, 180.0, 0.0]))  # the table 320 mm away: beyond the 250 mm range
    p = s.measure()
    assert len(p) == 0 and s._sc is None  # Blender was never asked to render
    # still a measurement: the report counts it, and the next one is numbered after it
    report = s.report().to_dict()
    assert report["frames"] == 1 and report["points"] == 0 and s.measure().frame == p.frame + 1 == 1
    assert s.report().to_dict()["frames"] == 2
    # A planner can ask first, by ray casts alone (nothing moved, nothing measured): a sweep
    # along y 60-100 mm beside the sphere (the laser line along x, so the sphere is never in its
    # plane) has only the table, 300 mm away, beyond the 250 mm range; one at 210 mm across
    # the sphere has it or the table in range in every frame.
    far = s.frames_out_of_range(*s.plan_sweep([0.0, 60.0, 300.0], [0.0, 100.0, 300.0], 9))
    near = s.frames_out_of_range(*s.plan_sweep([-40.0, 0.0, 210.0], [40.0, 0.0, 210.0], 9))
    assert far.tolist() == list(range(9)) and near.tolist() == []
    from addon.core.errors import InputError

    for q, t in ((np.zeros((3, 4)), np.zeros(3)), (np.zeros((2, 6)), np.zeros(3)), (np.full((1, 6), np.nan), [0.0])):
        with pytest.raises(InputError, match="frames_out_of_range needs"):
            s.frames_out_of_range(q, t)
    assert s.report().to_dict()["frames"] == 2
    # and it is said, by frame number, with the range: a sweep run past the part is no failure
    (said,) = [w for w in s.report().to_dict()["warnings"] if "probe's range" in w]
    assert said.startswith("frames 0-1 put no surface inside the probe's range 70-250 mm")


def test_sweep_report_and_save(scanner, tmp_path):
    n0 = len(scanner.cloud)
    profiles = scanner.sweep([-40.0, 0.0, 210.0], [40.0, 0.0, 210.0], 12)
    assert len(profiles) == 12 and len(scanner.cloud) == n0 + sum(len(p) for p in profiles)
    np.testing.assert_allclose(scanner.pose()[:3, 3], [40.0, 0.0, 210.0], atol=1e-6)
    report = scanner.report()
    assert isinstance(report, ScanReport) and report.points == len(scanner.result().cloud) <= len(scanner.cloud)
    assert report.frames == max(p.frame for p in profiles) + 1
    assert report.error_um.rms_um < 20
    files = scanner.save(tmp_path / "out")
    assert {p.name for p in (tmp_path / "out").iterdir()} == {"cloud.ply", "report.json", "preview.png"}
    again = ScanReport.from_dict(json.loads(files["report"].read_text()))
    assert again.points == report.points and again.error_um.rms_um == pytest.approx(report.error_um.rms_um)
    # A place that cannot take the files: one line naming it, as the command line says it.
    (tmp_path / "afile").write_text("x")
    for bad, words in ((tmp_path / "afile", "is a file"), (tmp_path / "afile" / "sub", "is a file, so no folder"),
                       ("/proc/scanner-out", "cannot be written")):
        with pytest.raises(InputError, match=words):
            scanner.save(bad)


def test_run_gives_the_chunk_engines_cloud_point_for_point():
    from addon.pipeline import ScanRun

    s = Scanner.from_config("step_block", frames=slice(0, 100, 10))
    report = s.run()
    run = ScanRun(s.config)  # the engine under Scanner, driven by hand over the same path
    while not run.step():
        pass
    direct = run.finish(None)
    np.testing.assert_array_equal(s.cloud.points, direct.cloud.points)
    assert report.error_um.rms_um == pytest.approx(direct.report["error_um"]["rms_um"])


def test_a_path_stopped_midway_keeps_nothing_of_it_and_the_scanner_goes_on():
    """Ctrl-C (here raised by the progress callback after the first chunk) during a path leaves
    the scanner as it was: no frame, point, pose or warning of the unfinished path; a path
    after it scans and numbers its frames as if the stopped one had never begun."""
    from addon.core.kinematics.path import sweep

    scanner = Scanner.from_config("demo")  # its own cell: the module's may have been replaced by now
    next_frame = scanner.measure().frame + 1
    before = (scanner.report().frames, len(scanner.cloud), scanner.q.copy(), scanner.table_deg)
    kept = {k: scanner.report().to_dict()[k] for k in ("clearance", "warnings", "mean_rows_rendered")}
    path = sweep(24, [-40.0, 10.0, 210.0], [40.0, 10.0, 210.0], [0.0, 0.0, -1.0], None,
                 table_rad=math.radians(scanner.table_deg))

    def ctrl_c(stage, done, total):
        assert 0 < done < total  # stopped inside the path
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        scanner.scan_path(path, progress=ctrl_c)
    frames, points, q, table_deg = before
    assert scanner.report().frames == frames and len(scanner.cloud) == points
    assert np.array_equal(scanner.q, q) and scanner.table_deg == table_deg
    assert {k: scanner.report().to_dict()[k] for k in kept} == kept  # no clearance, warning or stats of it
    profiles = scanner.scan_path(path)
    assert [p.frame for p in profiles] == list(range(next_frame, next_frame + 24))
    assert scanner.report().frames == frames + 24 and len(scanner.cloud) == points + sum(len(p) for p in profiles)
    points = np.concatenate([p.points for p in profiles])
    on_sphere = points[points[:, 2] > 1.0]  # the rest lie on the table top
    assert len(on_sphere) > 500 and np.abs(sphere_error_um(on_sphere)).max() < 60


def test_report_json_is_strict():
    text = report_json({"rms_um": float("nan"), "nested": [float("inf"), 1.0]})
    assert json.loads(text) == {"rms_um": None, "nested": [None, 1.0]}
    assert "NaN" not in text and "Infinity" not in text


def test_the_readme_example_runs_as_written(tmp_path):
    readme = (REPO / "README.md").read_text()
    match = re.search(r"<!-- example:scanner -->\s*```python\n(.*?)```", readme, re.S)
    assert match, "README.md has no Scanner example"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    out = subprocess.run([sys.executable, "-c", match.group(1)], cwd=tmp_path, env=env, capture_output=True,
                         text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert re.search(r"\d+ points, RMS \d+\.\d um", out.stdout), out.stdout
    assert (tmp_path / "out" / "adaptive-example" / "report.json").is_file()


def test_a_scan_is_measured_against_the_truth_once_for_its_report_and_its_files(tmp_path, monkeypatch):
    import addon.pipeline

    measured = []
    assemble = addon.pipeline.assemble
    monkeypatch.setattr(addon.pipeline, "assemble", lambda *a, **k: measured.append(1) or assemble(*a, **k))
    s = Scanner.from_config("demo", engine="raycast")
    s.sweep([-30.0, 0.0, 210.0], [30.0, 0.0, 210.0], 6)
    report = s.report()
    files = s.save(tmp_path / "a")  # save() after report() only writes
    assert len(measured) == 1 and json.loads(files["report"].read_text())["points"] == report.points
    # Written again through the typed report, report.json keeps its keys' order (it took the
    # dataclass's): the two files compare line by line.
    assert list(json.loads(report_json(report))) == list(json.loads(files["report"].read_text()))
    again = ScanReport.from_dict(json.loads(files["report"].read_text()))
    assert report_json(again).strip() == files["report"].read_text().strip()
    assert s.report().points == report.points and len(measured) == 1
    s.measure()
    assert s.report().frames == report.frames + 1 and len(measured) == 2  # a new profile: measured again
    s.config = replace(s.config, coverage_tolerance_mm=2.0)  # another config on the same frames: measured again
    assert s.report().coverage_tolerance_mm == 2.0 and len(measured) == 3


def test_the_stages_times_add_up_to_no_more_than_the_total(monkeypatch):
    """The check of the move to the path's start counted its time in "plan" and was counted
    again with the plan around it: plan 3.6 s of a 4.6 s scan, the stages 6.0 s."""
    import time as _time

    from addon.core.scan import plan as planmod

    check = planmod.check_motion
    monkeypatch.setattr(planmod, "check_motion", lambda *a, **k: _time.sleep(0.5) or check(*a, **k))
    s = Scanner(config=load_scan_config("demo").with_overrides(engine="raycast", frames=slice(0, 4)))
    s.run()
    times = json.loads(report_json(s.report()))["time_s"]
    stages = sum(v for k, v in times.items() if k != "total")
    assert times["plan"] >= 1.0 and stages <= times["total"] * 1.02 + 0.02, times


def test_a_path_run_twice_no_longer_claims_its_frame_numbers():
    """report.json's path_frames gives the path's frame number of each frame scanned: after a
    second run() it listed the first run's 6 for 12 frames."""
    s = Scanner(config=load_scan_config("demo").with_overrides(engine="raycast", frames=slice(0, 120, 20)))
    s.run()
    assert json.loads(report_json(s.report()))["config"]["path_frames"] == [0, 20, 40, 60, 80, 100]
    s.run()
    r = json.loads(report_json(s.report()))
    assert r["frames"] == 12 and r["config"]["path_frames"] is None


def test_save_writes_every_time_and_bad_arguments_are_named(scanner, tmp_path):
    import shutil

    files = scanner.save(tmp_path / "a")
    shutil.rmtree(tmp_path / "a")
    files = scanner.save(tmp_path / "a")  # the same frames, the same folder: written again
    assert all(p.is_file() for p in files.values())
    for call, message in ((lambda: scanner.turn_table("30"), "finite number of degrees"),
                          (lambda: scanner.sweep([0, 0], [10, 0, 210], 5), "from_mm must be three"),
                          (lambda: scanner.sweep([0, 0, 210], [10, float("nan"), 210], 5), "to_mm must be three finite"),
                          (lambda: scanner.plan_sweep([0, 0, 210], [10, 0, 210], 5, beam=[0, 0, 0]),
                           "beam must be a non-zero direction"),
                          # ten turns at most, also as a sweep's table angle and as the turn to an angle
                          (lambda: scanner.sweep([0, 0, 210], [10, 0, 210], 5, table_deg=1e9), "within ±3600"),
                          (lambda: scanner.plan_sweep([0, 0, 210], [10, 0, 210], 5, table_deg=float("nan")),
                           "finite number of degrees"),
                          (lambda: scanner.sweep([0, 0, 210], [10, 0, 210], 2.5), "whole number"),
                          (lambda: scanner.save(None), "output folder"),
                          (lambda: Scanner.from_config("demo", bogus=1), "unknown override 'bogus'")):
        with pytest.raises(InputError, match=message):
            call()


def test_frames_taken_counts_every_profile_measured_as_the_report_does(scanner):
    before = scanner.frames_taken
    scanner.sweep([-10, 0, 210], [10, 0, 210], 5)
    scanner.measure()
    assert scanner.frames_taken == before + 6 == scanner.report().frames
    assert scanner.frames_taken == sum(1 for _ in scanner.measurements())


def test_two_scanners_in_one_session_each_measure_on_their_own_cell():
    """A second Scanner builds its cell over the first's; the first builds its own again at its
    next measurement (it raised Blender's ReferenceError), and measures what it measured before."""
    first, second = Scanner.from_config("demo"), Scanner.from_config("step_block")
    a = first.measure()
    second.move_to(([12.0, 0.0, 210.0], [90.0, 180.0, 0.0]))  # looking down at the block
    b = second.measure()
    again = first.measure()
    assert len(a) > 100 and len(b) > 100
    np.testing.assert_allclose(again.points, a.points, atol=1e-9)
    assert not np.allclose(np.sort(b.points[:, 2])[:50], np.sort(a.points[:, 2])[:50])


def test_a_scanner_from_objects_starts_looking_at_the_table():
    s = Scanner(robot="puma560", probe="default", workpiece="sphere")
    z0, z1 = s.config.probe.z_range_mm
    np.testing.assert_allclose(s.pose()[:3, 3], [0.0, 0.0, (z0 + z1) / 2], atol=1e-6)
    np.testing.assert_allclose(s.pose()[:3, 2], [0.0, 0.0, -1.0], atol=1e-9)  # the beam straight down
    p = s.measure()
    assert len(p) > 50 and np.sqrt(np.mean(sphere_error_um(p.points[p.points[:, 2] > 1]) ** 2)) < 20


def test_a_scan_whose_ik_comes_over_the_bridge_gives_the_local_cloud(tmp_path):
    """The demo, its IK from an ik-server on loopback: the same cloud as with the local solver."""
    from addon.core.config.scan import load_scan_config
    from addon.core.config.rigs import load_robot
    from headless.ik_server import IKServer

    server = IKServer(load_robot("adept_viper_s650"), "127.0.0.1", 0).start()
    try:
        text = open(load_scan_config("demo").source).read()
        f = tmp_path / "bridge.toml"
        f.write_text(text.replace("start_deg = [0.0, 30.0, -15.0, 0.0, 75.0, 90.0]   # the probe over the table, looking down (the Scanner starts here)",
                                  "start_deg = [0.0, 30.0, -15.0, 0.0, 75.0, 90.0]\nik = \"controller\"\n"
                                  f"[robot.controller]\nport = {server.port}\n"))
        bridged = Scanner.from_config(f, frames=slice(None, None, 12))
        assert bridged.config.robot.ik_via is not None
        bridged.run()
        local = Scanner.from_config("demo", frames=slice(None, None, 12))
        local.run()
    finally:
        server.shutdown()
        server.server_close()
    a, b = bridged.cloud, local.cloud
    assert len(a) == len(b) > 1000
    np.testing.assert_allclose(a.points, b.points, atol=1e-6)


def test_ctrl_c_while_cycles_renders_stops_a_users_script():
    """Cycles catches a KeyboardInterrupt raised inside its Python callbacks and renders on;
    the Scanner defers the Ctrl-C to the end of the render call, so a script stops there
    instead of carrying on as if nobody had asked."""
    import signal
    import time

    script = (
        "from addon import Scanner\n"
        "s = Scanner.from_config('demo')\n"
        "s.sweep([-20, -40, 200], [-20, 40, 200], 3)\n"  # Blender set up, the first render done
        "print('rendering', flush=True)\n"
        "for _ in range(20):\n"
        "    s.sweep([-20, -40, 200], [-20, 40, 200], 40)\n"
        "print('FINISHED', flush=True)\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", script], cwd=REPO, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env={**os.environ, "PYTHONPATH": str(REPO)})
    try:
        assert proc.stdout.readline().strip() == "rendering"
        time.sleep(1.5)  # well inside the renders (each sweep takes seconds)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert "FINISHED" not in out and proc.returncode != 0, (out, err[-2000:])
    assert err.rstrip().splitlines()[-1].startswith("KeyboardInterrupt"), err[-2000:]
    assert "StructRNA" not in err and "Not freed memory" not in err, err[-2000:]


def test_the_report_keeps_the_paths_frame_numbers_only_while_the_scanner_ran_its_path_alone():
    s = Scanner.from_config("demo", engine="raycast", frames=slice(10, 14))
    s.run()
    assert s.report().to_dict()["config"]["path_frames"] == [10, 11, 12, 13]
    s.measure()  # a frame of its own: no path frame to give it
    assert s.report().to_dict()["config"]["path_frames"] is None


def test_a_fixture_reaching_into_the_part_is_warned_of_step_by_step_too():
    from dataclasses import replace

    import trimesh

    from addon.core.config.scan import load_scan_config
    from addon.core.safety import Fixture

    jaw = trimesh.creation.box([20.0, 20.0, 20.0])
    jaw.apply_translation([39.0, 0.0, 30.0])  # 1 mm into the demo's sphere (radius 30 mm)
    cfg = replace(load_scan_config("demo").with_overrides(engine="raycast"),
                  fixtures=(Fixture("fixture jaw", jaw, "table"),))
    s = Scanner(config=cfg)
    assert s.report().to_dict()["warnings"] == []  # nothing measured: nothing said yet
    s.measure()
    s.measure()
    said = [w for w in s.report().to_dict()["warnings"] if "reaches" in w]
    assert len(said) == 1 and said[0].startswith("fixture jaw reaches")


def test_a_path_that_measures_little_of_a_large_part_says_so():
    """A 200 mm plate scanned by a path of two profiles: each lights one line at most the
    plate's diagonal (283 mm) long, and coverage counts 1 mm either side of it, so at most
    2 × 2 × 283 mm² of the plate's 83 200 mm² (1.4 %) can be measurable: the report says the
    path misses most of the part. The same two profiles taken step by step, or two frames
    picked from a longer path, say nothing (a scan only begun, a path not all scanned); the
    demo's own first table turn measures far more of its sphere and says nothing either."""
    from dataclasses import replace

    import trimesh

    from addon.core.config.scan import load_scan_config
    from addon.core.geometry.workpiece import Workpiece

    from addon.core.kinematics.path import sweep

    plate = trimesh.creation.box([200.0, 200.0, 4.0])
    plate.apply_translation([0.0, 0.0, 2.0])
    base = load_scan_config("demo").with_overrides(engine="raycast")
    cfg = replace(base, workpiece=Workpiece("plate", plate, plate, "test:plate", np.eye(4)),
                  waypoints=sweep(2, [-1.0, 0.0, 150.0], [1.0, 0.0, 150.0]))
    s = Scanner(config=cfg)
    s.run()
    report = s.report().to_dict()
    assert 0 < report["measurable_share"] <= 2 * 2 * 283 / plate.area
    said = [w for w in report["warnings"] if "can measure only" in w]
    assert len(said) == 1 and f"{report['measurable_share'] * 100:.1f} % of the part's surface" in said[0]

    steps = Scanner(config=cfg)
    steps.move_to(s.pose())
    steps.measure()
    report = steps.report().to_dict()
    assert 0 < report["measurable_share"] < 0.05 and not any("can measure only" in w for w in report["warnings"])

    # Frames picked from a longer path (--frames) say nothing either: the path is not all scanned.
    picked = Scanner(config=replace(base, workpiece=cfg.workpiece).with_overrides(frames=slice(0, 2)))
    picked.run()
    report = picked.report().to_dict()
    assert 0 < report["measurable_share"] < 0.05 and not any("can measure only" in w for w in report["warnings"])

    demo = load_scan_config("demo").with_overrides(engine="raycast")
    turn = Scanner(config=replace(demo, waypoints=demo.waypoints.select(np.flatnonzero(demo.waypoints.segment == 0))))
    turn.run()  # the demo's table turn as a path of its own
    report = turn.report().to_dict()
    assert report["config"]["path_frames"] is None
    assert report["measurable_share"] > 0.05 and not any("can measure only" in w for w in report["warnings"])


def test_a_move_can_be_checked_before_it_is_made_and_the_table_turned_to_an_angle():
    """check_move_to answers what move_to would do with nothing moved: the same joints, and
    the clearance of the motion (the probe 150 mm above the sphere's top, looking down: its
    heads, 2 mm ahead of the probe's origin, are 148 mm from it, nearer than the table). A
    pose with the probe inside the sphere is refused by both, and nothing moves. The table
    turns to an angle from any angle (a cell designer's trial: only relative turns)."""
    from addon.core.errors import CollisionError

    s = Scanner.from_config("demo", engine="raycast")
    q_before = s.q
    above = ([0.0, 0.0, 210.0], [90.0, 180.0, 0.0])
    q, clearance = s.check_move_to(above)
    np.testing.assert_array_equal(s.q, q_before)
    nearest = clearance.nearest[0]
    assert {nearest.body_a, nearest.body_b} == {"probe", "workpiece"}
    assert nearest.distance_mm == pytest.approx(210.0 - 60.0 - 2.0, abs=0.5)
    np.testing.assert_allclose(s.move_to(above), q, atol=1e-12)
    with pytest.raises(CollisionError, match="probe touches the workpiece"):
        s.check_move_to(([0.0, 0.0, 40.0], [90.0, 180.0, 0.0]))  # the probe's origin inside the sphere
    np.testing.assert_allclose(s.q, q, atol=1e-12)
    assert s.turn_table_to(90.0) == pytest.approx(90.0)
    assert s.turn_table_to(-30.0) == pytest.approx(-30.0) and s.table_deg == pytest.approx(-30.0)
    with pytest.raises(InputError, match="table angle"):
        s.turn_table_to(float("nan"))
    s.turn_table(3000.0)
    assert s.turn_table_to(-3000.0) == pytest.approx(-3000.0)  # the limit is the angle's, not the turn's


def _waypoints(n: int) -> "Waypoints":
    return Waypoints(np.tile(np.eye(4), (n, 1, 1)), np.zeros(n), np.zeros(n, int))


@pytest.mark.parametrize("call,words", [
    (lambda: Scanner(workpiece=42), "workpiece must be"),
    (lambda: Scanner(table="x"), "table must be a Turntable"),
    (lambda: Scanner(render="raycast"), "engine=..."),
    (lambda: Scanner(robot=3), "robot must be"),
    (lambda: Scanner(probe=None), "probe must be"),
    (lambda: Scanner(config="demo"), "load_scan_config"),
    (lambda: Scanner.from_config("demo", samples="4"), "--samples (samples)"),
    (lambda: Scanner.from_config("demo", resolution="160x160"), "(width, height)"),
    (lambda: Scanner.from_config("demo", frames=1000), "must be a slice"),
    (lambda: Scanner.from_config("demo", frames=1.5), "must be a slice"),
    (lambda: Scanner.from_config("demo", frames=slice(0, 10, 0)), "the step must be"),
    (lambda: Scanner.from_config("demo", engine="raycast").turn_table(1e20), "within ±3600"),
    (lambda: Scanner.from_config("demo", engine="raycast").turn_table_to(-1e300), "within ±3600"),
    (lambda: list(Scanner.from_config("demo", engine="raycast").measurements(first=-5)), "measurements(first)"),
    # a pose as (xyz, yzz) of the wrong kind, a complex angle, result()'s own arguments (a
    # bug hunt: ValueErrors and TypeErrors, a ComplexWarning and the real part taken)
    (lambda: Scanner.from_config("demo", engine="raycast").move_to((["a", 0, 210], [90, 180, 0])), "three finite"),
    (lambda: Scanner.from_config("demo", engine="raycast").check_move_to(([1, [2], 3], [90, 180, 0])), "three finite"),
    (lambda: Scanner.from_config("demo", engine="raycast").turn_table(np.complex128(1)), "finite number of degrees"),
    (lambda: Scanner.from_config("demo", engine="raycast").result(out_dir=5), "output folder"),
    (lambda: Scanner.from_config("demo", engine="raycast").result(extra=5), "extra must be a dict"),
    (lambda: Scanner.from_config("demo", engine="raycast").config.__class__ and setattr(
        Scanner.from_config("demo", engine="raycast"), "config", "demo"), "must be a ScanConfig"),
    # Paths built by hand (a review: a broadcast ValueError, an IndexError, an AttributeError,
    # a TypeError, or a NaN blamed on the joints)
    (lambda: Scanner.from_config("demo", engine="raycast").plan_path([1, 2, 3]), "a path is Waypoints"),
    (lambda: Scanner.from_config("demo", engine="raycast").plan_path(_waypoints(0)), "has no waypoints"),
    (lambda: Waypoints(np.tile(np.eye(4), (3, 1, 1)), np.zeros(2), np.zeros(3, int)), "one of each per frame"),
    (lambda: Waypoints(np.full((2, 4, 4), np.nan), np.zeros(2), np.zeros(2, int)), "waypoint 0 is not finite"),
    (lambda: Waypoints(np.tile(np.eye(4), (2, 1, 1)), np.zeros(2), np.zeros(2)), "entry numbers (segment) must be whole"),
    (lambda: Waypoints(np.tile(2 * np.eye(4), (2, 1, 1)), np.zeros(2), np.zeros(2, int)), "not a rigid transform"),
    (lambda: scanpath.sweep(2.5, [0, 0, 200], [10, 0, 200]), "a sweep's frames"),
    (lambda: scanpath.sweep(3, [np.nan, 0, 200], [10, 0, 200]), "from_mm must be three finite"),
    (lambda: scanpath.sweep(3, [0, 0, 200], "abc"), "to_mm must be three numbers"),
    (lambda: scanpath.sweep(3, [0, 0, 200], [10, 0, 200], line="x"), "line must be three numbers"),
    (lambda: scanpath.turntable("5", [0, 0, 200], table=load_scan_config("demo").table), "turntable path's frames"),
    (lambda: scanpath.turntable(5, "abc", table=load_scan_config("demo").table), "probe_mm must be three"),
    (lambda: scanpath.turntable(5, [0, 0, 200], turn_rad=float("inf"), table=load_scan_config("demo").table),
     "its turn must be a finite number"),
])
def test_a_wrong_argument_to_the_api_is_named_in_the_projects_own_error(call, words):
    """A script's mistakes (a QA trial: a TypeError, an AttributeError, an IndexError, numpy's
    "Maximum allowed size exceeded") are InputErrors naming what was wrong and what is allowed."""
    with pytest.raises(InputError) as err:
        call()
    assert words in str(err.value), str(err.value)


def test_frames_may_be_given_as_the_command_lines_text():
    assert Scanner.from_config("demo", engine="raycast", frames="10:14").config.path_frames.tolist() == [10, 11, 12, 13]


@pytest.mark.parametrize("engine", ["raycast", "cycles"])
def test_a_sheet_lying_on_the_table_measures_as_the_table_does(engine):
    """The built-in plane lies in the table top unless posed. Drawn with the table, the two
    surfaces alternated along the line: the ray-cast engine read 141 µm RMS and 162 points
    beyond 0.2 mm, Cycles found no line on it at all. The truth is the plane z = 0 itself: every
    point on it lies within the table's own few µm, and the scan says what it measured."""
    from dataclasses import replace

    from addon.core.config.scan import load_scan_config
    from addon.core.geometry.workpiece import builtin_workpiece
    from addon.core.kinematics.path import sweep

    cfg = replace(load_scan_config("demo").with_overrides(engine=engine),
                  workpiece=builtin_workpiece("plane", width_mm=60.0, height_mm=40.0),
                  waypoints=sweep(12 if engine == "cycles" else 40, [-35.0, 0.0, 200.0], [35.0, 0.0, 200.0]))
    s = Scanner(config=cfg)
    s.run()
    r = s.report().to_dict()
    inside = (np.abs(s.cloud.points[:, 0]) < 29.0) & (np.abs(s.cloud.points[:, 1]) < 19.0)
    assert inside.sum() > 300 and np.abs(s.cloud.points[inside, 2]).max() < 0.01  # mm: the sheet's level
    assert r["points_on_part"] >= inside.sum() and r["outliers"] == 0 and r["error_um"]["max_um"] < 10.0
    assert any("lies flat in the table top" in w for w in r["warnings"])


def test_a_part_of_a_path_gets_the_sensor_noise_its_frames_get_in_the_whole_path():
    """Each frame's noise and speckle are drawn for its number in the whole path: frames 5:10
    scanned alone are frames 5..9 of the whole scan, not frames 0..4's grain again; and a
    Scanner's sweeps draw afresh, as their frames join it."""
    from addon.core.config.scan import load_scan_config
    from addon.core.optics.sensor import SensorModel

    noisy = load_scan_config("step_block").with_overrides(engine="raycast", frames=slice(0, 10))
    noisy = noisy.with_realism(SensorModel(noise=True, speckle=True, seed=3))
    whole = Scanner(config=noisy)
    whole.run()
    part = Scanner(config=noisy.with_overrides(frames=slice(5, 10)))
    part.run()
    a, b = whole.cloud, part.cloud
    for k in range(5):
        mine, theirs = b.points[b.frame == k], a.points[a.frame == 5 + k]
        assert len(mine) and len(mine) == len(theirs) and np.array_equal(mine, theirs), k
    # Two equal sweeps, one after the other: their frames differ in their noise.
    stepper = Scanner(config=noisy)
    first = stepper.sweep([-30.0, 0.0, 200.0], [30.0, 0.0, 200.0], 3)
    second = stepper.sweep([-30.0, 0.0, 200.0], [30.0, 0.0, 200.0], 3)
    assert len(first[0]) and not (len(first[0]) == len(second[0]) and np.array_equal(first[0].points,
                                                                                    second[0].points))


def test_a_scanner_runs_its_path_with_the_paths_own_noise_whatever_it_measured_before():
    """A config without a frame pick is numbered 0.. as written: its run after a measure()
    draws the same noise and speckle per path frame as a fresh Scanner's run."""
    from addon.core.config.scan import load_scan_config
    from addon.core.optics.sensor import SensorModel

    noisy = load_scan_config("step_block").with_overrides(engine="raycast")
    noisy = noisy.with_realism(SensorModel(noise=True, speckle=True, seed=3))
    assert noisy.path_frames is None
    fresh = Scanner(config=noisy)
    fresh.run()
    later = Scanner(config=noisy)
    later.measure()  # frame 0 of this Scanner: the path's frames join it from 1
    later.run()
    a, b = fresh.cloud, later.cloud
    for k in range(3):
        mine, theirs = b.points[b.frame == k + 1], a.points[a.frame == k]
        assert len(mine) and len(mine) == len(theirs) and np.array_equal(mine, theirs), k


def test_the_demo_arm_given_as_an_object_starts_where_it_does_by_name():
    """The demo's start posture holds for its robot and table however they are given (a review:
    a loaded Robot lost it, compared with the rig's name as text); another arm seeds itself."""
    from addon.core.config.rigs import load_robot
    from addon.core.kinematics.turntable import Turntable

    by_name, by_object = Scanner(), Scanner(robot=load_robot("adept_viper_s650"))
    np.testing.assert_array_equal(by_object.q, by_name.q)
    assert by_object.config.q_start is not None
    assert Scanner(robot="puma560").config.q_start is None
    assert Scanner(table=Turntable(a_mm=-450.0, d_mm=-200.0)).config.q_start is None
    base = np.eye(4)
    base[2, 3] = 400.0
    assert Scanner(robot=load_robot("adept_viper_s650").with_base(base)).config.q_start is None


def test_the_report_follows_moves_extras_and_a_replaced_config():
    """A bug hunt's sequences: a move after a report changed no clearance in the next one; an
    extra given to result() once stayed in every later report; a config replaced on the
    Scanner still scanned the old part (its ray caster kept); turn_table_to landed a hair off."""
    from addon.core.geometry.workpiece import builtin_workpiece

    s = Scanner.from_config("demo", engine="raycast")
    s.move_to(([12.0, 0.0, 210.0], [90.0, 180.0, 0.0]))
    s.measure()
    far = s.report().to_dict()["clearance"]["nearest"]["clearance_mm"]
    s.move_to(([12.0, 0.0, 150.0], [90.0, 180.0, 0.0]))  # nearer the sphere, nothing measured
    near = s.report().to_dict()["clearance"]["nearest"]["clearance_mm"]
    now = min(c.distance_mm for c in s.clearance().nearest.values())
    assert near < far - 30.0 and near == pytest.approx(now, abs=1e-3)
    assert s.result(extra={"note": "A"}).report["note"] == "A"
    assert "note" not in s.result().report
    # A planner's numpy values join as JSON's (a TypeError's traceback after the whole
    # measurement before); the report's own fields are not replaced ({"frames": 999} was).
    mine = s.result(extra={"mine": {"score": np.float32(0.5), "views": np.int64(3), "xyz": np.arange(2.0)}})
    assert json.loads(report_json(mine.report))["mine"] == {"score": 0.5, "views": 3, "xyz": [0.0, 1.0]}
    with pytest.raises(InputError, match="'frames', 'points' are the report's own"):
        s.result(extra={"frames": 999, "points": -1})
    with pytest.raises(InputError, match=r"extra\['mine'\]: set .* is not JSON"):
        s.result(extra={"mine": {1, 2}})
    s.turn_table(0.1)
    assert s.turn_table_to(30.0) == 30.0 and s.table_deg == 30.0
    s.turn_table_to(0.0)
    s.move_to(([12.0, 0.0, 210.0], [90.0, 180.0, 0.0]))
    s.config = replace(s.config, workpiece=builtin_workpiece("step_block"))
    top = float(s.config.workpiece.mesh.bounds[1][2])
    points = s.measure().points
    assert len(points) and points[:, 2].max() <= top + 0.05  # the block's, not the sphere's (its top at 60)


def test_a_path_asked_about_and_then_scanned_is_planned_once(monkeypatch):
    """plan_path then scan_path of the same waypoints from the same pose solves the path once
    (the Gym environment's steps solved every view twice); a move between them, or a scan that
    wants the clearance the question did not measure, plans again; the plan handed out is the
    caller's to change."""
    from addon.core.kinematics import path as path_module

    calls = []
    real = path_module.solve_path
    monkeypatch.setattr(path_module, "solve_path", lambda *a, **k: calls.append(1) or real(*a, **k))
    s = Scanner.from_config("demo", engine="raycast")
    s.keep_clearance = False
    wp = scanpath.sweep(6, [-20.0, 0.0, 210.0], [20.0, 0.0, 210.0])
    q, table_rad = s.plan_path(wp)
    q[:] = 0.0  # the caller's copy
    assert len(s.scan_path(wp)) == 6 and len(calls) == 1
    assert np.abs(s.plan_path(wp)[0]).max() > 0 and len(calls) == 2  # the robot moved: planned again
    s.keep_clearance = True
    s.turn_table(10.0)
    s.plan_path(wp)
    s.scan_path(wp)
    assert len(calls) == 4 and s.result().report["clearance"] is not None


def test_a_step_by_step_scans_clearance_names_frames_counted_over_the_whole_scan():
    """Each sweep's collision check counts its frames from 0: the report named frame 4 for the
    nearest pose, which was the second sweep's frame 4, the scan's frame 14."""
    s = Scanner.from_config("demo", engine="raycast")
    s.sweep([-40.0, 0.0, 230.0], [40.0, 0.0, 230.0], 10)
    s.sweep([-40.0, 0.0, 140.0], [40.0, 0.0, 140.0], 10)  # nearer the sphere: the nearest pose
    clearance = s.report().to_dict()["clearance"]
    assert 10 <= clearance["nearest"]["frame"] <= 19
    assert 0 <= clearance["per_path"]["0"]["frame"] <= 9 and clearance["per_path"]["1"] == clearance["nearest"]
    assert clearance["nearest"]["points_mm"][0][2] == pytest.approx(140.0 - 2.0, abs=0.01)  # the probe's heads


def test_a_path_whose_table_turns_past_ten_turns_is_refused_before_planning():
    """plan_path took any finite table angle, and a path to 1e6 rad asked the collision check
    for a sample per millimetre of the turn (30 GiB)."""
    from addon.core.kinematics.path import turntable

    s = Scanner.from_config("demo", engine="raycast")
    wp = turntable(4, s.pose()[:3, 3], [0.0, 0.0, -1.0], start_rad=1e6, table=s.config.table)
    with pytest.raises(InputError, match="ten turns"):
        s.plan_path(wp)
    # It is the turn that counts, not the angle: a table turned eleven times on may sweep where it stands.
    for _ in range(11):
        s.turn_table(359.0)
    assert s.table_deg > 3600.0
    s.sweep([-20.0, -40.0, 215.0], [-20.0, 40.0, 215.0], 3)


def test_the_preview_of_a_scan_with_no_point_on_the_part_says_so_in_its_title(tmp_path):
    """The error of no point is NaN in the report before it is written (null after): the title
    read "RMS nan um, p95 nan um"."""
    from addon.core.scan.outputs import preview_title

    s = Scanner.from_config("demo", engine="raycast")
    s.sweep([85.0, -10.0, 170.0], [85.0, 10.0, 170.0], 3)  # the table top beside the sphere
    report = s.result().report
    assert len(s.cloud) > 0 and report["points_on_part"] == 0
    title = preview_title("demo", len(s.cloud), report)
    assert "no point on the part" in title and "nan" not in title
    s.sweep([-20.0, -40.0, 215.0], [-20.0, 40.0, 215.0], 5)  # over the sphere
    title = preview_title("demo", len(s.cloud), s.result().report)
    assert "RMS " in title and "nan" not in title


def test_the_report_tells_apart_two_sensors_with_the_same_effects():
    """report.json said ["distortion"] for a lens undistorted (87 µm RMS) and one not (814 µm)."""
    from dataclasses import replace as changed

    from addon.core.config.scan import load_scan_config
    from addon.core.optics.sensor import SensorModel

    base = load_scan_config("demo").with_overrides(engine="raycast", frames=slice(0, 4))
    said = []
    for undistort in (True, False):
        cfg = changed(base, sensor=SensorModel(distortion=(-0.05, 0.0, 0.0, 0.0), undistort=undistort))
        s = Scanner(config=cfg.with_overrides(engine="cycles"))
        said.append(s.report().to_dict()["config"])
    assert said[0]["sensor"] == said[1]["sensor"] == ["distortion"]
    assert said[0]["sensor_settings"] == {"distortion": [-0.05, 0.0, 0.0, 0.0]}
    assert said[1]["sensor_settings"] == {"distortion": [-0.05, 0.0, 0.0, 0.0], "undistort": False}
    assert Scanner.from_config("demo", engine="raycast").report().to_dict()["config"]["sensor_settings"] == {}


def test_a_reports_keys_are_the_same_whatever_the_scan_met():
    """column_codes listed only the codes some column met (column_codes["EDGE"] a KeyError on
    another scan), and a farm's software.blender came last where a scan's came fifth (a hunt):
    a machine reading report.json finds every key, in one order."""
    from addon import Scanner
    from addon.core.optics.detect import LineCode

    scanner = Scanner.from_config("demo", engine="raycast")
    scanner.measure()
    report = scanner.report().to_dict()
    assert list(report["column_codes"]) == sorted(c.name for c in LineCode)
    assert sum(report["column_codes"].values()) > 0 and 0 in report["column_codes"].values()
    assert list(report["software"])[:5] == ["scanner", "python", "numpy", "opencv", "blender"]


def test_the_scanners_unit_refusal_leads_to_a_part_it_takes(tmp_path):
    """Scanner(workpiece=a file in metres) said to use load_workpiece(path, scale=...), whose
    part, no longer put on the table, was refused in turn (a hunt). The hint now names the
    call that places it; followed, the part lies on the table, 1000 times the file's size."""
    import re

    import trimesh

    from addon import Scanner, load_workpiece, resting_on_table
    from addon.core.errors import InputError

    box = trimesh.creation.box(extents=(0.04, 0.03, 0.02))  # metres, centred on the origin
    box.export(tmp_path / "m.stl")
    with pytest.raises(InputError) as info:
        Scanner(workpiece=str(tmp_path / "m.stl"))
    assert "resting_on_table(load_workpiece(path, scale=...))[0]" in str(info.value)
    part = resting_on_table(load_workpiece(tmp_path / "m.stl", scale=1000.0))[0]
    bounds = Scanner(workpiece=part).config.workpiece.mesh.bounds
    np.testing.assert_allclose(bounds, [[-20.0, -15.0, 0.0], [20.0, 15.0, 20.0]], atol=1e-9)
    assert re.search("resting_on_table", str(pytest.raises(InputError, Scanner,
                                                          workpiece=load_workpiece(tmp_path / "m.stl",
                                                                                   scale=1000.0)).value))


def test_the_summary_names_a_nearest_contact_on_a_move_after_the_last_frame(tmp_path, capsys):
    """The probe moved nearer the part after its last frame, and nothing measured there: the
    summary named "frame 6" of a session of frames 0-5; and, once frame 6 was taken elsewhere,
    "at frame 6" (a review)."""
    import trimesh

    from headless.scan import print_summary

    s = Scanner.from_config("demo", engine="raycast")
    s.sweep([-30.0, 0.0, 210.0], [30.0, 0.0, 210.0], 6)
    s.move_to(([0.0, 0.0, 150.0], [90.0, 180.0, 0.0]))
    # the truth: the probe's origin comes 60 mm nearer the 30 mm sphere than on the sweep
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=30.0)
    sphere.apply_translation((0.0, 0.0, 30.0))
    assert abs(sphere.nearest.signed_distance([s.pose()[:3, 3]])[0]) < 125.0
    report = s.report().to_dict()
    assert report["clearance"]["nearest"]["frame"] == report["frames"] == 6
    print_summary(s.result(tmp_path / "out"), 1.0)
    line = [ln for ln in capsys.readouterr().out.splitlines() if ln.strip().startswith("clearance")][0]
    assert "on a move after the last frame" in line and "frame 6" not in line, line
    # a sweep after it: frame 6 is now taken, at the sweep's start, which the move never reached
    s.sweep([-30.0, 0.0, 210.0], [30.0, 0.0, 210.0], 3)
    print_summary(s.result(tmp_path / "out2"), 1.0)
    line = [ln for ln in capsys.readouterr().out.splitlines() if ln.strip().startswith("clearance")][0]
    # (the move's 90 mm from the sphere, the probe's origin to its top, less the housing's reach)
    assert float(line.split()[1]) < 90.0 and "on a move before frame 6" in line, line


def test_a_report_says_where_a_scripts_part_stood_and_how_large_it_was_read(tmp_path):
    """A Scanner's part loaded from a file with a scale and put down by the script left only the
    file's name in report.json: the scan could not be repeated from it. The report now holds
    the part's placement and its size as read; both checked against the file's own box."""
    import trimesh

    from addon import Scanner
    from addon.core.config.render import RenderOptions
    from addon.core.geometry.workpiece import load_workpiece, resting_on_table

    box = trimesh.creation.box([0.04, 0.03, 0.02])  # metres, as a CAD export may be
    box.apply_translation([0.0, 0.0, -0.05])  # below the table: the script lifts it
    box.export(tmp_path / "block.stl")
    part, lift = resting_on_table(load_workpiece(tmp_path / "block.stl", scale=1000.0))
    scanner = Scanner(workpiece=part, render=RenderOptions(engine="raycast"))
    scanner.move_to(((0.0, 0.0, 180.0), (0.0, 180.0, 0.0)))
    scanner.measure()
    config = scanner.result(tmp_path / "out").report["config"]
    saved = json.loads((tmp_path / "out" / "report.json").read_text())["config"]
    assert saved["workpiece_size_mm"] == pytest.approx([40.0, 30.0, 20.0], abs=1e-4)  # (STL floats)
    pose = np.array(saved["workpiece_pose"])
    assert pose.shape == (4, 4) and lift == pytest.approx(60.0, abs=1e-4)  # its bottom from -60 mm up to the table
    assert pose[2, 3] == pytest.approx(lift, abs=1e-6)
    assert config["workpiece"] == str(tmp_path / "block.stl")
