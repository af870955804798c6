"""The Scanner panel's operators, called through bpy.ops with the UI registered."""

import json
import math

import bpy
from mathutils import Vector
import numpy as np
import pytest

import addon.ui as ui
from addon.core.kinematics.euler import pose_from_xyz_yzz
from addon.core.config.rigs import load_robot
from addon.core.config.rigs import load_probe
from addon.core.kinematics.turntable import Turntable
from addon.scene import rig
from addon.scene.ownership import mark, register_made
from addon.scene.units import from_blender


@pytest.fixture
def panel(scene):
    ui.register()
    yield scene
    ui.unregister()


def robot_obj():
    return bpy.data.objects["Robot"]


def test_build_cell_and_joint_sliders_pose_the_rig(panel):
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    robot = load_robot("adept_viper_s650").with_tool(load_probe("default").mount)
    q = np.radians([20, 50, -70, 10, 40, -30])
    for k in range(6):
        robot_obj()[f"q{k + 1}"] = float(q[k])  # what the sliders write
    robot_obj().update_tag()
    bpy.context.view_layer.update()
    np.testing.assert_allclose(rig.dh_frames(robot_obj(), robot), robot.link_frames(q), atol=1e-3)


def test_go_reaches_the_cartesian_target_relative_to_the_table(panel):
    bpy.ops.scanner.build_cell()
    s = panel.scanner
    s.table_angle = math.radians(40)
    s.target_frame = "table"
    s.target_location = (15.0, -5.0, 150.0)
    s.target_rotation = (0.3, math.pi, 0.0)
    assert bpy.ops.scanner.go() == {"FINISHED"}
    probe2world = from_blender(bpy.data.objects["Probe frame"].matrix_world)
    target = Turntable().table2base(math.radians(40)) @ pose_from_xyz_yzz([15, -5, 150], [0.3, math.pi, 0])
    np.testing.assert_allclose(probe2world, target, atol=1e-3)


def test_go_refuses_while_the_robot_or_the_table_object_stands_moved_in_the_viewport(panel):
    """Go solves the IK in the cell's placement: with the Robot object moved 100 mm in the
    viewport it said "Reached" with the probe 100 mm from the target. It refuses, naming the
    object and how far; put back, it goes."""
    bpy.ops.scanner.build_cell()
    s = panel.scanner
    s.target_frame, s.target_location = "table", (0.0, 0.0, 150.0)
    for name, shift in (("Robot", (0.1, 0.0, 0.0)), ("Turntable", (0.0, 0.05, 0.0))):
        obj = bpy.data.objects[name] if name == "Turntable" else robot_obj()
        before = obj.location.copy()
        obj.location = before + Vector(shift)
        bpy.context.view_layer.update()
        with pytest.raises(RuntimeError, match=f"The {name} object was moved in the viewport "
                                               f"\\({1000 * max(shift):.1f} mm"):
            bpy.ops.scanner.go()
        obj.location = before
        bpy.context.view_layer.update()
    assert bpy.ops.scanner.go() == {"FINISHED"}


def test_unreachable_target_reports_and_leaves_the_robot_still(panel):
    bpy.ops.scanner.build_cell()
    before = rig.get_joints(robot_obj()).copy()
    panel.scanner.target_location = (5000.0, 0.0, 0.0)
    with pytest.raises(RuntimeError, match="Unreachable"):
        bpy.ops.scanner.go()
    np.testing.assert_array_equal(rig.get_joints(robot_obj()), before)


def test_invalid_probe_is_refused_and_shown(panel):
    s = panel.scanner
    s.probe_phi = math.radians(10)  # below gamma: no far limit
    with pytest.raises(RuntimeError, match="φ − γ"):
        bpy.ops.scanner.build_cell()
    assert bpy.data.collections.get("Scanner Cell") is None
    assert bpy.ops.scanner.load_probe() == {"FINISHED"}
    assert s.probe_phi == pytest.approx(load_probe("default").phi_rad)


def test_table_angle_turns_the_table(panel):
    bpy.ops.scanner.build_cell()
    panel.scanner.table_angle = 1.2
    assert bpy.data.objects["Turntable"].rotation_euler[2] == pytest.approx(1.2)


@pytest.mark.parametrize("laser", ["gobo", "spot"])
def test_probe_views_render_into_images(panel, laser):
    # The spots are Eevee's line: the views render with Eevee for them, Cycles for the gobo.
    panel.scanner.laser = laser
    bpy.ops.scanner.build_cell()
    s = panel.scanner
    s.target_location = (0.0, 0.0, 60.0 + 150.0)
    bpy.ops.scanner.go()
    assert bpy.ops.scanner.render_views() == {"FINISHED"}
    for camera in (0, 1):
        img = bpy.data.images[f"Probe camera {camera}"]
        assert tuple(img.size) == (160, 160)
        px = np.empty(160 * 160 * 4, np.float32)
        img.pixels.foreach_get(px)
        px = px.reshape(160, 160, 4)
        assert (px[..., 0] - px[..., 1]).max() > 0.2  # the red line is there


def test_probe_views_refuse_a_cell_whose_laser_or_part_a_render_would_leave_out(panel):
    """The views rendered without the laser (hidden from renders, or its collection excluded
    from the view layer) and said they had; a deleted laser was "Build the cell first". Each is
    refused naming the object and why; shown again, the views render."""
    bpy.ops.scanner.build_cell()
    panel.scanner.target_location = (0.0, 0.0, 210.0)
    bpy.ops.scanner.go()
    laser, part = bpy.data.objects["Laser"], bpy.data.objects["Workpiece sphere"]
    layer = bpy.context.view_layer.layer_collection.children["Scanner Cell"]
    for hide, show, words in (
            (lambda: setattr(laser, "hide_render", True), lambda: setattr(laser, "hide_render", False),
             "The cell's Laser is hidden from renders"),
            (lambda: setattr(part, "hide_render", True), lambda: setattr(part, "hide_render", False),
             "The cell's Workpiece sphere is hidden from renders"),
            (lambda: setattr(layer, "exclude", True), lambda: setattr(layer, "exclude", False),
             "left out of the view layer \\(collection Scanner Cell excluded\\)")):
        hide()
        with pytest.raises(RuntimeError, match=words):
            bpy.ops.scanner.render_views()
        show()
    assert bpy.ops.scanner.render_views() == {"FINISHED"}
    bpy.data.objects.remove(laser)
    with pytest.raises(RuntimeError, match="The built cell lacks Laser"):
        bpy.ops.scanner.render_views()


def test_calibrating_another_configs_probe_says_the_cell_was_swapped_and_the_cloud_kept(panel, tmp_path, capfd):
    """Calibrate with another config's probe builds that config's cell (its sphere for the
    panel's cylinder) and keeps the scan cloud: the message said nothing of either (Scan's
    says so), and the help text said the part was kept."""
    s = panel.scanner
    s.workpiece, s.output_dir = "cylinder", str(tmp_path)
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    s.scan_config, s.scan_engine, s.scan_frames = "CELL", "raycast", "0:60:20"
    assert bpy.ops.scanner.scan() == {"FINISHED"}
    capfd.readouterr()
    assert bpy.ops.scanner.calibrate(config="demo", views=4) == {"FINISHED"}
    said = "".join(capfd.readouterr())
    assert "the cell is the scan config's (Demo: sphere on the turntable) (the scan cloud there is the earlier " \
           "cell's)" in said, said
    assert "keeping its part" not in bpy.ops.scanner.calibrate.get_rna_type().description


def test_sensor_fields_keep_to_the_ranges_a_config_allows(panel):
    """k1 = 50 scanned (1 mm RMS) and a gain of inf (3.4e38) saturated every column, where a
    config's [sensor] refuses them: the fields stop at the config's limits."""
    s = panel.scanner
    for name, value, top in (("sensor_k1", 50.0, 10.0), ("sensor_k2", -50.0, -10.0), ("sensor_gain", math.inf, 1e7),
                             ("sensor_exposure_ms", 1e30, 1e7), ("sensor_f_number", 1e30, 1e7),
                             ("sensor_focus_mm", 1e30, 1e7)):
        setattr(s, name, value)
        assert getattr(s, name) == pytest.approx(top), name


def test_probe_views_are_saved_with_the_blend_file(panel, tmp_path):
    """The probe views survive a save: read back from the saved file (appended from it, as
    another file would), each has the pixels it was rendered with."""
    bpy.ops.scanner.build_cell()
    panel.scanner.target_location = (0.0, 0.0, 210.0)
    bpy.ops.scanner.go()
    assert bpy.ops.scanner.render_views() == {"FINISHED"}
    rendered = {}
    for camera in (0, 1):
        img = bpy.data.images[f"Probe camera {camera}"]
        rendered[camera] = np.empty(len(img.pixels), np.float32)
        img.pixels.foreach_get(rendered[camera])
    path = str(tmp_path / "views.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path, copy=True)
    with bpy.data.libraries.load(path) as (there, here):
        assert {"Probe camera 0", "Probe camera 1"} <= set(there.images)
        here.images = ["Probe camera 0", "Probe camera 1"]
    for camera, img in enumerate(here.images):
        px = np.empty(len(img.pixels), np.float32)
        img.pixels.foreach_get(px)
        assert px.shape == rendered[camera].shape and np.abs(px - rendered[camera]).max() < 1e-6
        bpy.data.images.remove(img)


def _artists_settings(scene):
    """Render settings an artist might have, none of them the scanner's."""
    r = scene.render
    r.engine = "CYCLES"
    r.resolution_x, r.resolution_y, r.resolution_percentage = 1920, 1080, 50
    r.film_transparent = True
    r.use_multiview = False
    r.image_settings.file_format = "PNG"
    scene.cycles.samples = 128
    scene.cycles.light_sampling_threshold = 0.01
    scene.view_settings.view_transform = "AgX"
    world = bpy.data.worlds.new("Artist's sky")
    if world.node_tree is None:  # worlds have node trees from the start in Blender 5
        world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.7
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.2, 0.3, 0.9, 1.0)
    scene.world = world
    cam = bpy.data.objects.new("Artist's camera", bpy.data.cameras.new("Artist's camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.frame_set(7)


def _settings_of(scene):
    r, bg = scene.render, scene.world.node_tree.nodes["Background"]
    return dict(engine=r.engine, res=(r.resolution_x, r.resolution_y, r.resolution_percentage),
                transparent=r.film_transparent, multiview=r.use_multiview, format=r.image_settings.file_format,
                samples=scene.cycles.samples, threshold=round(scene.cycles.light_sampling_threshold, 6),
                view=scene.view_settings.view_transform, world=scene.world.name,
                sky=(round(bg.inputs["Strength"].default_value, 6), tuple(round(c, 6) for c in bg.inputs["Color"].default_value)),
                camera=scene.camera.name, frame=scene.frame_current,
                white_balance=(scene.view_settings.white_balance_temperature, scene.view_settings.white_balance_tint))


def test_panel_renders_leave_the_scenes_own_render_settings_as_they_were(panel, tmp_path):
    _artists_settings(panel)
    before = _settings_of(panel)
    bpy.ops.scanner.build_cell()
    panel.scanner.target_location = (0.0, 0.0, 210.0)
    bpy.ops.scanner.go()
    for _ in range(3):  # a hair's drift a render (the white balance's) would add up
        assert bpy.ops.scanner.render_views() == {"FINISHED"}
    assert _settings_of(panel) == before
    s = panel.scanner
    s.scan_config, s.output_dir = "step_block", str(tmp_path)
    assert bpy.ops.scanner.scan(frames="0:100:25") == {"FINISHED"}
    assert bpy.data.objects.get("Scan cloud") is not None  # it did render
    assert _settings_of(panel) == before
    # and a scan refused halfway through (a frame range outside the path) as well
    with pytest.raises(RuntimeError):
        bpy.ops.scanner.scan(frames="500:600")
    assert _settings_of(panel) == before


def _artists_post_processing(scene):
    """What an artist's scene may hold that would change a probe image if rendered with it:
    a compositor (a blur), a sequencer strip over the picture, Freestyle lines, the film's
    exposure, a view layer's material and sample overrides, and a world whose background node
    is named otherwise (the scan dimmed only a node named "Background")."""
    if hasattr(scene, "compositing_node_group"):  # 5.0 and later
        g = bpy.data.node_groups.new("Artist's compositor", "CompositorNodeTree")
        g.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
        out, layers, blur = (g.nodes.new(t) for t in ("NodeGroupOutput", "CompositorNodeRLayers", "CompositorNodeBlur"))
        blur.inputs["Size"].default_value = (6, 6)
        g.links.new(layers.outputs["Image"], blur.inputs["Image"])
        g.links.new(blur.outputs["Image"], out.inputs[0])
        scene.compositing_node_group = g
    else:
        scene.use_nodes = True
        tree = scene.node_tree
        blur = tree.nodes.new("CompositorNodeBlur")
        blur.size_x = blur.size_y = 6
        tree.links.new(tree.nodes["Render Layers"].outputs["Image"], blur.inputs["Image"])
        tree.links.new(blur.outputs["Image"], tree.nodes["Composite"].inputs["Image"])
    scene.render.use_compositing = scene.render.use_sequencer = scene.render.use_freestyle = True
    editor = scene.sequence_editor_create()
    strips = editor.strips if hasattr(editor, "strips") else editor.sequences  # (named so before 5.0)
    strips.new_effect("Red", "COLOR", 1, frame_start=1, length=100000).color = (1.0, 0.0, 0.0)
    scene.cycles.film_exposure = 0.2
    dark = bpy.data.materials.new("Artist's clay")
    scene.view_layers[0].material_override = dark
    scene.view_layers[0].samples = 3
    world = bpy.data.worlds.new("Artist's sky")
    if world.node_tree is None:
        world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.name = "Sky light"
    bg.inputs["Strength"].default_value = 1.0
    scene.world = world


def test_a_panel_scan_gives_the_same_cloud_whatever_the_scenes_own_post_processing(panel, tmp_path):
    """The probe images are the scanner's: with every setting above the panel's scan gave 273
    points at 22 µm (a blurred line) or none (a dark override) where a clean scene gives 423
    at 6 µm; afterwards the scene's settings are its own again."""
    from addon.core.geometry.cloud import load_ply

    s = panel.scanner
    s.scan_config = "demo"

    def scan(folder):
        s.output_dir = str(tmp_path / folder)
        assert bpy.ops.scanner.scan(frames="0:120:40") == {"FINISHED"}
        return load_ply(next((tmp_path / folder).rglob("cloud.ply")))

    clean = scan("clean")
    _artists_post_processing(panel)
    layer = panel.view_layers[0]
    busy = scan("busy")
    assert len(clean) > 300 and len(busy) == len(clean)
    np.testing.assert_array_equal(busy.points, clean.points)
    r = panel.render
    assert (r.use_compositing, r.use_sequencer, r.use_freestyle) == (True, True, True)
    assert panel.cycles.film_exposure == pytest.approx(0.2)
    assert layer.material_override.name == "Artist's clay" and layer.samples == 3
    assert panel.world.name == "Artist's sky"
    assert panel.world.node_tree.nodes["Sky light"].inputs["Strength"].default_value == 1.0


def _view(camera: int) -> np.ndarray:
    img = bpy.data.images[f"Probe camera {camera}"]
    px = np.empty(img.size[0] * img.size[1] * 4, np.float32)
    img.pixels.foreach_get(px)
    return px.reshape(img.size[1], img.size[0], 4)


def test_realistic_sensor_in_the_probe_section_changes_the_views(panel):
    bpy.ops.scanner.build_cell()
    s = panel.scanner
    s.target_location = (0.0, 0.0, 60.0 + 150.0)
    bpy.ops.scanner.go()
    bpy.ops.scanner.render_views()
    ideal = _view(0)
    s.sensor_realistic = True
    s.sensor_saturate = s.sensor_noise = True
    s.sensor_bit_depth = "8"
    s.sensor_exposure_ms = 4.0  # four times full scale at the line: it clips
    assert bpy.ops.scanner.render_views() == {"FINISHED"}
    real = _view(0)
    dn = real[..., :3] * 255
    np.testing.assert_allclose(dn, np.round(dn), atol=1e-3)  # 8-bit numbers
    assert real[..., 0].max() == pytest.approx(1.0) and (real[..., 0] >= 1.0).sum() > 20  # clipped
    bpy.ops.scanner.render_views()
    np.testing.assert_array_equal(_view(0), real)  # seeded: the same noise again
    s.sensor_seed += 1
    bpy.ops.scanner.render_views()
    assert (_view(0) != real).mean() > 0.3  # another seed, other noise, on most pixels
    s.sensor_realistic = False  # the switch restores the ideal views exactly
    bpy.ops.scanner.render_views()
    np.testing.assert_array_equal(_view(0), ideal)


def test_bad_sensor_settings_are_refused_with_the_reason(panel):
    bpy.ops.scanner.build_cell()
    s = panel.scanner
    s.sensor_realistic = s.sensor_motion_blur = True
    s.sensor_exposure_ms = 20.0  # longer than a frame at 100 frames/s
    with pytest.raises(RuntimeError, match="longer than 0.98 of a frame"):
        bpy.ops.scanner.render_views()


def test_scan_can_take_the_panels_sensor_and_material(panel, tmp_path):
    import json

    s = panel.scanner
    s.scan_config = "step_block"
    s.output_dir = str(tmp_path)
    s.sensor_realistic = s.sensor_saturate = s.sensor_speckle = True
    s.material, s.ambient = "dark", 0.0
    assert bpy.ops.scanner.scan(frames="0:100:25") == {"FINISHED"}
    report = json.loads(next(tmp_path.glob("*/report.json")).read_text())
    assert report["config"]["sensor"] == "ideal" and report["config"]["material"] == "grey"  # the config's
    s.scan_sensor = "PANEL"
    assert bpy.ops.scanner.scan(frames="0:100:25") == {"FINISHED"}
    report = json.loads(next(tmp_path.glob("*/report.json")).read_text())
    assert report["config"]["sensor"] == ["saturate", "speckle"] and report["config"]["material"] == "dark"


def _errors(obj):
    values = np.empty(len(obj.data.vertices), np.float32)
    obj.data.attributes["error_um"].data.foreach_get("value", values)
    return values


def test_scan_imports_the_cloud_on_the_turntable_and_exports_ply(panel, tmp_path):
    s = panel.scanner
    s.scan_config = "step_block"
    s.output_dir = str(tmp_path)
    assert bpy.ops.scanner.scan(frames="0:100:10") == {"FINISHED"}
    cloud = bpy.data.objects["Scan cloud"]
    assert cloud.parent == bpy.data.objects["Turntable"]
    n = len(cloud.data.vertices)
    assert n > 1000
    from addon.scene.cloud_object import cloud_from_object
    from addon.core.geometry.workpiece import builtin_workpiece

    points = cloud_from_object(cloud).points  # table frame
    d = builtin_workpiece("step_block").truth.distance(points)
    assert np.median(d) < 0.05  # on the part (or the table top, z = 0)
    # Its colours run from blue at 0 to red at the part's 95th percentile of error, said in µm.
    from addon.scene.cloud_object import error_scale_um

    part = cloud_from_object(cloud).points[:, 2] > 0.5  # above the table top: the part's
    top = error_scale_um(cloud)
    assert top > 0 and 0.9 < np.mean(_errors(cloud)[part] <= top) < 0.99
    assert {p.name for p in next(tmp_path.iterdir()).iterdir()} == {"cloud.ply", "report.json", "preview.png"}
    out = tmp_path / "exported.ply"
    assert bpy.ops.scanner.export_ply(filepath=str(out)) == {"FINISHED"}
    from addon.core.geometry.cloud import load_ply

    assert len(load_ply(out)) == n
    # The imported cloud stays out of the probe's images: a second scan sees exactly the same.
    assert bpy.ops.scanner.scan(frames="0:100:10") == {"FINISHED"}
    assert len(bpy.data.objects["Scan cloud"].data.vertices) == n


def test_scan_refusal_leaves_no_cloud(panel, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text((__import__("pathlib").Path(__file__).parents[2] / "rigs/scenes/step_block.toml").read_text()
                   .replace("[0.0, -35.0, 200.0]", "[900.0, -35.0, 200.0]"))
    s = panel.scanner
    s.scan_config = "FILE"
    s.scan_file = str(bad)
    with pytest.raises(RuntimeError, match="cannot be reached"):
        bpy.ops.scanner.scan()
    assert bpy.data.objects.get("Scan cloud") is None


def test_a_scan_dropped_midway_keeps_nothing(scene, tmp_path):
    from addon.core.config.scan import load_scan_config
    from addon.pipeline import ScanRun

    run = ScanRun(load_scan_config("step_block"), scene)
    run.step()
    assert 0 < run.done < run.n
    del run  # what the modal operator does on Esc
    assert not any(tmp_path.iterdir())


def test_poll_greys_out_what_cannot_run(panel):
    assert not bpy.ops.scanner.go.poll()
    assert not bpy.ops.scanner.render_views.poll()
    assert not bpy.ops.scanner.export_ply.poll()
    bpy.ops.scanner.build_cell()
    assert bpy.ops.scanner.go.poll() and bpy.ops.scanner.render_views.poll()


def test_register_unregister_register_leaves_no_residue(scene):
    for _ in range(2):
        ui.register()
        assert hasattr(bpy.types.Scene, "scanner") and hasattr(bpy.types, "SCANNER_OT_scan")
        ui.unregister()
        assert not hasattr(bpy.types.Scene, "scanner")
        assert not [name for name in dir(bpy.types) if name.startswith("SCANNER_")]
    assert not bpy.app.handlers.frame_change_pre and not bpy.app.handlers.render_write


class FakeLayout:
    """Stands in for Blender's UILayout: records labels and checks every drawn property exists."""

    def __init__(self, labels):
        self.labels = labels
        self.active = self.alert = True

    def _sub(self, *args, **kwargs):
        return FakeLayout(self.labels)

    column = row = box = split = _sub

    def prop(self, data, name, **kwargs):
        if name.startswith('["'):
            assert name[2:-2] in data.keys(), name
        else:
            assert hasattr(data, name), name

    def label(self, text="", **kwargs):
        self.labels.append(text)

    def operator(self, idname, **kwargs):
        group, name = idname.split(".")
        assert hasattr(getattr(bpy.ops, group), name), idname


def draw_all(context) -> list[str]:
    from addon.ui.panel import CLASSES

    labels = []
    for cls in CLASSES:
        for attr in ("draw_header", "draw"):
            if hasattr(cls, attr):  # the unbound method on a stand-in panel that has only a layout
                getattr(cls, attr)(type("Panel", (), {"layout": FakeLayout(labels)})(), context)
    return labels


def test_every_panel_draws_with_and_without_a_cell_and_realism(panel):
    context = bpy.context
    assert "Build the cell first" in draw_all(context)
    bpy.ops.scanner.build_cell()
    s = panel.scanner
    assert not any("Speckle" in t for t in draw_all(context))
    s.sensor_realistic = s.sensor_distortion = True
    labels = draw_all(context)
    assert any(t.startswith("Speckle grain") for t in labels) and any("In focus at" in t for t in labels)
    s.sensor_focus_mm = 1.0  # inside the focal length: shown, not raised
    assert "focal length" in " ".join(draw_all(context))


def test_the_scan_operator_carries_its_parameters(panel, tmp_path):
    # A script sets nothing on the panel: config, frames and output folder are the call's.
    assert panel.scanner.scan_config == "demo"
    res = bpy.ops.scanner.scan(config="step_block", frames="0:100:25", output_dir=str(tmp_path))
    assert res == {"FINISHED"}
    (folder,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    assert {p.name for p in folder.iterdir()} == {"cloud.ply", "report.json", "preview.png"}
    import json

    assert json.loads((folder / "report.json").read_text())["frames"] == 4
    with pytest.raises(RuntimeError, match="step must be a whole number of at least 1"):
        bpy.ops.scanner.scan(config="step_block", frames="0:4:0", output_dir=str(tmp_path))


def test_an_unexpected_failure_midway_puts_the_scene_back(panel, tmp_path, monkeypatch):
    from addon import pipeline

    _artists_settings(panel)
    before = _settings_of(panel)

    def broken(self):
        raise RuntimeError("disk on fire")

    monkeypatch.setattr(pipeline.ScanRun, "step", broken)
    with pytest.raises(RuntimeError, match="RuntimeError: disk on fire"):  # bpy.ops raises what the operator reported
        bpy.ops.scanner.scan(config="demo", frames="0:10", output_dir=str(tmp_path))
    assert _settings_of(panel) == before
    assert not list(tmp_path.rglob("*.ply")) and bpy.data.objects.get("Scan cloud") is None


def test_the_joints_box_shows_the_clearance_and_a_collision(panel):
    bpy.ops.scanner.build_cell()
    labels = draw_all(bpy.context)
    shown = [t for t in labels if t.startswith("Clearance")]
    assert len(shown) == 1 and " mm (" in shown[0] and " to " in shown[0], labels
    assert float(shown[0].split()[1]) > 2.0  # the rest pose is clear
    q = np.radians([-18.7, 125.3, -99.6, -49.3, 39.5, 148.1])  # link 4 in the table (see tests/core/test_safety)
    for k in range(6):
        robot_obj()[f"q{k + 1}"] = float(q[k])
    assert any(t == "Collision: link 4 and table" for t in draw_all(bpy.context))


def test_go_refuses_a_colliding_target_and_leaves_the_robot_still(panel):
    bpy.ops.scanner.build_cell()
    before = rig.get_joints(robot_obj()).copy()
    s = panel.scanner
    s.target_frame = "table"
    s.target_location = (0.0, 0.0, 20.0)  # the probe's origin 20 mm up: inside the 30 mm sphere
    s.target_rotation = (0.0, math.pi, 0.0)
    with pytest.raises(RuntimeError, match="Colliding, the robot stays put"):
        bpy.ops.scanner.go()
    np.testing.assert_array_equal(rig.get_joints(robot_obj()), before)


def test_the_calibrate_operator_writes_a_calibrated_probe_and_keeps_the_scene(panel, tmp_path):
    """The panel's Calibrate button: files written, the board gone again, the artist's
    render settings as they were, and the cell the panel scanned in still there: its part
    (rendered again) and the scan's cloud where it was, the cell not taken for stale by Go."""
    from addon.scene.cell import cell_object
    from addon.scene.cloud_object import CLOUD_ROLE, cloud_from_object

    scene = bpy.context.scene
    s = panel.scanner
    s.scan_config, s.scan_engine, s.scan_frames = "CELL", "raycast", "0:60:6"
    s.output_dir, s.table_angle = str(tmp_path / "scan"), math.radians(20)
    assert bpy.ops.scanner.scan() == {"FINISHED"}
    cloud = cloud_from_object(cell_object(CLOUD_ROLE))
    assert len(cloud) > 100
    where = _world_position(cell_object(CLOUD_ROLE))
    hidden = {o.name: o.hide_render for o in bpy.data.collections["Table"].objects}
    scene.render.resolution_x, scene.cycles.samples = 777, 9
    # The Scan box's sensor from the probe panel, with lens distortion: the calibration fits it.
    s.scan_sensor, s.sensor_realistic, s.sensor_distortion = "PANEL", True, True
    assert bpy.ops.scanner.calibrate(views=6, output_dir=str(tmp_path / "cal")) == {"FINISHED"}  # the panel's
    folder = next((tmp_path / "cal").iterdir())
    assert json.loads((folder / "calibration.json").read_text())["distortion_fitted"] is True
    assert sorted(p.name for p in folder.iterdir()) == ["calibration.json", "calibration.png", "probe.toml"]
    assert load_probe(folder / "probe.toml").calibration is not None
    assert "Calibration board" not in bpy.data.objects
    assert (scene.render.resolution_x, scene.cycles.samples) == (777, 9)
    assert hidden == {o.name: o.hide_render for o in bpy.data.collections["Table"].objects}
    assert hidden["Workpiece sphere"] is False
    kept = cell_object(CLOUD_ROLE)
    assert kept is not None and kept.parent == cell_object("Turntable")
    assert np.allclose(_world_position(kept), where, atol=1e-5)
    assert np.allclose(cloud_from_object(kept).points, cloud.points, atol=1e-3)
    s.target_frame, s.target_location = "table", (0.0, 0.0, 210.0)
    assert bpy.ops.scanner.go() == {"FINISHED"}  # the cell is the panel's, not a stale one
    # The calibrated probe chosen in the panel: its optics changed there are refused (the
    # scan triangulated with the calibration of the other geometry: 46 mm RMS at a = 80 mm).
    s.probe, s.probe_file = "FILE", str(folder / "probe.toml")
    calibrated_a = s.probe_a
    s.probe_a = calibrated_a + 20.0
    with pytest.raises(RuntimeError, match=r"carries a calibration made on its own optics \(a_mm 60 mm calibrated, "
                                           r"80 mm asked\)"):
        bpy.ops.scanner.scan()
    s.probe_a = calibrated_a
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}


def test_the_scan_box_sets_engine_frames_and_budget_and_the_operators_own_values_win(panel, tmp_path):
    """The Scan box's Engine, Frames and Profile Budget reach Scan and Adaptive Scan; a value
    given to the operator (a script's) wins over the box's; an engine that cannot render the
    scan is refused in one line before anything renders."""
    import json

    s = panel.scanner
    s.output_dir = str(tmp_path / "box")
    s.scan_engine, s.scan_frames = "raycast", "0:100:25"
    assert bpy.ops.scanner.scan() == {"FINISHED"}
    report = json.loads(next((tmp_path / "box").glob("*/report.json")).read_text())
    assert report["config"]["engine"] == "raycast" and report["frames"] == 4
    with pytest.raises(RuntimeError, match="engine 'foo' is not one of: cycles, eevee, raycast"):
        bpy.ops.scanner.scan(engine="foo")
    assert bpy.ops.scanner.scan(frames="0:20:10", engine="Cycles", output_dir=str(tmp_path / "call")) == {"FINISHED"}
    report = json.loads(next((tmp_path / "call").glob("*/report.json")).read_text())
    assert report["config"]["engine"] == "cycles" and report["frames"] == 2
    s.adaptive_budget = 2  # fits no sweep: the box's budget is the one used, and the panel's field named
    with pytest.raises(RuntimeError, match=r"budget of 2 profiles is below the smallest view's \d+; raise Profile "
                                           r"Budget to at least \d+ \(nothing was scanned\)"):
        bpy.ops.scanner.adaptive(config="demo")
    first = next((tmp_path / "box").glob("*/report.json"))
    written = first.stat().st_mtime_ns
    s.scan_sensor, s.sensor_realistic, s.sensor_noise = "PANEL", True, True  # raycast renders ideal sensors only
    with pytest.raises(RuntimeError, match="Engine raycast: "):
        bpy.ops.scanner.scan()
    assert first.stat().st_mtime_ns == written  # the refused scan wrote nothing over the first one


def test_a_scans_warnings_reach_the_panel_user(panel, tmp_path, capfd):
    """A world fixture over the sphere (not rendered: warned of in report.json) is said by the
    Scan operator too, as a warning report, and its summary line counts it."""
    import json
    from pathlib import Path

    import trimesh

    post = trimesh.creation.box([40.0, 40.0, 100.0])
    post.apply_translation([0.0, 0.0, 114.0])  # 4 mm over the sphere's top (one through it is refused)
    post.apply_transform(load_scan_config_table2base())
    post.export(tmp_path / "post.stl")
    demo = (Path(__file__).parents[2] / "rigs/scenes/demo.toml").read_text()
    (tmp_path / "post.toml").write_text(demo + '\n[[fixture]]\nname = "post"\nfile = "post.stl"\non = "world"\n')
    s = panel.scanner
    s.scan_config, s.scan_file, s.scan_engine = "FILE", str(tmp_path / "post.toml"), "raycast"
    capfd.readouterr()
    assert bpy.ops.scanner.scan(frames="0:100:25", output_dir=str(tmp_path / "out")) == {"FINISHED"}
    said = capfd.readouterr()
    report = json.loads(next((tmp_path / "out").glob("*/report.json")).read_text())
    (warning,) = [w for w in report["warnings"] if "fixture post" in w]
    assert warning in said.out + said.err and "(1 warning: see the Info editor" in said.out + said.err


def load_scan_config_table2base():
    from addon.core.config.scan import load_scan_config

    return load_scan_config("demo").cell.table.table2base(0.0)


def test_the_adaptive_operator_scans_from_the_box_and_brings_the_cloud_in(panel, tmp_path):
    # a budget no sweep fits: told so, naming the panel's field, nothing written
    with pytest.raises(RuntimeError, match="raise Profile Budget to at least"):
        bpy.ops.scanner.adaptive(config="demo", max_profiles=2, output_dir=str(tmp_path))
    assert not any(tmp_path.iterdir())
    assert bpy.ops.scanner.adaptive(config="demo", max_profiles=120, target_coverage=0.05,
                                    output_dir=str(tmp_path)) == {"FINISHED"}
    import json

    (folder,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    report = json.loads((folder / "report.json").read_text())
    assert 0 < report["frames"] <= 120 and report["adaptive"]["sweeps"]
    assert report["adaptive"]["target_coverage"] == pytest.approx(0.05)
    assert report["points"] > 0
    from addon.ui import models

    assert models.CLOUD_NAME in bpy.data.objects


def test_an_output_folder_that_cannot_take_the_files_is_refused_before_anything_renders(panel, tmp_path):
    import time

    s = panel.scanner
    s.scan_config = "step_block"
    (tmp_path / "afile").write_text("x")
    for folder, words in (("/proc/scanner-out", "cannot be written"), (str(tmp_path / "afile"), "is a file"),
                          ("//scans", "not saved yet")):
        s.output_dir = folder
        t = time.perf_counter()
        with pytest.raises(RuntimeError, match=words):
            bpy.ops.scanner.scan(frames="0:100:10")
        with pytest.raises(RuntimeError, match=words):
            bpy.ops.scanner.adaptive(config="demo", max_profiles=120)
        assert time.perf_counter() - t < 20.0  # refused up front, not after the renders
    assert bpy.data.objects.get("Scan cloud") is None


def test_export_ply_where_it_cannot_be_written_says_so_in_one_line(panel, tmp_path):
    s = panel.scanner
    s.scan_config = "step_block"
    s.output_dir = str(tmp_path / "scans")
    assert bpy.ops.scanner.scan(frames="0:100:25") == {"FINISHED"}
    for target, words in (("/proc/scanner-out/x.ply", "nothing written"), (str(tmp_path), "needs a file name")):
        with pytest.raises(RuntimeError, match=words) as caught:
            bpy.ops.scanner.export_ply(filepath=target)
        assert "Traceback" not in str(caught.value)
    assert bpy.ops.scanner.export_ply(filepath=str(tmp_path / "cloud")) == {"FINISHED"}
    assert (tmp_path / "cloud.ply").is_file()  # the extension added, as Blender's exporters do
    assert not bpy.data.filepath
    with pytest.raises(RuntimeError, match="relative to the .blend file, which is not saved yet"):
        bpy.ops.scanner.export_ply(filepath="//beside.ply")  # it would land wherever Blender started
    # In Edit Mode, with half the points deleted there: what the user sees is written (a
    # traceback before: the mesh's data is the edit's until Blender writes it back).
    import bmesh

    from addon.core.geometry.cloud import load_ply

    from addon.scene.cloud_object import cloud_from_object

    cloud = bpy.data.objects["Scan cloud"]
    whole = cloud_from_object(cloud)
    bpy.context.view_layer.objects.active = cloud
    bpy.ops.object.mode_set(mode="EDIT")
    bm = bmesh.from_edit_mesh(cloud.data)
    bmesh.ops.delete(bm, geom=[v for v in bm.verts if v.index % 2], context="VERTS")
    bmesh.update_edit_mesh(cloud.data)
    assert bpy.ops.scanner.export_ply(filepath=str(tmp_path / "edited.ply")) == {"FINISHED"}
    bpy.ops.object.mode_set(mode="OBJECT")
    edited = load_ply(tmp_path / "edited.ply")
    np.testing.assert_allclose(edited.points, whole.points[::2], atol=1e-4)
    for name in ("frame", "camera", "quality"):  # each point keeps its own attributes
        np.testing.assert_array_equal(getattr(edited, name), getattr(whole, name)[::2])


def _world_position(obj):
    bpy.context.view_layer.update()
    return np.array(obj.matrix_world.translation)


def test_the_artists_objects_and_names_survive_the_cells_builds_and_scans(panel, tmp_path):
    """The cell finds its objects by what they are, not by name, and keeps the artist's: an
    object of theirs named "Turntable" or "Robot", one filed in the cell's collection, a prop
    parented to the turntable (where it was), the turntable's own animation; and a rebuild
    leaves no data behind without users."""
    from addon.scene.cell import cell_object

    for name in ("Turntable", "Robot"):
        panel.collection.objects.link(bpy.data.objects.new(name, None))
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    table, robot = cell_object("Turntable"), cell_object("Robot")
    assert table.name == "Turntable.001" and robot.name == "Robot.001" and robot.type == "ARMATURE"
    panel.scanner.target_location = (0.0, 0.0, 210.0)
    assert bpy.ops.scanner.go() == {"FINISHED"}          # the panel's own robot, found under another name
    assert bpy.ops.scanner.render_views() == {"FINISHED"}
    prop = bpy.data.objects.new("Prop", bpy.data.meshes.new("Prop"))
    panel.collection.objects.link(prop)
    prop.parent = table
    prop.location = (0.1, 0.0, 0.02)
    where = _world_position(prop)
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    bpy.data.collections["Scanner Cell"].objects.link(lamp)  # filed with the cell only
    table.keyframe_insert("rotation_euler", index=2, frame=1)
    table.rotation_euler[2] = math.tau
    table.keyframe_insert("rotation_euler", index=2, frame=120)
    spin = table.animation_data.action
    s = panel.scanner
    s.scan_config, s.scan_engine, s.scan_frames, s.output_dir = "CELL", "raycast", "0:4", str(tmp_path)
    assert bpy.ops.scanner.scan() == {"FINISHED"}        # rebuilds the cell built here, then scans
    table = cell_object("Turntable")
    assert prop.parent == table and np.allclose(_world_position(prop), where, atol=1e-6)  # (float32)
    assert table.animation_data.action == spin
    panel.frame_set(60)  # the artist's spin plays on the new turntable
    assert 2.0 < table.rotation_euler[2] < 4.5
    panel.frame_set(1)
    assert [a.name for a in bpy.data.actions] == [spin.name]  # the scan's motion gone with it
    assert lamp.name in panel.objects and lamp.users_collection  # kept, in the scene
    assert all(bpy.data.objects.get(n) is not None and bpy.data.objects[n].type == "EMPTY" for n in ("Turntable", "Robot"))
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    unused = [d.name for coll in (bpy.data.meshes, bpy.data.cameras, bpy.data.lights, bpy.data.armatures,
                                   bpy.data.materials, bpy.data.actions) for d in coll if d.users == 0]
    assert unused == [], unused


def test_props_on_a_turned_table_and_on_a_posed_arm_stay_where_they_were_through_a_scan(panel, tmp_path):
    """A rebuilt cell (a scan rebuilds it) takes the table at 0° and the arm at rest, and the
    panel then turns and poses them again: a prop parented to the turntable, or to the arm's
    last bone, is where it was in the world once the scan is over, not turned by the angle
    again."""
    from addon.scene.cell import cell_object

    s = panel.scanner
    s.table_angle = math.radians(35)
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    s.target_location = (0.0, 0.0, 210.0)
    assert bpy.ops.scanner.go() == {"FINISHED"}
    table, robot = cell_object("Turntable"), cell_object("Robot")
    bpy.context.view_layer.update()
    on_table = bpy.data.objects.new("Prop on the table", None)
    on_arm = bpy.data.objects.new("Prop on the arm", None)
    for prop, parent in ((on_table, table), (on_arm, robot)):
        panel.collection.objects.link(prop)
        prop.location = (0.08, 0.03, 0.25)
        bpy.context.view_layer.update()
        world = prop.matrix_world.copy()
        prop.parent = parent
        if parent is robot:
            prop.parent_type, prop.parent_bone = "BONE", rig.bone_name(6)
        prop.matrix_world = world
    where = [_world_position(p) for p in (on_table, on_arm)]
    assert np.allclose(where, [[0.08, 0.03, 0.25]] * 2, atol=1e-6)
    s.scan_config, s.scan_engine, s.scan_frames, s.output_dir = "CELL", "raycast", "0:4", str(tmp_path)
    assert bpy.ops.scanner.scan() == {"FINISHED"}
    assert abs(cell_object("Turntable").rotation_euler[2] - math.radians(35)) < 1e-6
    assert on_table.parent == cell_object("Turntable") and on_arm.parent == cell_object("Robot")
    assert np.allclose([_world_position(p) for p in (on_table, on_arm)], where, atol=1e-5)


def test_a_cell_filed_under_a_collection_of_the_artists_is_still_the_scenes_cell(panel):
    """The artist files the built cell under a collection of theirs: Go still reaches, and a
    rebuild puts the new cell where they filed the old one."""
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    root = bpy.data.collections["Scanner Cell"]
    setup = bpy.data.collections.new("Setup")
    panel.collection.children.link(setup)
    setup.children.link(root)
    panel.collection.children.unlink(root)
    panel.scanner.target_location = (0.0, 0.0, 210.0)
    assert bpy.ops.scanner.go.poll() and bpy.ops.scanner.go() == {"FINISHED"}
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    root = bpy.data.collections["Scanner Cell"]
    assert root.name in setup.children and root.name not in panel.collection.children


def test_the_artists_copies_of_the_cells_objects_are_the_artists(panel):
    """Shift+D on the part or a probe camera copies its mark: the copy stays the artist's. A
    rebuild keeps it, and the cell's cameras are still its own."""
    from addon.scene.cell import cell_object

    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    copies = []
    for role in ("Workpiece sphere", "ProbeCam_L"):
        original = cell_object(role)
        copy = original.copy()  # what Shift+D does: the custom properties come along
        for col in original.users_collection:
            col.objects.link(copy)
        copy.name = f"My {role}"
        copies.append(copy)
    from addon.ui import models

    sc = models.scene_cell(bpy.context)
    assert [c.name for c in sc.cameras] == ["ProbeCam_L", "ProbeCam_R"]
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    for copy in copies:  # kept, in the scene
        assert copy.name in bpy.data.objects and copy.users_collection
    assert cell_object("ProbeCam_L").name == "ProbeCam_L" and cell_object("Workpiece sphere") not in copies


def test_a_gantry_from_its_urdf_file_gets_its_table_under_it(panel):
    """The Cell panel places the table (Eq. 4's a_R, d_R): a gantry read from its URDF file
    with the table under it reaches over the part, the turntable stands where a_R and d_R put
    it, and a table moved after the build makes Go refuse until the cell is built again."""
    from pathlib import Path

    from addon.scene.cell import cell_object
    from addon.ui import models

    s = panel.scanner
    s.robot, s.robot_file = "FILE", str(Path(__file__).parents[2] / "rigs" / "robots" / "urdf" / "gantry.urdf")
    s.table_a_mm, s.table_d_mm = 0.0, 0.0
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    bpy.context.view_layer.update()
    table = np.array(from_blender(cell_object("Turntable").matrix_world))[:3, 3]
    assert np.allclose(table, [0.0, 0.0, 0.0], atol=1e-3)  # mm, in the robot base's frame
    s.target_frame, s.target_location, s.target_rotation = "table", (10.0, -5.0, 210.0), (0.3, math.pi, 0.0)
    assert bpy.ops.scanner.go() == {"FINISHED"}
    probe2world = from_blender(bpy.data.objects["Probe frame"].matrix_world)
    assert np.allclose(probe2world[:3, 3], [10.0, -5.0, 210.0], atol=0.05)
    s.table_a_mm = -300.0
    with pytest.raises(RuntimeError, match="the turntable's place: built at a_R 0 mm, d_R 0 mm, the panel's at -300"):
        bpy.ops.scanner.go()
    assert models.cell_from(s).table.a_mm == -300.0


def test_a_robot_file_edited_on_disk_makes_the_built_cell_stale(panel, tmp_path):
    """The same file chosen, edited since Build Cell (a link 20 mm longer): Go refuses until
    the cell is built again, as for a new choice."""
    import os
    from pathlib import Path

    text = (Path(__file__).parents[2] / "rigs" / "robots" / "puma560.toml").read_text()
    rig_file = tmp_path / "arm.toml"
    rig_file.write_text(text.replace("../../.cache", str(Path(__file__).parents[2] / ".cache")))
    s = panel.scanner
    s.robot, s.robot_file = "FILE", str(rig_file)
    s.target_frame, s.target_location = "table", (0.0, 0.0, 210.0)
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    assert bpy.ops.scanner.go() == {"FINISHED"}
    rig_file.write_text(rig_file.read_text().replace("a_mm = 431.8", "a_mm = 451.8", 1))
    stat = rig_file.stat()
    os.utime(rig_file, ns=(stat.st_atime_ns, stat.st_mtime_ns + 10**9))  # a second later, however fast the test
    with pytest.raises(RuntimeError, match="its joints or links differ from the built one's"):
        bpy.ops.scanner.go()
    assert bpy.ops.scanner.build_cell() == {"FINISHED"} and bpy.ops.scanner.go() == {"FINISHED"}


def test_a_urdf_robots_mesh_edited_on_disk_renews_the_panels_collision_model(panel, tmp_path):
    """The panel's collision model (the clearance readout) is kept per choice; a collision mesh
    the chosen URDF names, edited since, makes it another choice, so the checks take the new
    shape."""
    import os
    from pathlib import Path

    import trimesh

    from addon.ui import models

    def write_box(size_mm, when_ns):
        stl = tmp_path / "carriage.stl"
        stl.write_bytes(trimesh.creation.box((size_mm, 10.0, 10.0)).export(file_type="stl"))
        os.utime(stl, ns=(when_ns, when_ns))

    write_box(20.0, 1_000_000_000_000_000_000)
    text = (Path(__file__).parents[2] / "rigs" / "robots" / "urdf" / "gantry.urdf").read_text()
    urdf = tmp_path / "gantry.urdf"
    urdf.write_text(text.replace('<link name="carriage">', '<link name="carriage"><collision><geometry>'
                                 '<mesh filename="carriage.stl" scale="0.001 0.001 0.001"/></geometry></collision>', 1))
    s = panel.scanner
    s.robot, s.robot_file = "FILE", str(urdf)
    s.table_a_mm, s.table_d_mm = 0.0, 0.0

    def longest_side_mm(model):
        mesh, _ = model.robot.collision_meshes[model.robot.link_names.index("carriage")]
        return float(np.ptp(mesh.vertices, axis=0).max())

    models.collision_model(s)
    first = models.collision_model(s)
    assert models.collision_model(s) is first  # nothing changed: the same model
    assert longest_side_mm(first) == pytest.approx(20.0, abs=1e-6)
    write_box(80.0, 1_000_000_100_000_000_000)
    renewed = models.collision_model(s)
    assert renewed is not first and longest_side_mm(renewed) == pytest.approx(80.0, abs=1e-6)


def test_a_cell_object_the_artist_deletes_is_freed_and_a_copied_cloud_kept(panel, tmp_path):
    """The cell's record holds its objects by reference: one the artist deletes is freed by the
    next build (its name free again, no object without users left), and a copy the artist
    makes of the scan's cloud is theirs while the cloud stays the cell's."""
    from addon.scene.cell import cell_object
    from addon.scene.cloud_object import CLOUD_ROLE

    s = panel.scanner
    s.scan_config, s.scan_engine, s.scan_frames, s.output_dir = "CELL", "raycast", "0:40:8", str(tmp_path)
    assert bpy.ops.scanner.scan() == {"FINISHED"}
    cloud = cell_object(CLOUD_ROLE)
    copy = cloud.copy()  # Shift+D
    for col in cloud.users_collection:
        col.objects.link(copy)
    copy.name = "My cloud"
    assert cell_object(CLOUD_ROLE) == cloud
    part = cell_object("Workpiece sphere")
    for col in list(part.users_collection):  # what X in the viewport does: out of every collection
        col.objects.unlink(part)
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    assert cell_object("Workpiece sphere").name == "Workpiece sphere"
    assert [o.name for o in bpy.data.objects if o.users == 0] == []
    assert "My cloud" in bpy.data.objects and bpy.data.objects["My cloud"].users_collection


def test_a_cell_from_before_the_marks_is_calibrated_in_without_a_traceback(panel, tmp_path):
    """A cell saved before its objects were marked (and recorded) owns all it holds: keeping
    its cloud through the calibration's build is not tried, and nothing raises."""
    from addon.calibrate import _cell_keeping_cloud
    from addon.core.config.scan import load_scan_config
    from addon.scene.cell import cell_object
    from addon.scene.ownership import BUILT_OBJECTS_KEY, ROLE_KEY

    s = panel.scanner
    s.scan_config, s.scan_engine, s.scan_frames, s.output_dir = "demo", "raycast", "0:40:8", str(tmp_path)
    assert bpy.ops.scanner.scan() == {"FINISHED"}
    root = bpy.data.collections["Scanner Cell"]
    del root[BUILT_OBJECTS_KEY]
    for obj in root.all_objects:
        obj.pop(ROLE_KEY, None)
    sc = _cell_keeping_cloud(load_scan_config("demo"), panel)
    assert sc.table is not None and cell_object("Turntable") is not None


def test_the_artists_action_on_the_probe_frame_survives_a_cycles_render(panel, tmp_path):
    from addon.scene.cell import cell_object

    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    frame = cell_object("Probe frame")
    action = bpy.data.actions.new("Wobble")
    frame.animation_data_create().action = action
    s = panel.scanner
    s.scan_config, s.scan_engine, s.scan_frames, s.output_dir = "CELL", "cycles", "0:2", str(tmp_path)
    assert bpy.ops.scanner.scan() == {"FINISHED"}
    assert "Wobble" in bpy.data.actions


def test_a_cell_saved_before_the_table_was_recorded_is_stale_once_the_table_moves(panel):
    import json

    from addon.scene.cell import BUILT_FROM_KEY
    from addon.ui import models

    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    root = bpy.data.collections["Scanner Cell"]
    record = json.loads(root[BUILT_FROM_KEY])
    del record["table"]
    root[BUILT_FROM_KEY] = json.dumps(record)
    assert models.cell_mismatch(bpy.context) is None  # built on the default table, as then
    panel.scanner.table_a_mm = -460.0
    assert "the turntable's place" in models.cell_mismatch(bpy.context)


def test_a_cycles_scan_leaves_no_data_without_users(panel, tmp_path):
    """Each render call keys the probe's motion on an action of its own; once the frames are
    rendered nothing of it stays behind (a scan of a few chunks left one action per chunk)."""
    s = panel.scanner
    s.scan_config, s.scan_engine, s.scan_frames, s.output_dir = "CELL", "cycles", "0:3", str(tmp_path)
    assert bpy.ops.scanner.scan() == {"FINISHED"}
    unused = [d.name for coll in (bpy.data.meshes, bpy.data.cameras, bpy.data.lights, bpy.data.armatures,
                                   bpy.data.materials, bpy.data.actions) for d in coll if d.users == 0]
    assert unused == [], unused


def test_while_a_scan_runs_the_operators_that_would_pull_the_scene_from_under_it_are_greyed_out(panel):
    from addon.ui import ops

    bpy.ops.scanner.build_cell()
    assert bpy.ops.scanner.build_cell.poll() and bpy.ops.scanner.go.poll() and bpy.ops.scanner.scan.poll()
    ops._SCAN_RUNNING[0] = True
    try:
        for name in ("build_cell", "load_probe", "go", "render_views", "scan", "adaptive", "calibrate"):
            assert not getattr(bpy.ops.scanner, name).poll(), name
    finally:
        ops._SCAN_RUNNING[0] = False
    assert bpy.ops.scanner.build_cell.poll()
    assert ops._error_text({"n": 0, "rms_um": float("nan")}) == "no point on the part (no error to give)"


def test_the_stepped_scan_runs_a_chunk_per_timer_tick_and_esc_keeps_nothing(panel):
    """The panel's Scan and Adaptive Scan (ops._SteppedScan) driven as Blender's event loop
    would: invoke, timer ticks, Esc; with a stand-in for the window manager and the scanner."""
    from types import SimpleNamespace

    from addon.ui import ops

    class Wm:
        def __init__(self):
            self.calls = []

        def event_timer_add(self, *a, **k):
            self.calls.append("timer")
            return object()

        def event_timer_remove(self, timer):
            self.calls.append("timer off")

        def progress_begin(self, lo, hi):
            self.calls.append(("begin", hi))

        def progress_update(self, v):
            self.calls.append(("update", v))

        def progress_end(self):
            self.calls.append("end")

        def modal_handler_add(self, op):
            self.calls.append("modal")

    class Stepped(ops._SteppedScan):
        bl_label = "Stepped"
        _unit = "frames"

        def __init__(self):
            self.messages, self.finished = [], []

        def report(self, kind, text):
            self.messages.append((kind, text))

        def _open(self, context):
            def chunks():
                for done in (2, 4, 6):
                    yield done, 6
                return "the result"
            return "scanner", chunks()

        @staticmethod
        def _progress_of(value):
            return value

        def _finish(self, context, scanner, value):
            self.finished.append((scanner, value))
            return {"FINISHED"}

    context = SimpleNamespace(scene=panel, window=None, window_manager=Wm(), workspace=None)
    tick, esc = SimpleNamespace(type="TIMER", value="NOTHING"), SimpleNamespace(type="ESC", value="PRESS")
    op = Stepped()
    assert op.invoke(context, None) == {"RUNNING_MODAL"} and not ops.idle()  # the first chunk is done
    assert op.modal(context, SimpleNamespace(type="MOUSEMOVE", value="NOTHING")) == {"PASS_THROUGH"}
    assert op.modal(context, tick) == {"RUNNING_MODAL"}
    assert op.modal(context, tick) == {"RUNNING_MODAL"}
    assert op.modal(context, tick) == {"FINISHED"} and op.finished == [("scanner", "the result")] and ops.idle()
    assert ("update", 6) in context.window_manager.calls and context.window_manager.calls[-1] == "end"
    op = Stepped()
    op.invoke(context, None)
    assert op.modal(context, esc) == {"CANCELLED"} and not op.finished and ops.idle()
    assert op.messages[-1] == ({"WARNING"}, "Stepped cancelled; nothing was kept")
    # Blender ending it (a file opened): the panel is not left greyed out.
    op = Stepped()
    op.invoke(context, None)
    op.cancel(context)
    assert ops.idle() and context.window_manager.calls[-1] == "end"


def test_a_calibration_dropped_midway_writes_nothing_and_takes_the_board_away(panel, tmp_path):
    from addon.calibrate import calibrate_steps
    from addon.core.config.scan import load_scan_config

    steps = calibrate_steps(load_scan_config("demo"), tmp_path / "cal", views=6, scene=bpy.context.scene)
    first, second = next(steps), next(steps)
    assert first == (0, 12) and 0 < second[0] < 12 and second[1] == 12  # the board images under way
    assert "Calibration board" in bpy.data.objects
    steps.close()  # Esc
    assert "Calibration board" not in bpy.data.objects
    assert not (tmp_path / "cal").exists() or not any((tmp_path / "cal").iterdir())


def test_points_on_a_table_fixture_come_in_with_the_previews_colour_for_them(panel, tmp_path):
    """A block on the table beside the sphere: the imported cloud colours the block's points
    (judged by the block's own geometry) as preview.png does, and none of the sphere's."""
    from pathlib import Path

    import trimesh

    from addon.scene.cloud_object import FIXTURE_RGB, cloud_from_object

    block = trimesh.creation.box([20.0, 60.0, 60.0])
    block.apply_translation([45.0, 0.0, 30.0])
    block.export(tmp_path / "block.stl")
    demo = (Path(__file__).parents[2] / "rigs/scenes/demo.toml").read_text()
    (tmp_path / "block.toml").write_text(demo + '\n[[fixture]]\nname = "block"\nfile = "block.stl"\non = "table"\n')
    s = panel.scanner
    s.scan_config, s.scan_file, s.scan_engine = "FILE", str(tmp_path / "block.toml"), "raycast"
    assert bpy.ops.scanner.scan(frames="0:180:6", output_dir=str(tmp_path / "out")) == {"FINISHED"}
    cloud = bpy.data.objects["Scan cloud"]
    points = cloud_from_object(cloud).points
    rgba = np.empty(4 * len(points), np.float32)
    cloud.data.color_attributes["error_colour"].data.foreach_get("color", rgba)
    from addon.core.scan.preview import FIXTURE_BGR

    # preview.png's sRGB colour, seen in Blender's linear colour space
    np.testing.assert_allclose(FIXTURE_RGB ** (1 / 2.2) * 255, FIXTURE_BGR[::-1], atol=0.5)
    fixture_coloured = np.all(np.isclose(rgba.reshape(-1, 4)[:, :3], FIXTURE_RGB, atol=1e-6), axis=1)
    q = np.abs(points - [45.0, 0.0, 30.0]) - [10.0, 30.0, 30.0]
    on_block = np.abs(np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)) < 0.2
    from addon.core.config.scan import load_scan_config

    on_sphere = load_scan_config("demo").workpiece.truth.distance(points) < 0.2
    assert on_block.sum() > 50 and fixture_coloured[on_block].mean() > 0.98
    assert on_sphere.sum() > 100 and not fixture_coloured[on_sphere].any()


def test_choosing_a_probe_loads_its_optics_and_a_mesh_in_metres_takes_the_scale_field(panel, tmp_path):
    """From an artist's trial: the probe list's choice is what Build Cell builds (its optics come
    into the fields, and the name says the sensor built); a 50 mm box saved in metres is refused
    naming the Scale field, then built at its size with Scale 1000, the message naming the file."""
    import trimesh

    from addon.core.config.rigs import load_probe

    s = panel.scanner
    s.probe = "hires"
    hires = load_probe("hires")
    assert (s.probe_rows, s.probe_cols) == (hires.rows_px, hires.cols_px)
    assert s.probe_phi == pytest.approx(hires.phi_rad)
    s.probe_rows, s.probe_cols = 200, 320  # edited by hand: built so, and named so
    box = trimesh.creation.box([0.05, 0.04, 0.03])
    box.apply_translation([0.0, 0.0, 0.015])
    box.export(tmp_path / "box_in_metres.stl")
    s.workpiece, s.workpiece_file = "FILE", str(tmp_path / "box_in_metres.stl")
    with pytest.raises(RuntimeError, match="0.05 mm across.*Scale field"):
        bpy.ops.scanner.build_cell()
    # A part lying wholly beyond the table's rim is refused as Scanner(workpiece=path) refuses it
    # (the panel built and scanned it: a review found the panel's own placement skipped the check).
    far = box.copy()
    far.apply_translation([5.0, 0.0, 0.0])
    far.export(tmp_path / "far.stl")
    s.workpiece_file, s.workpiece_scale = str(tmp_path / "far.stl"), 1000.0
    with pytest.raises(RuntimeError, match="wholly beyond the table.*centre the part in the file"):
        bpy.ops.scanner.build_cell()
    s.workpiece_file = str(tmp_path / "box_in_metres.stl")
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    part = next(o for o in bpy.data.objects if o.name.startswith("Workpiece ") and "twin" not in o.name)
    np.testing.assert_allclose(sorted(part.dimensions), sorted([0.05, 0.04, 0.03]), rtol=1e-6)  # metres in Blender
    from addon.ui import models

    assert "320x200" in models.probe_from(s).name


def test_scan_can_take_the_cell_built_here_with_the_users_own_mesh(panel, tmp_path, capfd):
    """From an artist's trial: Scan used to swap the cell built from the Cell panel for the
    scan config's. "The Cell Built Here" scans the panel's own cell: a torus of the user's own,
    measured along a path laid out for it, its points on the torus by the torus's own geometry."""
    import json

    import trimesh

    torus = trimesh.creation.torus(major_radius=25.0, minor_radius=8.0, major_sections=96, minor_sections=48)
    torus.apply_translation([0.0, 0.0, 8.0])  # lying on the table
    torus.export(tmp_path / "torus.stl")
    s = panel.scanner
    s.workpiece, s.workpiece_file = "FILE", str(tmp_path / "torus.stl")
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    s.scan_config, s.scan_engine = "CELL", "raycast"
    assert bpy.ops.scanner.scan(frames="0:210:3", output_dir=str(tmp_path / "out")) == {"FINISHED"}
    report = json.loads(next((tmp_path / "out").glob("*/report.json")).read_text())
    assert report["config"]["workpiece"] == str(tmp_path / "torus.stl") and report["points_on_part"] > 500
    from addon.scene.cloud_object import cloud_from_object

    P = cloud_from_object(bpy.data.objects["Scan cloud"]).points
    part = P[:, 2] > 0.5
    ring = np.hypot(np.hypot(P[part, 0], P[part, 1]) - 25.0, P[part, 2] - 8.0)  # distance from the tube's axis
    assert np.median(np.abs(ring - 8.0)) < 0.05  # on the torus's surface (its facets lie within 0.02 mm)
    assert bpy.data.objects["Workpiece torus"]  # the user's part is still the cell's
    assert "the cell is the scan config's" not in "".join(capfd.readouterr())
    s.scan_config = "demo"  # a config's cell stands in for the one built here: said so
    assert bpy.ops.scanner.scan(frames="0:180:60", output_dir=str(tmp_path / "out2")) == {"FINISHED"}
    assert "the cell is the scan config's (Demo: sphere on the turntable)" in "".join(capfd.readouterr())


def test_after_a_scan_the_robot_and_the_table_are_where_the_panel_says(panel, tmp_path):
    """From an artist's trial: a scan rebuilt the cell from its config and left the robot at
    zero joints and the table at 0° while the Table box still said 45°."""
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    q = np.radians([20, 50, -70, 10, 40, -30])
    rig.set_joints(robot_obj(), q)
    panel.scanner.table_angle = math.radians(45)
    # Cycles (the demo's engine) keyframes the robot's and the table's motion: neither may pull
    # them back to the scan's path when the frame changes.
    assert bpy.ops.scanner.scan(frames="0:180:90", output_dir=str(tmp_path / "out")) == {"FINISHED"}
    np.testing.assert_allclose(rig.get_joints(robot_obj()), q, atol=1e-6)
    assert bpy.data.objects["Turntable"].rotation_euler[2] == pytest.approx(math.radians(45))
    panel.frame_set(panel.frame_current + 1)  # no scan keyframe pulls them away
    assert bpy.data.objects["Turntable"].rotation_euler[2] == pytest.approx(math.radians(45))
    np.testing.assert_allclose(rig.get_joints(robot_obj()), q, atol=1e-6)


def test_the_cell_built_here_is_scanned_from_its_probes_own_range(panel):
    """A probe edited to a 30 mm baseline measures at 35-125 mm, not the default's 70-250 mm:
    the path laid out for the part stands the probe off by the middle of that range and leaves
    out the sweep's ends that look past the part at a table beyond that range, so no frame is
    out of range (by the Scanner's own ray casts) and the turns are all there."""
    from addon import Scanner
    from addon.core.kinematics.path import solve_path
    from addon.ui import models
    from addon.ui.ops import _cell_config

    s = panel.scanner
    s.probe_a = 30.0
    z0, z1 = models.probe_from(s).z_range_mm
    assert z1 < 160.0  # the default stand-off would leave everything out of range
    cfg = _cell_config(s)
    sol = solve_path(cfg.cell, cfg.waypoints, cfg.q_start)
    assert sol.ok.all()
    assert Scanner(config=cfg).frames_out_of_range(sol.q, cfg.waypoints.table_rad).tolist() == []
    assert 180 <= len(cfg.waypoints) < 210  # three turns of 60, and part of the 30-frame sweep


def test_a_mesh_file_rests_on_the_table_and_bad_values_from_a_script_are_refused(panel, tmp_path, capfd):
    """From a Blender 4.5 user's trial: a box saved centred on its origin (half of it below the
    table top) is put on the table, the message saying by how much; a NaN table angle and a
    camera a kilometre from the laser are refused by the operators with one line; Export PLY
    names the file and the folder, never its temporary file, and says why it is greyed out."""
    import trimesh

    box = trimesh.creation.box([40.0, 30.0, 20.0])  # centred: z from -10 to 10 mm
    box.export(tmp_path / "box.stl")
    s = panel.scanner
    s.workpiece, s.workpiece_file = "FILE", str(tmp_path / "box.stl")
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    assert "box.stl (put on the table: lifted 10.0 mm" in "".join(capfd.readouterr())
    part = next(o for o in bpy.data.objects if o.name.startswith("Workpiece ") and "twin" not in o.name)
    lowest = min((part.matrix_world @ v.co).z for v in part.data.vertices)
    table_top = bpy.data.objects["Turntable"].matrix_world.translation.z
    assert lowest == pytest.approx(table_top, abs=1e-6)  # metres in Blender: on the table top

    s.table_angle = float("nan")
    for op in (bpy.ops.scanner.build_cell, bpy.ops.scanner.render_views):
        with pytest.raises(RuntimeError, match="Table angle must be a finite angle"):
            op()
    with pytest.raises(RuntimeError, match="Table angle must be a finite angle"):
        bpy.ops.scanner.scan(frames="0:2", output_dir=str(tmp_path / "never"))
    assert not (tmp_path / "never").exists()
    assert all(math.isfinite(v) for v in bpy.data.objects["Turntable"].matrix_world.to_euler())
    s.table_angle = 0.0
    s.probe_b = 1e6
    with pytest.raises(RuntimeError, match=r"b_mm = 1e\+06 mm is beyond the ±100000 mm"):
        bpy.ops.scanner.build_cell()

    assert not bpy.ops.scanner.export_ply.poll()  # no cloud yet
    (tmp_path / "a_file").write_text("")
    for target, words in (("", "needs a file name, and none was given"),
                          (str(tmp_path / "a_file" / "x.ply"), "a_file is a file, not a folder"),
                          (str(tmp_path / "nowhere" / "x.ply"), "the folder .*nowhere does not exist")):
        cloud = mark(bpy.data.objects.new("Scan cloud", bpy.data.meshes.new("Scan cloud")), "Scan cloud")
        bpy.data.collections["Scanner Cell"].objects.link(cloud)  # something to export, where a scan puts it
        register_made(bpy.data.collections["Scanner Cell"], cloud)  # and as the cell's, as a scan records it
        with pytest.raises(RuntimeError, match=words) as caught:
            bpy.ops.scanner.export_ply(filepath=target)
        assert ".part" not in str(caught.value)
        bpy.data.objects.remove(cloud)
    assert not (tmp_path / "nowhere").exists()



def test_a_cell_built_in_one_scene_is_not_taken_for_built_in_another(panel):
    from addon.scene.cell import cell_object

    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    bpy.data.collections["Scanner Cell"].objects.link(lamp)  # the artist's, filed with the cell
    other = bpy.data.scenes.new("Shot 2")
    with _in_scene(other):
        assert not bpy.ops.scanner.go.poll() and not bpy.ops.scanner.render_views.poll()
        with pytest.raises(RuntimeError, match="The cell is built in another scene: Build Cell here takes it here"):
            bpy.ops.scanner.render_views()
        assert cell_object("Robot", scene=other) is None and cell_object("Robot") is not None
        assert bpy.ops.scanner.build_cell() == {"FINISHED"}
        assert cell_object("Robot", scene=other) is not None and bpy.ops.scanner.render_views.poll()
    assert cell_object("Robot", scene=panel) is None  # one cell a file: it went to the other scene
    assert lamp.name in panel.objects and lamp.name not in other.objects  # the lamp stayed where it was


def _in_scene(scene):
    """The window showing ``scene`` meanwhile (as the artist's scene switcher does), or the
    context overridden where bpy has no window."""
    from contextlib import contextmanager

    window = bpy.context.window
    if window is None:
        return bpy.context.temp_override(scene=scene)

    @contextmanager
    def shown():
        before = window.scene
        window.scene = scene
        try:
            yield
        finally:
            window.scene = before
    return shown()


def test_go_and_the_views_refuse_a_cell_the_panel_no_longer_describes(panel):
    """Go solves with the panel's robot and probe and moves the built arm; the views render the
    built cameras: once the choices change, both refuse until the cell is built again, and the
    Joints box says so instead of a clearance for a cell that is not there."""
    from addon.ui import models

    s = panel.scanner
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    assert models.cell_mismatch(bpy.context) is None
    robot = models.find_robot(panel)
    before = list(rig.get_joints(robot))
    s.robot = "puma560"
    s.target_location = (20.0, -10.0, 150.0)
    with pytest.raises(RuntimeError, match=r"no longer describes the built cell \(the robot: built Adept Viper s650, "
                                           r"chosen Unimation PUMA 560\): press Build Cell"):
        bpy.ops.scanner.go()
    assert list(rig.get_joints(robot)) == before and models.clearance_readout(bpy.context) is None
    s.robot = "adept_viper_s650"
    s.probe_a = 55.0
    with pytest.raises(RuntimeError, match="its optics, sensor or mount differ from the built one's"):
        bpy.ops.scanner.render_views()
    s.probe_a = 60.0
    assert models.cell_mismatch(bpy.context) is None and bpy.ops.scanner.render_views() == {"FINISHED"}
    # A cell built with the table elsewhere (a scan config's cell, as a Scan of it builds one)
    from addon.core.kinematics.turntable import Turntable
    from addon.scene.cell import build_cell

    here = models.cell_from(s)
    moved = type(here)(here.robot, Turntable(here.table.a_mm + 40.0, here.table.d_mm))
    build_cell(panel, moved, models.probe_from(s), models.workpiece_from(s), name=models.CELL_NAME)
    with pytest.raises(RuntimeError, match=r"the turntable's place: built at a_R -460 mm, d_R -200 mm, the "
                                           r"panel's at -500 and -200 mm"):
        bpy.ops.scanner.go()
    assert bpy.ops.scanner.build_cell() == {"FINISHED"} and models.cell_mismatch(bpy.context) is None
    robot = models.find_robot(panel)
    robot["q1"] = 1000.0  # from a script: the sliders keep the limits
    with pytest.raises(RuntimeError, match=r"outside its joint limits \(J1 = 57295.780° outside \[-170°, 170°\]\)"):
        bpy.ops.scanner.go()
    assert math.isnan(models.clearance_readout(bpy.context)[0])
    robot["q1"] = 0.0
    s.sensor_realistic, s.sensor_defocus, s.sensor_focus_mm = True, True, 1.0
    with pytest.raises(RuntimeError, match=r"^Error: Sensor realism: defocus: \[sensor\] focus_mm 1 mm must lie "
                                           r"beyond the lens's focal length") as caught:
        bpy.ops.scanner.render_views()
    assert "Traceback" not in str(caught.value)


def test_the_cell_built_here_scans_with_the_cells_laser_and_adaptive_takes_the_panels_sensor(panel, tmp_path):
    import json

    from addon.ui import models

    s = panel.scanner
    s.laser = "slit"
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    s.scan_config, s.scan_engine, s.scan_frames, s.output_dir = "CELL", "cycles", "0:2", str(tmp_path)
    assert bpy.ops.scanner.scan() == {"FINISHED"}
    assert models.scene_cell(bpy.context).laser_model == "slit"  # the cell's own laser, not the demo's gobo
    s.laser, s.scan_engine, s.adaptive_budget = "gobo", "raycast", 75
    s.scan_sensor, s.sensor_realistic, s.sensor_noise = "PANEL", True, True
    s.ambient = 0.0
    assert bpy.ops.scanner.adaptive() == {"FINISHED"}
    report = json.loads(next(tmp_path.rglob("*adaptive*/report.json")).read_text())
    assert report["config"]["sensor"] == ["noise"]


def test_a_rebuild_that_fails_on_a_mesh_changed_on_disk_leaves_the_old_cell(panel, tmp_path):
    """The rig file unchanged, its base mesh made junk (or removed) since: the build is refused
    in one line naming the file, and the cell built before is still whole (it was removed first,
    leaving a robot alone in it, or a traceback)."""
    import shutil
    import trimesh

    from addon.core.config.toml import resolve_rig

    rig_file = tmp_path / "arm.toml"
    shutil.copy(resolve_rig("robots", "puma560"), rig_file)
    text = "\n".join(ln for ln in rig_file.read_text().splitlines()
                     if not ln.startswith(("base_mesh", "meshes_optional", "mesh =")))
    rig_file.write_text('base_mesh = "base.stl"\n' + text + "\n")
    trimesh.creation.box([200.0, 200.0, 100.0]).export(tmp_path / "base.stl")
    s = panel.scanner
    s.robot, s.robot_file = "FILE", str(rig_file)
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    before = sorted(o.name for o in bpy.data.collections["Scanner Cell"].all_objects)
    (tmp_path / "base.stl").write_text("not an stl\n")
    with pytest.raises(RuntimeError, match=r"base mesh .*base.stl.*the cell is left as it was"):
        bpy.ops.scanner.build_cell()
    (tmp_path / "base.stl").unlink()
    with pytest.raises(RuntimeError, match=r"base mesh .*base.stl.*cannot be read now"):
        bpy.ops.scanner.build_cell()
    assert sorted(o.name for o in bpy.data.collections["Scanner Cell"].all_objects) == before


def test_go_and_scan_name_a_nan_table_angle_and_a_deleted_joint_and_a_rig_limited_away_from_zero(panel, tmp_path):
    from addon.core.config.toml import resolve_rig

    bpy.ops.scanner.build_cell()
    panel.scanner.table_angle = float("nan")
    with pytest.raises(RuntimeError, match="Table angle must be a finite angle"):
        bpy.ops.scanner.go()
    panel.scanner.table_angle = 0.0
    del robot_obj()["q3"]  # one click in Custom Properties
    with pytest.raises(RuntimeError, match="no joint value q3.*Build Cell again"):
        bpy.ops.scanner.go()
    # a rig whose J2 limits exclude 0 is built at its nearest limit, and Go starts from there
    rig_file = tmp_path / "viper.toml"
    text = resolve_rig("robots", "adept_viper_s650").read_text()
    assert "min_deg = -150.0" in text or "min_deg" in text
    lines, seen = [], 0
    for line in text.splitlines():
        if line.strip().startswith("min_deg"):
            seen += 1
            if seen == 2:
                line = "min_deg = 10.0"
        lines.append(line)
    rig_file.write_text("\n".join(lines) + "\n")
    panel.scanner.robot, panel.scanner.robot_file = "FILE", str(rig_file)
    assert bpy.ops.scanner.build_cell() == {"FINISHED"}
    assert rig.get_joints(robot_obj())[1] == pytest.approx(math.radians(10.0))
    try:  # whatever Go says of its target, it no longer refuses to start from the built pose
        bpy.ops.scanner.go()
    except RuntimeError as exc:
        assert "stands outside its joint limits" not in str(exc), exc


def test_a_changed_laser_or_surface_asks_for_a_rebuild_and_a_nan_roughness_is_refused_before_it(panel):
    from addon.ui import models

    bpy.ops.scanner.build_cell()
    assert models.cell_mismatch(bpy.context) is None
    panel.scanner.laser = "slit"
    assert "the laser: built gobo, chosen slit" in models.cell_mismatch(bpy.context)
    panel.scanner.laser = "gobo"
    panel.scanner.material = "glossy"
    assert "the workpiece's surface" in models.cell_mismatch(bpy.context)
    bpy.ops.scanner.build_cell()
    mats = {}
    for r in (0.001, 0.004):  # each its own material (0.004 took 0.001's, named to 2 decimals)
        panel.scanner.roughness = r
        bpy.ops.scanner.build_cell()
        wp = next(o for o in bpy.data.collections["Scanner Cell"].all_objects if o.name.startswith("Workpiece"))
        mats[r] = wp.active_material.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value
    assert mats[0.001] == pytest.approx(0.001, abs=1e-6) and mats[0.004] == pytest.approx(0.004, abs=1e-6)
    before = sorted(o.name for o in bpy.data.collections["Scanner Cell"].all_objects)
    panel.scanner["roughness"] = float("nan")  # from a script (the slider keeps 0..1)
    with pytest.raises(RuntimeError, match="roughness must be a number from 0 to 1"):
        bpy.ops.scanner.build_cell()
    assert sorted(o.name for o in bpy.data.collections["Scanner Cell"].all_objects) == before


def test_the_table_angle_of_another_scene_leaves_this_cell_alone(panel):
    bpy.ops.scanner.build_cell()
    other = bpy.data.scenes.new("Other")
    try:
        other.scanner.table_angle = 1.0
        table = next(o for o in bpy.data.collections["Scanner Cell"].all_objects if o.name == "Turntable")
        assert table.rotation_euler[2] == pytest.approx(panel.scanner.table_angle)
    finally:
        bpy.data.scenes.remove(other)


def test_probe_views_at_a_negative_frame_are_refused_in_one_line(panel, tmp_path, monkeypatch):
    # (Blender rendered frame 0, the files of frame -5 were not found: a traceback, and a
    # temporary folder of images left behind). The temporary folders go to this test's own
    # folder: other test files' renders come and go in the system's meanwhile.
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    bpy.ops.scanner.build_cell()
    panel.frame_set(-5)
    try:
        with pytest.raises(RuntimeError, match="Blender renders frames from 0 on"):
            bpy.ops.scanner.render_views()
    finally:
        panel.frame_set(1)
    assert list(tmp_path.glob("scanner-render-*")) == []


def test_panel_paths_expand_the_home_folder_and_calibrate_refuses_a_folder_of_an_unsaved_file(panel):
    import os

    from addon.ui import models

    # (a scan to "~/scans" made a folder named "~" where Blender was started)
    assert models.panel_path("~/scans") == os.path.join(os.path.expanduser("~"), "scans")
    assert str(models.output_dir("~/scans", "demo")).startswith(os.path.expanduser("~"))
    assert not bpy.data.filepath
    with pytest.raises(RuntimeError, match="relative to the .blend file, which is not saved yet"):
        bpy.ops.scanner.calibrate(config="demo", views=4, output_dir="//cal")


def test_a_second_scan_of_a_config_does_not_say_its_own_cell_was_swapped_in(panel, tmp_path):
    # (the first scan of a config leaves that config's cell; every later scan of it said "the
    # cell is the scan config's: choose The Cell Built Here ...", though nothing was swapped)
    panel.scanner.output_dir = str(tmp_path)
    assert bpy.ops.scanner.scan(config="demo", frames="0:1", engine="raycast") == {"FINISHED"}
    from addon.ui import ops

    texts = []
    real = ops._swapped_text
    ops._swapped_text = lambda op, report, config=None: texts.append(real(op, report, config)) or texts[-1]
    try:
        assert bpy.ops.scanner.scan(config="demo", frames="1:2", engine="raycast") == {"FINISHED"}
        panel.scanner.robot = "puma560"  # a cell of another robot built here: that one is swapped out
        bpy.ops.scanner.build_cell()
        assert bpy.ops.scanner.scan(config="demo", frames="1:2", engine="raycast") == {"FINISHED"}
    finally:
        ops._swapped_text = real
    assert texts[0] == "" and "the cell is the scan config's" in texts[1], texts


def test_a_deleted_cloud_material_is_made_again_and_used_by_the_next_cloud(panel, tmp_path):
    panel.scanner.output_dir = str(tmp_path)
    assert bpy.ops.scanner.scan(config="demo", frames="0:1", engine="raycast") == {"FINISHED"}
    bpy.data.materials.remove(bpy.data.materials["Scanner cloud"])  # the artist tidies up
    assert bpy.ops.scanner.scan(config="demo", frames="1:2", engine="raycast") == {"FINISHED"}
    tree = bpy.data.node_groups["Scanner cloud points"]
    (node,) = [n for n in tree.nodes if n.bl_idname == "GeometryNodeSetMaterial"]
    assert node.inputs["Material"].default_value == bpy.data.materials["Scanner cloud"]
