"""Scan config inputs that were taken without a word or refused with the wrong reason: a
partial probe mount, a byte-order mark, a mesh with no area, step heights, a detector
picked on the command line, the samples a sensor model renders with, a dangling --out."""

from pathlib import Path

import numpy as np
import pytest
import trimesh

from addon.core.config.scan import load_scan_config
from addon.core.errors import ConfigError, InputError

REPO = Path(__file__).resolve().parents[2]
DEMO = (REPO / "rigs" / "scenes" / "demo.toml").read_text()


def demo_with(tmp_path, extra: str = "", old: str = "", new: str = "", name: str = "scan.toml"):
    path = tmp_path / name
    path.write_text(DEMO.replace(old, new, 1) + "\n" + extra)
    return path


def test_a_probe_mount_that_gives_one_key_keeps_the_rigs_other():
    """[probe.mount] with only its angles set the rig's 100 mm stand-off from the flange to 0."""
    rig = load_scan_config("demo").probe.mount
    assert np.linalg.norm(rig[:3, 3]) > 10.0
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        turned = load_scan_config(demo_with(Path(d), "[probe.mount]\nyzz_deg = [0.0, 0.0, 10.0]\n")).probe.mount
        moved = load_scan_config(demo_with(Path(d), "[probe.mount]\nxyz_mm = [0.0, 0.0, 120.0]\n")).probe.mount
    np.testing.assert_allclose(turned[:3, 3], rig[:3, 3])
    assert not np.allclose(turned[:3, :3], rig[:3, :3])
    np.testing.assert_allclose(moved[:3, :3], rig[:3, :3], atol=1e-12)
    np.testing.assert_allclose(moved[:3, 3], [0.0, 0.0, 120.0])


def test_a_config_saved_with_a_byte_order_mark_is_named_for_it(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + DEMO.encode())
    with pytest.raises(ConfigError, match="byte-order mark"):
        load_scan_config(path)


def test_a_mesh_with_no_area_is_refused(tmp_path):
    """Three corners on one line: 0 points on the part and a scan that exited 0."""
    trimesh.Trimesh([[0.0, 0.0, 5.0], [10.0, 0.0, 5.0], [20.0, 0.0, 5.0]], [[0, 1, 2]],
                    process=False).export(tmp_path / "line.stl")
    path = demo_with(tmp_path, old='shape = "sphere"', new='file = "line.stl"')
    text = path.read_text().replace("radius_mm = 30.0", "")
    path.write_text(text)
    with pytest.raises(ConfigError, match="no surface"):
        load_scan_config(path)


def test_step_heights_out_of_order_are_named_by_their_key_in_plain_numbers(tmp_path):
    path = demo_with(tmp_path, old='shape = "sphere"', new='shape = "step_block"\nheights_mm = [30.0, 40.0]')
    path.write_text(path.read_text().replace("radius_mm = 30.0", ""))
    with pytest.raises(ConfigError, match=r"heights_mm: .*got \[30, 40\]") as err:
        load_scan_config(path)
    assert "np.float64" not in str(err.value)


def test_steger_picked_on_the_command_line_is_refused_where_the_config_smooths_nothing(tmp_path):
    """The config's own [detect] method = "steger" with smoothing_px = 0 is refused; --detect
    steger over a config with smoothing_px = 0 rendered and then failed in OpenCV."""
    cfg = load_scan_config(demo_with(tmp_path, old="[detect]\n", new="[detect]\nsmoothing_px = 0.0\n"))
    with pytest.raises(InputError, match="smoothing_px = 0"):
        cfg.with_overrides(detect="steger")
    assert cfg.with_overrides(detect="cog").detect_method == "cog"


def test_the_samples_a_sensor_model_renders_with_are_the_ones_budgeted():
    """integrate_pixels renders at 16 samples at least; the time check read the config's 1."""
    from headless.preflight import render_budget

    cfg = load_scan_config("cylinder_realistic")
    assert cfg.sensor.integrate_pixels and cfg.render.samples < 16
    assert render_budget(cfg).samples >= 16


def test_an_output_folder_that_is_a_dangling_link_is_refused_before_any_work(tmp_path):
    from addon.core.files import check_output_folder

    (tmp_path / "out").symlink_to(tmp_path / "missing")
    with pytest.raises(InputError, match="does not exist"):
        check_output_folder(tmp_path / "out")


def test_a_roughness_is_refused_for_a_surface_that_has_none(tmp_path):
    """grey and dark are matt and a mirror polished: a roughness given them did nothing (a mirror
    at 0.9 and at 0.05 gave the same cloud) and named the material after it."""
    for material in ("mirror", "grey"):
        path = demo_with(tmp_path, old="[workpiece]\n", new=f'[workpiece]\nmaterial = "{material}"\nroughness = 0.9\n')
        with pytest.raises(ConfigError, match='roughness: applies to material = "glossy" only'):
            load_scan_config(path)
    path = demo_with(tmp_path, old="[workpiece]\n", new='[workpiece]\nmaterial = "glossy"\nroughness = 0.9\n')
    assert load_scan_config(path).roughness == 0.9


@pytest.mark.parametrize("entry,fragment", [
    ('kind = "turntable"\nframes = 5\nprobe_mm = [12.0, 0.0, 210.0]\nturn_deg = 1440.0\n', "turn_deg"),
    ('kind = "sweep"\nframes = 20\nfrom_mm = [0.0, 0.0, 210.0]\nto_mm = [0.0, 0.0, 210.0]\nline = [0.0, 1.0, 0.0]\n',
     "takes one profile 20 times"),
    # (a 1e-8 mm sweep and a 1e-9° turn were let through)
    ('kind = "sweep"\nframes = 3\nfrom_mm = [0.0, 0.0, 210.0]\nto_mm = [1e-8, 0.0, 210.0]\n',
     "takes one profile 3 times; give to_mm apart from from_mm .by 1e-06 mm or more., or 1 frame with a line"),
    ('kind = "turntable"\nframes = 3\nprobe_mm = [12.0, 0.0, 210.0]\nturn_deg = 1e-9\n',
     "turntable path of 3 frames with turn_deg 1e-09 takes one profile 3 times"),
    ('kind = "sweep"\nframes = 1\nfrom_mm = [0.0, 0.0, 210.0]\nto_mm = [0.0, 0.0, 210.0]\n',
     "give its line, or to_mm apart across the beam"),
])
def test_a_path_that_takes_the_same_profiles_again_is_refused(tmp_path, entry, fragment):
    """Four whole turns in 5 frames took one profile 5 times (and counted each in the error);
    a sweep from a point to itself with its line given, 20 times."""
    text = DEMO[:DEMO.index("[[path]]")] + "[[path]]\n" + entry
    path = tmp_path / "again.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=fragment):
        load_scan_config(path)


def test_a_built_in_part_far_too_small_is_named_by_its_size_key(tmp_path):
    """radius_mm = 1e-20 gave numpy's warnings and 'NaN vertex coordinates'."""
    path = demo_with(tmp_path, old="radius_mm = 30.0", new="radius_mm = 1e-20")
    with pytest.raises(ConfigError, match="radius_mm 1e-20 mm is too small"):
        load_scan_config(path)


def test_an_obj_face_naming_vertex_0_is_refused(tmp_path):
    """OBJ counts vertices from 1: the reader dropped a face naming 0 without a word."""
    (tmp_path / "zero.obj").write_text("v 0 0 0\nv 20 0 0\nv 20 20 0\nv 0 20 0\nv 10 10 20\n"
                                       "f 1 2 5\nf 2 3 5\nf 3 4 5\nf 4 1 5\nf 1 2 0\n")
    from addon.core.geometry.workpiece import load_workpiece

    with pytest.raises(InputError, match="line 10 names vertex 0"):
        load_workpiece(tmp_path / "zero.obj")


def test_a_controller_table_without_ik_controller_is_named_for_it(tmp_path):
    """[robot.controller] with the default ik = "local" read as an unknown key whose list of
    allowed keys did not name it (a hunt)."""
    path = demo_with(tmp_path, old="[robot]\n", new="[robot.controller]\nport = 5758\n\n[robot]\n")
    with pytest.raises(ConfigError, match=r'robot\.controller: is read only with ik = "controller"'):
        load_scan_config(path)
    typo = demo_with(tmp_path, old="[robot]\n", new="[robot]\nikk = 1\n", name="typo.toml")
    with pytest.raises(ConfigError, match=r"allowed here: .*controller"):
        load_scan_config(typo)


def test_samples_the_raycast_engine_cannot_take_are_refused_with_the_overrides():
    """--engine raycast --samples 4 passed the overrides and was refused by the first frame's
    worker, after a local farm had started (a hunt)."""
    demo = load_scan_config("demo")
    with pytest.raises(InputError, match=r"--samples \(samples\) 4 with the raycast engine: .*need engine cycles"):
        demo.with_overrides(engine="raycast", samples=4)
    assert demo.with_overrides(engine="raycast", samples=1).render.engine == "raycast"


def test_a_config_named_by_a_relative_path_keeps_whole_paths(tmp_path, monkeypatch):
    """report.json named the config and its mesh relative to the folder the scan ran in, so a
    merge elsewhere, or the default output folder's check, read them as other files (a hunt)."""
    mesh = trimesh.creation.box(extents=(20.0, 20.0, 10.0))
    mesh.apply_translation((0.0, 0.0, 5.0))
    (tmp_path / "a").mkdir()
    mesh.export(tmp_path / "a" / "part.stl")
    text = DEMO[:DEMO.index("[workpiece]")] + '[workpiece]\nfile = "part.stl"\n' + DEMO[DEMO.index("[[path]]"):]
    (tmp_path / "a" / "scan.toml").write_text(text)
    monkeypatch.chdir(tmp_path)
    cfg = load_scan_config("a/scan.toml")
    assert cfg.source == str(tmp_path / "a" / "scan.toml")
    assert Path(cfg.workpiece.source) == tmp_path / "a" / "part.stl"
