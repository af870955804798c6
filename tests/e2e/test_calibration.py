"""Calibrating the simulated probe from rendered images, end to end, and scanning with the result.

Truth from geometry: the probe's true cameras and laser plane (the rig file), the tilted
plate's exact plane. The bounds come from the calibration's own covariance (4.5 σ), and the
scan's point error from the calibration's error field over the view (what the calibration
does to points on the laser plane, computed from the true and calibrated models alone).
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from addon import Scanner
from addon.calibrate import calibrate
from addon.core.config.rigs import load_probe
from addon.core.config.scan import load_scan_config
from addon.core.errors import ConfigError
from headless.cli import main

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    out = tmp_path_factory.mktemp("calibration")
    run = calibrate("demo", out, views=8)
    return run, out


def test_calibration_recovers_the_true_probe_within_its_stated_deviation(calibrated):
    run, out = calibrated
    s = json.loads((out / "calibration.json").read_text())
    assert s["views"] == 8
    for c in (0, 1):
        cam = s[f"camera{c}"]
        # corners on rendered boards are found to about a tenth of a pixel
        assert cam["reprojection_error_px"] < 0.3
        assert cam["corners"] >= 8 * 8
        dev, sd = cam["deviation"], cam["std"]
        for key in ("fx_px", "fy_px", "cx_px", "cy_px"):
            assert abs(dev[key]) <= 4.5 * sd[key], (c, key, dev[key], sd[key])
        assert dev["position_mm"] <= 4.5 * sd["position_mm"]
        assert dev["rotation_deg"] <= 4.5 * sd["rotation_deg"]
    rot = max(s[f"camera{c}"]["std"]["rotation_deg"] for c in (0, 1))
    laser = s["laser"]
    assert laser["deviation"]["tilt_deg"] <= 4.5 * laser["std"]["tilt_deg"] <= 4.5 * rot
    # the plane is measured through the cameras: its offset is as good as their positions
    pos = max(s[f"camera{c}"]["std"]["position_mm"] for c in (0, 1))
    assert abs(laser["deviation"]["offset_mm"]) <= 4.5 * laser["std"]["offset_mm"] <= 4.5 * pos
    assert laser["fit_rms_mm"] < 0.05  # the line's points lie on one plane
    # the calibrated probe file reads back to the same calibration
    back = load_probe(out / "probe.toml")
    assert np.abs(back.calibration.cameras[0].K - run.fit.probe.calibration.cameras[0].K).max() < 1e-9
    assert (out / "calibration.png").stat().st_size > 10_000


def test_a_scan_with_the_calibrated_probe_shows_what_the_calibration_costs(calibrated, tmp_path):
    run, out = calibrated
    text = (REPO / "rigs" / "scenes" / "tilted_plane.toml").read_text()
    cfg_path = tmp_path / "tilted_calibrated.toml"
    cfg_path.write_text(text.replace('rig = "default"', f'rig = "default"\ncalibration = "{out / "probe.toml"}"', 1))
    cfg = load_scan_config(cfg_path)
    assert cfg.probe.calibration is not None
    # Eq. 6 assumes the nominal probe: with a calibration it is refused as the config loads
    paper = tmp_path / "tilted_calibrated_paper.toml"
    paper.write_text(cfg_path.read_text() + '\n[triangulate]\nmethod = "paper"\n')
    with pytest.raises(ConfigError, match='method "paper".*probe.calibration.*"exact"'):
        load_scan_config(paper)
    frames = slice(0, 30, 3)
    truth = Scanner.from_config("tilted_plane", frames=frames).run()
    measured = Scanner.from_config(cfg_path, frames=frames).run()
    assert measured.frames == truth.frames == 10
    assert measured.points > 0.8 * truth.points
    field = run.summary["triangulation_error"]["all"]
    # every point is off by no more than the calibration's error field allows (plus the true probe's own error)
    assert measured.error_um.max_um <= 1e3 * field["max_mm"] + truth.error_um.max_um + 1.0
    assert measured.error_um.rms_um > truth.error_um.rms_um  # a real calibration is never perfect


def _poses_file(path, poses):
    from addon.core.kinematics.euler import pose_to_xyz_yzz

    lines = []
    for T in poses:
        xyz, yzz = pose_to_xyz_yzz(T)
        lines += ["[[view]]", f"xyz_mm = {[float(v) for v in xyz]}", f"yzz_deg = {[float(v) for v in np.degrees(yzz)]}",
                  ""]
    path.write_text("\n".join(lines))
    return str(path)


def test_calibrate_command_takes_the_users_poses_and_writes_its_files(tmp_path, capsys):
    from addon.core.calibration import board_for, board_views

    probe = load_probe("default")
    poses = _poses_file(tmp_path / "poses.toml", board_views(board_for(probe), probe.z_range_mm, 6))
    rc = main(["calibrate", "demo", "--poses", poses, "--out", str(tmp_path / "cal")])
    captured = capsys.readouterr()
    text = captured.out
    assert rc == 0, text
    assert "6 board views from" in text and "reprojection" in text and "laser plane" in text
    # The plan's progress counts board views, not frames.
    assert "plan: 6 of 6 board views reachable" in text
    assert "plan:" not in captured.err and "images:" in captured.err
    assert sorted(p.name for p in (tmp_path / "cal").iterdir()) == ["calibration.json", "calibration.png",
                                                                     "probe.toml"]


def test_parallel_poses_from_the_user_are_refused_with_nothing_written(tmp_path, capsys):
    from addon.core.calibration import board_for, flat_views

    probe = load_probe("default")
    poses = _poses_file(tmp_path / "flat.toml", flat_views(board_for(probe), probe.z_range_mm, 6))
    rc = main(["calibrate", "demo", "--poses", poses, "--out", str(tmp_path / "cal"), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "parallel" in err[0], err
    assert not (tmp_path / "cal").exists() or not any((tmp_path / "cal").iterdir())


def test_a_raycast_config_says_that_its_calibration_renders_with_cycles(tmp_path, capsys):
    """The ray caster draws a laser line only; the board images need Blender's renderer, and
    the command says so rather than changing engines without a word."""
    from addon.core.calibration import board_for, flat_views

    config = tmp_path / "raycast.toml"
    config.write_text((REPO / "rigs" / "scenes" / "demo.toml").read_text()
                      .replace('engine = "cycles"', 'engine = "raycast"'))
    probe = load_probe("default")
    poses = _poses_file(tmp_path / "flat.toml", flat_views(board_for(probe), probe.z_range_mm, 6))
    rc = main(["calibrate", str(config), "--poses", poses, "--out", str(tmp_path / "cal"), "--quiet"])
    out = capsys.readouterr().out
    assert rc == 2 and "rendered with Cycles (the config's raycast engine draws no board)" in out, out
    rc = main(["calibrate", "demo", "--poses", poses, "--out", str(tmp_path / "cal"), "--quiet"])
    assert rc == 2 and "rendered with Cycles" not in capsys.readouterr().out


def test_too_few_poses_from_the_user_are_refused_as_too_few_not_as_collisions(tmp_path, capsys):
    from addon.core.calibration import board_for, board_views

    probe = load_probe("default")
    poses = _poses_file(tmp_path / "two.toml", board_views(board_for(probe), probe.z_range_mm, 2))
    rc = main(["calibrate", "demo", "--poses", poses, "--out", str(tmp_path / "cal"), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    assert poses in err[0] and "2 board views" in err[0] and "at least 4" in err[0], err
    assert "collision" not in err[0] and "reached" not in err[0], err
    assert not (tmp_path / "cal").exists() or not any((tmp_path / "cal").iterdir())


def test_too_few_poses_through_the_api_are_refused_as_too_few():
    from addon.core.calibration import board_for, board_views
    from addon.core.errors import CalibrationError

    probe = load_probe("default")
    with pytest.raises(CalibrationError) as info:
        calibrate("demo", None, poses=board_views(board_for(probe), probe.z_range_mm, 3))
    assert str(info.value) == "3 board views given; a calibration needs at least 4 (give more [[view]] tables)"
    with pytest.raises(CalibrationError, match="^2 board views given; a calibration needs at least 4$"):
        calibrate("demo", None, views=2)


def test_views_left_out_as_unreachable_are_named_as_such():
    from addon.calibrate import plan_views
    from addon.core.calibration import board_for, board_views
    from addon.core.errors import CalibrationError

    cfg = load_scan_config("demo")
    board = board_for(cfg.probe)
    views = board_views(board, cfg.probe.z_range_mm, 4)
    far = views.copy()
    far[1:, :3, 3] += [0.0, 0.0, 5000.0]  # five metres above the table: out of the arm's reach
    q, kept, dropped = plan_views(cfg, board, 4, views)
    assert len(q) == 4 and dropped == []
    with pytest.raises(CalibrationError) as info:
        plan_views(cfg, board, 4, far)
    message = str(info.value)
    assert message.startswith("only 1 of 4 board views can be reached without a collision (3 left out); "
                              "a calibration needs at least 4; first refusal (view 1): unreachable"), message


def test_a_view_that_runs_the_probe_into_a_world_fixture_is_left_out():
    """A 20 mm box standing in the world where the probe's housing is at the first proposed
    view: calibration checked its moves without the config's fixtures (the world's stay in the
    cell while the board stands in for the part), kept that view and reported none left out."""
    import trimesh

    from addon.calibrate import plan_views
    from addon.core.calibration import board_for
    from addon.core.safety import Fixture

    cfg = load_scan_config("demo")
    board = board_for(cfg.probe)
    q, kept, dropped = plan_views(cfg, board, 8)
    assert dropped == []
    probe2base = cfg.cell.robot.fk(q[:1])[0]
    box = trimesh.creation.box((20.0, 20.0, 20.0))
    box.apply_translation(probe2base[:3, :3] @ [0.0, 0.0, -40.0] + probe2base[:3, 3])  # in the housing
    walled = replace(cfg, fixtures=(Fixture("fixture wall", box, "world"),))
    q2, kept2, dropped2 = plan_views(walled, board, 8)
    assert 0 in [k for k, _ in dropped2] and all("fixture wall" in why for _, why in dropped2), dropped2
    assert len(q2) + len(dropped2) == 8


@pytest.mark.parametrize("kw, words", [
    (dict(poses="abc"), "calibration poses must be \\(n, 4, 4\\) probe poses \\(numbers\\), got str"),
    (dict(board="x"), "board must be a ChArUcoBoard"),
    (dict(distortion="no"), "distortion must be True, False or None"),
])
def test_wrong_kinds_of_api_arguments_are_one_line(kw, words):
    """A string of poses, a board that is not one (a ValueError's and an AttributeError's words
    before), and distortion="no" (read as True: the lens fitted) are refused."""
    from addon.core.errors import CalibrationError

    with pytest.raises(CalibrationError, match=words):
        calibrate("demo", None, **kw)


def test_an_overexposed_board_is_refused_with_an_exposure_hint(tmp_path, capsys):
    """A sensor that clips the whole lit board (an exposure 200 times too long) cannot find it;
    the refusal says to lower the exposure, not to give other poses."""
    from addon.core.calibration import board_for, board_views

    probe = load_probe("default")
    poses = _poses_file(tmp_path / "poses.toml", board_views(board_for(probe), probe.z_range_mm, 4))
    text = (Path(__file__).parents[2] / "rigs" / "scenes" / "demo.toml").read_text()
    text += "\n[sensor]\nsaturate = true\nexposure_ms = 200.0\n"
    assert "[sensor]" not in text.split("[sensor]\nsaturate")[0]  # the demo has no [sensor] of its own
    cfg = tmp_path / "bright.toml"
    cfg.write_text(text)
    rc = main(["calibrate", str(cfg), "--poses", poses, "--out", str(tmp_path / "cal"), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    assert "found the board in 0 of 4" in err[0] and "clipped" in err[0] and "exposure_ms" in err[0], err
    assert "poses" not in err[0], err
    assert not (tmp_path / "cal").exists() or not any((tmp_path / "cal").iterdir())


def test_a_calibrated_probe_given_as_the_rig_is_named_by_its_file_and_calibrates_again(calibrated, tmp_path):
    """A probe.toml that calibrate wrote, given as a config's [probe] rig (not as its
    calibration): the report names the file as for [probe] calibration (the summary read
    "in calibrated in the cell of ..."), and calibrating that config again names the probe
    "(calibrated)" once."""
    run, out = calibrated
    text = (REPO / "rigs" / "scenes" / "demo.toml").read_text()
    assert 'rig = "default"' in text
    config = tmp_path / "rig_calibrated.toml"
    config.write_text(text.replace('rig = "default"', f'rig = "{(out / "probe.toml").as_posix()}"', 1))
    cfg = load_scan_config(str(config))
    assert cfg.probe.calibration.source.startswith(str((out / "probe.toml").resolve()))
    assert "calibrated in the cell of" in cfg.probe.calibration.source
    again = calibrate(str(config), None, views=8)
    assert again.fit.probe.name.count("(calibrated)") == 1, again.fit.probe.name


def test_a_sensor_too_coarse_to_read_the_board_says_so_not_to_give_more_poses(tmp_path, capsys):
    """A 16 x 16 sensor was told to give more poses, or poses nearer the middle of the range,
    where no pose resolves the board's markers (a hunt): the line says how many pixels a
    marker spans (the board's marker size at mid-range through the probe's focal length) and
    to calibrate at a larger resolution."""
    probe = (REPO / "rigs" / "probes" / "default.toml").read_text()
    probe = probe.replace("rows_px = 160 ", "rows_px = 16 ").replace("cols_px = 160 ", "cols_px = 16 ")
    assert "rows_px = 16 " in probe and "cols_px = 16 " in probe
    (tmp_path / "tiny.toml").write_text(probe)
    demo = (REPO / "rigs" / "scenes" / "demo.toml").read_text().replace('rig = "default"', 'rig = "tiny.toml"')
    (tmp_path / "scene.toml").write_text(demo)
    assert main(["calibrate", str(tmp_path / "scene.toml"), "--views", "8", "--out", str(tmp_path / "out"),
                 "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "a marker of the board spans only" in err and "larger resolution" in err and "more poses" not in err, err
    assert not (tmp_path / "out").exists()
