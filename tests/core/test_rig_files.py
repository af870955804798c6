"""Robot rig files: loading by name or path, and one clear error per kind of mistake."""

import textwrap
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from addon.core.errors import ConfigError
from addon.core.config.rigs import load_robot

LINK = """
[[link]]
a_mm = 100.0
d_mm = 0.0
alpha_deg = 90.0
theta_offset_deg = 0.0
min_deg = -170.0
max_deg = 170.0
"""


def write_rig(tmp_path, body: str, links: int = 6, name="bad.toml"):
    path = tmp_path / name
    path.write_text('name = "test arm"\n' + textwrap.dedent(body) + LINK * links)
    return path


def test_load_by_path_and_tool_base_tables(tmp_path):
    path = tmp_path / "ok.toml"
    path.write_text('name = "test arm"\n' + LINK * 6 + textwrap.dedent("""
        [tool]
        xyz_mm = [0, 0, 150]
        [base]
        xyz_mm = [10, 20, 30]
        yzz_deg = [90, 0, 0]
        """))
    robot = load_robot(str(path))
    assert robot.name == "test arm"
    np.testing.assert_allclose(robot.tool[:3, 3], [0, 0, 150])
    np.testing.assert_allclose(robot.base[:3, 3], [10, 20, 30])
    np.testing.assert_allclose(robot.base[:3, 0], [0, 1, 0], atol=1e-15)
    # The tool plate carries what is mounted on it: a probe's mount comes after it (it replaced
    # the rig's tool, so a scan's probe sat 150 mm nearer the flange than the rig says).
    mount = np.eye(4)
    mount[:3, 3] = [5.0, 0.0, 40.0]
    q = np.radians([10.0, -20.0, 30.0, 40.0, -50.0, 60.0])
    plain = replace(robot, tool=np.eye(4), flange=np.eye(4))
    np.testing.assert_allclose(robot.with_tool(mount).fk(q), plain.fk(q) @ robot.tool @ mount, atol=1e-9)
    np.testing.assert_allclose(robot.with_tool(mount).fk(q)[:3, 3] - plain.fk(q)[:3, 3],
                               plain.fk(q)[:3, :3] @ [5.0, 0.0, 190.0], atol=1e-9)


def test_unknown_name_lists_the_bundled_robots():
    with pytest.raises(ConfigError, match="puma560") as info:
        load_robot("kuka_kr6")
    assert "kuka_kr6" in str(info.value)


def test_missing_file():
    with pytest.raises(ConfigError, match="no such file"):
        load_robot("/nonexistent/robot.toml")


@pytest.mark.parametrize(
    "body,links,fragments",
    [
        ("", 5, ["found 5 [[link]]", "exactly 6"]),
        ("colour = 'red'\n", 6, ["unknown key colour"]),
        ("name2 = 1\n", 6, ["unknown key name2"]),
        ("this is not toml\n", 6, ["not valid TOML"]),
    ],
)
def test_structural_errors(tmp_path, body, links, fragments):
    path = write_rig(tmp_path, body, links)
    with pytest.raises(ConfigError) as info:
        load_robot(path)
    msg = str(info.value)
    assert str(path) in msg
    for f in fragments:
        assert f in msg


@pytest.mark.parametrize(
    "replace,fragments",
    [
        (("a_mm = 100.0", "a_mm = nan"), ["link[1].a_mm", "finite"]),
        (("a_mm = 100.0", "a_mm = 'long'"), ["link[1].a_mm", "not a number"]),
        (("a_mm = 100.0", "a_mm = true"), ["link[1].a_mm", "not a number"]),
        (("a_mm = 100.0", "a_mm = 1e9"), ["link[1].a_mm", "out of range", "[-1e+06, 1e+06]"]),
        (("max_deg = 170.0", "max_deg = -180.0"), ["link[1].max_deg", "greater than min_deg"]),
        (("min_deg = -170.0", "min_deg = -1000.0"), ["link[1].min_deg", "[-720, 720]"]),
        (("alpha_deg = 90.0\n", ""), ["link[1].alpha_deg", "missing"]),
        (("d_mm = 0.0", "d_mm = 0.0\nmass_kg = 3.0"), ["link[1].mass_kg", "unknown key"]),
        # A misspelt optional key: the list of what is allowed names the optional ones too.
        (("d_mm = 0.0", "d_mm = 0.0\nmesj = 'arm.stl'"), ["link[1].mesj", "unknown key", "mesh, mesh_offset"]),
    ],
)
def test_value_errors_name_file_key_and_range(tmp_path, replace, fragments):
    path = write_rig(tmp_path, "")
    text = path.read_text()
    path.write_text(text.replace(replace[0], replace[1], 1))
    with pytest.raises(ConfigError) as info:
        load_robot(path)
    msg = str(info.value)
    assert str(path) in msg
    for f in fragments:
        assert f in msg, msg


def test_link_meshes_are_resolved_next_to_the_rig(tmp_path):
    import trimesh

    trimesh.creation.box([40.0, 40.0, 200.0]).export(tmp_path / "link1.stl")
    path = write_rig(tmp_path, "")
    text = path.read_text().replace("max_deg = 170.0", 'max_deg = 170.0\nmesh = "link1.stl"\n[link.mesh_offset]\nxyz_mm = [0, 0, 5]', 1)
    path.write_text(text)
    robot = load_robot(path)
    assert len(robot.link_meshes) == 6
    mesh, offset = robot.link_meshes[0]
    assert mesh == str((tmp_path / "link1.stl").resolve()) and offset[2, 3] == 5.0
    assert robot.link_meshes[1][0] == ""
    assert load_robot("adept_viper_s650").link_meshes == ()  # a bundled rig without meshes


def test_missing_link_mesh_is_an_error(tmp_path):
    path = write_rig(tmp_path, "")
    path.write_text(path.read_text().replace("max_deg = 170.0", 'max_deg = 170.0\nmesh = "nope.stl"', 1))
    with pytest.raises(ConfigError, match="link\\[1\\].mesh.*no such file"):
        load_robot(path)


def test_mesh_offset_without_a_mesh_is_an_error(tmp_path):
    # It was dropped silently: the user meant to place a mesh the file never names.
    path = write_rig(tmp_path, "")
    path.write_text(path.read_text().replace("max_deg = 170.0", 'max_deg = 170.0\n[link.mesh_offset]\nxyz_mm = [0, 0, 5]', 1))
    with pytest.raises(ConfigError, match=r"link\[1\].mesh_offset.*has none"):
        load_robot(path)


def test_rigs_are_read_once_and_again_only_when_the_file_changes(tmp_path, monkeypatch):
    import os
    import shutil

    from addon.core.config import rigs, toml
    from addon.core.config.rigs import load_probe

    path = tmp_path / "probe.toml"
    shutil.copy(toml.RIGS_DIR / "probes" / "default.toml", path)
    reads = []
    real = rigs.load_toml
    monkeypatch.setattr(rigs, "load_toml", lambda p: reads.append(p) or real(p))
    first = load_probe(path)
    for _ in range(50):  # a panel redrawing: no file is parsed again
        assert load_probe(path) is first
    assert len(reads) == 1
    path.write_text(path.read_text().replace('name = "', 'name = "Edited ', 1))
    os.utime(path, ns=(path.stat().st_atime_ns, path.stat().st_mtime_ns + 10**9))
    assert load_probe(path).name.startswith("Edited") and len(reads) == 2


@pytest.mark.parametrize("content, fragment", [
    (b"this is a text file, not a mesh\n", "link\\[1\\].mesh"),
    (b"solid x\nendsolid x\n", "no triangles could be read"),
])
def test_a_link_mesh_that_is_not_a_mesh_is_refused_when_the_rig_loads(tmp_path, content, fragment):
    (tmp_path / "link1.stl").write_bytes(content)
    path = write_rig(tmp_path, "")
    path.write_text(path.read_text().replace("max_deg = 170.0", 'max_deg = 170.0\nmesh = "link1.stl"', 1))
    with pytest.raises(ConfigError, match=fragment):
        load_robot(path)


SLIDE = """
[[link]]
joint = "prismatic"
a_mm = 0.0
d_mm = 50.0
alpha_deg = -90.0
theta_offset_deg = 90.0
min_mm = 0.0
max_mm = 400.0
"""


def test_a_dh_rig_declares_sliding_joints(tmp_path):
    """A linear axis under a 5R arm: the first joint slides. Checked against geometry: its
    q moves the flange by exactly q mm along the base's z axis, the others stay revolute."""
    path = tmp_path / "rail.toml"
    path.write_text('name = "arm on a lift"\n' + SLIDE + LINK * 5)
    robot = load_robot(str(path))
    assert robot.prismatic == (True,) + (False,) * 5
    assert (robot.q_min_rad[0], robot.q_max_rad[0]) == (0.0, 400.0)
    np.testing.assert_allclose(robot.q_max_rad[1], np.radians(170.0))
    q = np.radians([0.0, 20.0, -30.0, 40.0, 10.0, 5.0])
    q[0] = 120.0
    lifted = q.copy()
    lifted[0] = 250.0
    moved = robot.fk(lifted)[:3, 3] - robot.fk(q)[:3, 3]
    np.testing.assert_allclose(moved, [0.0, 0.0, 130.0], atol=1e-9)
    assert "mm" in robot.joint_text(0, 250.0, ".1f")


@pytest.mark.parametrize("edit, fragment", [
    (lambda s: s.replace("min_mm", "min_deg"), "min_mm"),
    (lambda s: s.replace('"prismatic"', '"sliding"'), "joint"),
    (lambda s: s.replace("max_mm = 400.0", "max_mm = -5.0"), "max_mm"),
])
def test_sliding_joint_mistakes_name_the_key(tmp_path, edit, fragment):
    path = tmp_path / "rail.toml"
    path.write_text('name = "arm on a lift"\n' + edit(SLIDE) + LINK * 5)
    with pytest.raises(ConfigError, match=fragment):
        load_robot(str(path))


def test_a_revolute_joint_refuses_millimetre_limits(tmp_path):
    path = tmp_path / "arm.toml"
    path.write_text('name = "arm"\n' + LINK.replace("min_deg = -170.0", "min_deg = -170.0\nmin_mm = 3.0") * 6)
    with pytest.raises(ConfigError, match="min_deg and max_deg"):
        load_robot(str(path))


def test_a_urdf_rig_and_a_home_path_are_read_from_the_configs_folder(tmp_path, monkeypatch):
    """A rig named by its file (ur5.urdf beside the config) is the config's, not a file of that
    name in the working folder (which a bug hunt loaded silently); ~ is the home folder."""
    import shutil

    from addon.core.config.scan import load_scan_config

    repo = Path(__file__).resolve().parents[2]
    demo = (repo / "rigs" / "scenes" / "demo.toml").read_text()
    here = tmp_path / "cell"
    here.mkdir()
    shutil.copy(repo / "rigs" / "robots" / "urdf" / "ur5.urdf", here / "ur5.urdf")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    shutil.copy(repo / "rigs" / "robots" / "urdf" / "gantry.urdf", elsewhere / "ur5.urdf")  # same name, other robot
    monkeypatch.chdir(elsewhere)
    text = demo.replace('rig = "adept_viper_s650"', 'rig = "ur5.urdf"', 1).replace(
        "start_deg = [0.0, 30.0, -15.0, 0.0, 75.0, 90.0]", "start_deg = [0.0, -90.0, 90.0, -90.0, -90.0, 0.0]", 1)
    (here / "scene.toml").write_text(text)
    assert load_scan_config(here / "scene.toml").robot.prismatic == (False,) * 6  # the UR5, not the gantry
    monkeypatch.setenv("HOME", str(here))
    (here / "home.toml").write_text(text.replace('rig = "ur5.urdf"', 'rig = "~/ur5.urdf"', 1))
    assert load_scan_config(here / "home.toml").robot.prismatic == (False,) * 6


def test_a_calibration_made_at_the_configs_resolution_is_taken(tmp_path):
    """[probe] calibration made on a 320x240 sensor with [render] resolution = [320, 240]: the
    resolution is applied first, then the calibration (it was the other way round, and every
    calibration at another size than the rig's was refused, the right one too)."""
    from dataclasses import replace

    from addon.core.config.rigs import load_probe, probe_toml
    from addon.core.config.scan import load_scan_config
    from addon.core.optics.calibrated import ProbeCalibration

    repo = Path(__file__).resolve().parents[2]
    demo = (repo / "rigs" / "scenes" / "demo.toml").read_text()
    at_320 = load_probe("default").with_resolution(240, 320)
    (tmp_path / "cal320.toml").write_text(probe_toml(replace(at_320, calibration=ProbeCalibration.of(at_320))))
    text = demo.replace('rig = "default"', 'rig = "default"\ncalibration = "cal320.toml"', 1).replace(
        "[render]", "[render]\nresolution = [320, 240]", 1)
    (tmp_path / "scene.toml").write_text(text)
    cfg = load_scan_config(tmp_path / "scene.toml")
    assert (cfg.probe.cols_px, cfg.probe.rows_px) == (320, 240) and cfg.probe.calibration is not None
    # the same calibration with the rig's own sensor size: refused, naming the file and the key
    (tmp_path / "scene160.toml").write_text(text.replace("resolution = [320, 240]", "resolution = [160, 160]", 1))
    with pytest.raises(ConfigError, match=r"scene160.toml: probe.calibration: .*cal320.toml"):
        load_scan_config(tmp_path / "scene160.toml")
    # a probe rig that carries its own calibration, at another resolution: the key is named
    (tmp_path / "scene_rig.toml").write_text(demo.replace('rig = "default"', 'rig = "cal320.toml"', 1))
    (tmp_path / "scene_rig.toml").write_text((tmp_path / "scene_rig.toml").read_text().replace(
        "[render]", "[render]\nresolution = [160, 160]", 1))
    with pytest.raises(ConfigError, match=r"scene_rig.toml: render.resolution: .*calibration"):
        load_scan_config(tmp_path / "scene_rig.toml")


def test_speckle_takes_the_probes_laser_wavelength_unless_the_sensor_sets_one(tmp_path):
    """A probe rig's [laser] wavelength_nm was checked and never used: speckle read [sensor]
    wavelength_nm (650 nm) whatever the laser was."""
    from addon.core.config.scan import load_scan_config

    repo = Path(__file__).resolve().parents[2]
    probe = (repo / "rigs" / "probes" / "default.toml").read_text()
    assert "wavelength_nm = 650.0" in probe
    (tmp_path / "green.toml").write_text(probe.replace("wavelength_nm = 650.0", "wavelength_nm = 532.0", 1))
    demo = (repo / "rigs" / "scenes" / "demo.toml").read_text().replace('rig = "default"', 'rig = "green.toml"', 1)
    (tmp_path / "scene.toml").write_text(demo + "\n[sensor]\nspeckle = true\n")
    assert load_scan_config(tmp_path / "scene.toml").sensor.wavelength_nm == 532.0
    (tmp_path / "own.toml").write_text(demo + "\n[sensor]\nspeckle = true\nwavelength_nm = 905.0\n")
    assert load_scan_config(tmp_path / "own.toml").sensor.wavelength_nm == 905.0
