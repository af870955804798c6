"""Core models from the panel's settings, and the cell's Blender objects found again by name."""

from __future__ import annotations

import math
import tempfile
import os
from pathlib import Path

import bpy

from ..core.kinematics.cell import Cell
from ..core.errors import InputError, ScannerError
from ..core.config.rigs import load_robot
from ..core.optics.probe import Probe
from ..core.config.rigs import load_probe
from ..core.optics.sensor import SensorModel
from ..core.kinematics.turntable import PAPER_A_R_MM, PAPER_D_R_MM, Turntable
from ..core.geometry.workpiece import builtin_workpiece, load_workpiece, resting_on_table
from ..scene.cell import CELL_NAME, cell_object, in_scene
from ..scene.cloud_object import CLOUD_ROLE
from .props import CELL, FILE

CLOUD_NAME = CLOUD_ROLE  # the scan cloud is found by its role
# The extension's own package ("bl_ext.<repo>.<id>"); empty when these modules are used outside one.
ROOT_PACKAGE = ".".join(__package__.split(".")[:-2])


def chosen_file(value: str, what: str) -> str:
    """The absolute path of a file chosen in the panel; InputError when none is chosen."""
    if not value:
        raise InputError(f"choose a {what} file first")
    return panel_path(value)


def panel_path(value: str) -> str:
    """A path from the panel made absolute: //-relative to the .blend file, ~ the home folder
    (a scan to "~/scans" made a folder named "~" where Blender was started)."""
    return os.path.expanduser(bpy.path.abspath(value))


def robot_from(s):
    return load_robot(chosen_file(s.robot_file, "robot") if s.robot == FILE else s.robot)


def chosen_probe_rig(s) -> Probe:
    """The probe rig chosen in the panel's list (or its file), as the rig file has it."""
    return load_probe(chosen_file(s.probe_file, "probe") if s.probe == FILE else s.probe)


def show_probe_optics(s, probe: Probe) -> None:
    """Put ``probe``'s optics (a, b, phi, gamma, sensor size) into the panel's fields."""
    s.probe_a, s.probe_b, s.probe_phi, s.probe_gamma = probe.a_mm, probe.b_mm, probe.phi_rad, probe.gamma_rad
    s.probe_rows, s.probe_cols = probe.rows_px, probe.cols_px


def probe_from(s) -> Probe:
    """The probe rig with the panel's optics (a, b, phi, gamma, sensor size, which its name then
    says); raises InputError when invalid."""
    rig = chosen_probe_rig(s).with_resolution(s.probe_rows, s.probe_cols)
    return rig.with_optics(s.probe_a, s.probe_b, s.probe_phi, s.probe_gamma)


def sensor_from(s) -> SensorModel:
    """The probe panel's sensor model (the ideal one unless "Realistic sensor" is ticked);
    raises InputError when a setting is out of range."""
    if not s.sensor_realistic:
        return SensorModel()
    return SensorModel(integrate_pixels=s.sensor_integrate_pixels, saturate=s.sensor_saturate, noise=s.sensor_noise,
                       speckle=s.sensor_speckle, defocus=s.sensor_defocus, motion_blur=s.sensor_motion_blur,
                       distortion=(s.sensor_k1, s.sensor_k2, 0.0, 0.0) if s.sensor_distortion else (),
                       undistort=s.sensor_undistort, exposure_ms=s.sensor_exposure_ms,
                       auto_exposure=s.sensor_auto_exposure, target_peak=s.sensor_target_peak, gain=s.sensor_gain,
                       bit_depth=int(s.sensor_bit_depth), f_number=s.sensor_f_number, focus_mm=s.sensor_focus_mm or None,
                       seed=s.sensor_seed, wavelength_nm=probe_from(s).wavelength_nm)  # speckle: the laser's, as a config's


def check_table_angle(s) -> None:
    """Refuse a table angle that is not a finite number (a script can set NaN)."""
    if not math.isfinite(s.table_angle):
        raise InputError(f"the Table angle must be a finite angle, got {s.table_angle}")


def placed_workpiece(s):
    """The panel's part and how far it was lifted to rest on the table (mm): a built-in shape
    (0), or a mesh file put on the table, its lowest point on the table top, the file's x and
    y kept."""
    if s.workpiece == FILE:
        part = load_workpiece(chosen_file(s.workpiece_file, "mesh"), scale=s.workpiece_scale or None)
        return resting_on_table(part)
    return builtin_workpiece(s.workpiece), 0.0


def workpiece_from(s):
    return placed_workpiece(s)[0]


def cell_from(s) -> Cell:
    return Cell(robot_from(s), Turntable(s.table_a_mm, s.table_d_mm))


def scene_cell(context):
    """The built cell's handles, or None when no cell has been built in this scene."""
    from ..scene.cell import SceneCell

    s = context.scene.scanner
    try:
        return SceneCell.attach(context.scene, cell_from(s), probe_from(s), None, CELL_NAME)
    except ScannerError:  # the panel's choices cannot be read (a robot file gone, an impossible probe)
        return None


def find_robot(scene):
    """The cell's robot where the cell is built in ``scene``, else None."""
    return cell_object("Robot", scene=scene)


_CLEARANCE_MODELS: dict = {}  # the panel's collision model per robot, probe and workpiece choice


def collision_model(s):
    """The collision model of the panel's robot, table, probe and workpiece (built once per choice)."""
    from ..core.safety import CollisionModel, Safety

    key = _choices_key(s)
    model = _CLEARANCE_MODELS.get(key)
    if model is None:
        probe, cell = probe_from(s), cell_from(s)
        model = CollisionModel(cell.robot.with_tool(probe.mount), probe, cell.table, workpiece_from(s).mesh, (),
                               Safety().min_clearance_mm)
        _CLEARANCE_MODELS.clear()
        _CLEARANCE_MODELS[key] = model
    return model


_DESCRIBED: dict = {}  # what the panel's choices build (scene.cell.built_from), per choice


def cell_mismatch(context) -> str | None:
    """How the cell built in the scene differs from the one the panel's robot, probe and
    workpiece choices describe ("the robot: built Adept Viper s650, chosen Unimation PUMA
    560"), or None where they agree, no cell is built here, or the cell predates the record
    (a file saved by an earlier version). Go, the probe views and the clearance readout act
    on the built cell, so they ask first."""
    import json

    from ..scene.cell import BUILT_FROM_KEY, built_from

    root = bpy.data.collections.get(CELL_NAME)
    if root is None or not in_scene(root, context.scene) or BUILT_FROM_KEY not in root:
        return None
    s = context.scene.scanner
    key = _choices_key(s) + (s.probe_rows, s.probe_cols)
    described = _DESCRIBED.get(key)
    if described is None:
        described = built_from(robot_from(s), probe_from(s), workpiece_from(s), cell_from(s).table)
        _DESCRIBED.clear()
        _DESCRIBED[key] = described
    built = json.loads(root[BUILT_FROM_KEY])
    differ = []
    from ..scene.cell import surface_key

    if "laser" in built and built["laser"] != s.laser:
        differ.append(f"the laser: built {built['laser']}, chosen {s.laser}")
    if "surface" in built and built["surface"] != surface_key(s.material, s.roughness):
        differ.append(f"the workpiece's surface: built {built['surface'][0]}, chosen {s.material}"
                      + (f" (roughness {s.roughness:g})" if built["surface"][0] == s.material else ""))
    # A cell saved before the table was recorded was built on the default table (Turntable()).
    built.setdefault("table", [PAPER_A_R_MM, PAPER_D_R_MM])
    if built["table"] != described["table"]:
        differ.append("the turntable's place: built at a_R {:g} mm, d_R {:g} mm, the panel's at {:g} and {:g} "
                      "mm".format(*built["table"], *described["table"]))
    for what, detail in (("robot", "its joints or links"), ("probe", "its optics, sensor or mount"),
                         ("workpiece", "its size")):
        same = built.get(what) == described[what] and (what != "robot"
                                                       or built.get("robot_poses") == described["robot_poses"])
        if same:
            continue
        was, now = _name_of(built.get(what)), _name_of(described[what])
        differ.append(f"the {what}: built {was}, chosen {now}" if was != now else
                      f"the {what} {now}: {detail} differ from the built one's")
    return "; ".join(differ) or None


def placement_mismatch(context) -> str | None:
    """Where the built cell's robot or table object was moved in the viewport away from where
    the cell puts it (the robot's base at its rig's pose, the table at its a_R and d_R), in
    words; None where they stand where built, or no cell is built. Go, the IK and the collision
    checks work in the cell's placement, so a moved object made Go say "Reached" 100 mm off."""
    import numpy as np

    from ..scene.units import from_blender

    s = context.scene.scanner
    out = []
    robot_obj, table_obj = cell_object("Robot"), cell_object("Turntable")
    if robot_obj is not None:
        off = from_blender(robot_obj.matrix_world) @ np.linalg.inv(robot_from(s).base)
        moved = float(np.linalg.norm(off[:3, 3]))
        turned = math.degrees(math.acos(max(-1.0, min(1.0, (float(np.trace(off[:3, :3])) - 1.0) / 2.0))))
        if moved > 0.01 or turned > 0.01:
            out.append(f"the Robot object was moved in the viewport ({moved:.1f} mm, {turned:.1f}° from where the "
                       f"cell puts the robot's base)")
    if table_obj is not None:
        expected = cell_from(s).table.table2base(0.0)[:3, 3]
        moved = float(np.linalg.norm(from_blender(table_obj.matrix_world)[:3, 3] - expected))
        if moved > 0.01:
            out.append(f"the Turntable object was moved in the viewport ({moved:.1f} mm from the table's a_R and "
                       f"d_R)")
    return "; ".join(out) or None


def hidden_from_render(context, objects) -> str | None:
    """The first of ``objects`` (the cell's laser, table, part) that a render would leave out,
    and why, in words; None where all render. The probe views rendered without the laser and
    said they had rendered (the artist's visibility is kept on the cell's own objects)."""
    def path_to(layer, collection):
        if layer.collection == collection:
            return [layer]
        for child in layer.children:
            found = path_to(child, collection)
            if found:
                return [layer] + found
        return []

    for obj in objects:
        if obj is None:
            continue
        if obj.hide_render:
            return f"the cell's {obj.name} is hidden from renders (its Disable in Renders)"
        for collection in obj.users_collection:
            for layer in path_to(context.view_layer.layer_collection, collection):
                if layer.exclude:
                    return (f"the cell's {obj.name} is left out of the view layer (collection "
                            f"{layer.collection.name} excluded)")
                if layer.collection.hide_render:
                    return (f"the cell's {obj.name} is hidden from renders (collection {layer.collection.name}'s "
                            f"Disable in Renders)")
    return None


def missing_cell_objects(context) -> list[str]:
    """The cell's objects that Go and the probe views need and that are gone from the built
    cell (deleted by hand), by role; empty where none is built or all are there."""
    from ..scene.ownership import own_objects, role_of

    root = bpy.data.collections.get(CELL_NAME)
    if root is None or not in_scene(root, context.scene):
        return []
    roles = {role_of(o) for o in own_objects(root)}
    return [k for k in ("Robot", "Probe frame", "ProbeCam_L", "ProbeCam_R", "Laser", "Turntable") if k not in roles]


def _name_of(entry) -> str:
    """A built_from entry in words: the name it leads with."""
    if entry is None:
        return "none"
    name = entry if isinstance(entry, str) else entry[0]
    return str(name)


def _choices_key(s) -> tuple:
    """The panel's choices, and each chosen file's size and time of change: a file edited on
    disk under the same name is another choice, and so is a URDF robot whose mesh files were."""
    from ..core.config.rigs import file_stamp, urdf_mesh_files

    files = [(s.robot == FILE, s.robot_file), (s.probe == FILE, s.probe_file), (s.workpiece == FILE, s.workpiece_file)]
    meshes = urdf_mesh_files(bpy.path.abspath(s.robot_file)) if s.robot == FILE and s.robot_file else ()
    return (s.robot, s.robot_file, s.table_a_mm, s.table_d_mm, s.probe, s.probe_file, s.probe_a, s.probe_b,
            s.probe_phi, s.probe_gamma, s.workpiece, s.workpiece_file, s.workpiece_scale,
            *(file_stamp(bpy.path.abspath(path)) if chosen and path else None for chosen, path in files),
            *(file_stamp(path) for path in meshes))


def stale_cell_message(mismatch: str) -> str:
    return (f"The panel no longer describes the built cell ({mismatch}): press Build Cell to build the one it "
            f"describes")


def clearance_readout(context):
    """(clearance mm, body, other body, colliding) of the built cell's current pose, for the
    panel; None where there is no cell or the choices cannot be read (the panel says so
    elsewhere). Uses the default clearance of a scan config."""
    from ..core.errors import ScannerError
    from ..scene.rig import get_joints

    s = context.scene.scanner
    robot_obj, table_obj = find_robot(context.scene), cell_object("Turntable", scene=context.scene)
    if robot_obj is None or table_obj is None:
        return None
    try:
        if cell_mismatch(context) is not None:  # the panel's collision model is not the built cell's
            return None
        outside = collision_model(s).robot.limit_violations(get_joints(robot_obj))
    except (ScannerError, OSError, ValueError):
        return None
    if outside:  # (set from a script: the sliders keep the limits) no clearance worth giving there
        return float("nan"), "; ".join(outside), "its limits", True
    try:
        found = collision_model(s).clearance_at(get_joints(robot_obj), float(table_obj.rotation_euler[2]))
    except (ScannerError, OSError, ValueError):
        return None
    if found.collisions:
        c = found.first_collision[0]
        return c.distance_mm, found.label(c.body_a), found.label(c.body_b), True
    c = found.nearest.get(0)
    return None if c is None else (c.distance_mm, found.label(c.body_a), found.label(c.body_b), False)


def default_output_dir() -> Path:
    """The extension's user folder when running as an extension, else a temporary folder."""
    if ROOT_PACKAGE.startswith("bl_ext."):
        return Path(bpy.utils.extension_path_user(ROOT_PACKAGE, path="scans", create=True))
    folder = Path(tempfile.gettempdir()) / "laser_scanner_sim" / "scans"
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def output_dir(folder: str, config_name: str) -> Path:
    """A scan's output folder: ``config_name`` (made file-safe) inside ``folder`` (a Blender
    path; empty: the extension's user folder)."""
    base = Path(panel_path(folder)) if folder else default_output_dir()
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in config_name) or "scan"
    return base / safe


def status(context, text: str | None) -> None:
    """Status-bar text (ignored where there is no window, e.g. headless)."""
    if context.workspace is not None:
        context.workspace.status_text_set(text)


