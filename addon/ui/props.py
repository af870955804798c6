"""The panel's settings (``scene.scanner``): what to build, where to go, what to scan.

Lengths are millimetres (the fields say so), angles are stored in radians and
shown in degrees. Joint angles are not here: they live on the robot armature
(custom properties q1..q6), so the sliders pose the rig directly.
"""

from __future__ import annotations

import math

import bpy
from bpy.props import (BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty, IntProperty,
                       StringProperty)

from ..core.config import available_rigs
from ..core.workpiece import BUILTINS

FILE = "FILE"


def _rig_items(kind: str, label: str):
    return [(n, n.replace("_", " "), f"Bundled {label}") for n in available_rigs(kind)] + [
        (FILE, "File...", f"A {label} file (TOML) chosen below")]


# Enum items are built once: Blender keeps pointers to these strings.
ROBOT_ITEMS = _rig_items("robots", "robot rig")
PROBE_ITEMS = _rig_items("probes", "probe rig")
SCENE_ITEMS = _rig_items("scenes", "scan config")
WORKPIECE_ITEMS = [(k, k.replace("_", " ").title(), f"Built-in {k.replace('_', ' ')} with exact ground truth")
                   for k in BUILTINS] + [(FILE, "Mesh file...", "STL, OBJ, PLY or GLB (mm; GLB in metres)")]


def _table_angle_changed(self, context):
    from .models import find_table

    table = find_table(context.scene)
    if table is not None:
        table.rotation_euler[2] = self.table_angle


class ScannerSettings(bpy.types.PropertyGroup):
    # -- cell ----------------------------------------------------------------------
    robot: EnumProperty(name="Robot", items=ROBOT_ITEMS, default=ROBOT_ITEMS[0][0],
                        description="Robot rig: a DH table with joint limits")
    robot_file: StringProperty(name="Robot file", subtype="FILE_PATH", description="Robot rig file (TOML)")
    probe: EnumProperty(name="Probe", items=PROBE_ITEMS, default="default",
                        description="Probe rig: laser, cameras and mount; its optics are edited below")
    probe_file: StringProperty(name="Probe file", subtype="FILE_PATH", description="Probe rig file (TOML)")
    workpiece: EnumProperty(name="Workpiece", items=WORKPIECE_ITEMS, default="sphere")
    workpiece_file: StringProperty(name="Mesh file", subtype="FILE_PATH", description="Workpiece mesh")
    laser: EnumProperty(name="Laser", items=[("gobo", "Gobo (Cycles)", "Spot light with a Gaussian slit gobo"),
                                             ("slit", "Slit (Cycles, Eevee)", "Point light behind a slit, as in the paper")],
                        default="gobo")
    # -- Cartesian target ------------------------------------------------------------
    target_location: FloatVectorProperty(name="Position (mm)", size=3, default=(20.0, -10.0, 150.0),
                                         description="Tool position in mm, relative to the chosen frame")
    target_rotation: FloatVectorProperty(name="YZZ' angles", size=3, subtype="EULER", default=(0.0, math.pi, 0.0),
                                         description="Tool orientation: yaw, pitch, roll (YZZ' Euler angles)")
    target_frame: EnumProperty(name="Relative to", items=[("base", "Robot base", "Robot base frame 0"),
                                                          ("table", "Rotary table", "Table (workpiece) frame")],
                               default="table")
    tool_location: FloatVectorProperty(name="Tool offset (mm)", size=3, default=(0.0, 0.0, 0.0),
                                       description="Tool point in the probe frame, mm (e.g. 0, 0, 160: mid-range)")
    tool_rotation: FloatVectorProperty(name="Tool angles", size=3, subtype="EULER", default=(0.0, 0.0, 0.0),
                                       description="Tool orientation in the probe frame (YZZ')")
    # -- probe optics ----------------------------------------------------------------
    probe_a: FloatProperty(name="a (mm)", default=60.0, min=0.001, soft_max=500.0,
                           description="Each camera's distance from the laser plane")
    probe_b: FloatProperty(name="b (mm)", default=0.0, soft_min=-200.0, soft_max=200.0,
                           description="Camera offset along the beam")
    probe_phi: FloatProperty(name="phi", subtype="ANGLE", default=math.radians(27.0485), min=0.0,
                             max=math.pi / 2, description="Angle between the beam and each camera's axis")
    probe_gamma: FloatProperty(name="gamma", subtype="ANGLE", default=math.radians(13.5528), min=0.0,
                               max=math.pi / 2, description="Half field of view along the triangulation direction")
    probe_rows: IntProperty(name="Rows", default=160, min=2, max=100000,
                            description="Sensor rows (H), along the triangulation direction")
    probe_cols: IntProperty(name="Columns", default=160, min=2, max=100000,
                            description="Sensor columns (W), along the laser line")
    # -- table ------------------------------------------------------------------------
    table_angle: FloatProperty(name="Table angle", subtype="ANGLE", default=0.0, update=_table_angle_changed,
                               description="Rotary table angle theta_R")
    # -- scan -------------------------------------------------------------------------
    scan_config: EnumProperty(name="Scan", items=SCENE_ITEMS, default="demo", description="Scan config")
    scan_file: StringProperty(name="Scan file", subtype="FILE_PATH", description="Scan config file (TOML)")
    output_dir: StringProperty(name="Output", subtype="DIR_PATH", default="",
                               description="Folder for cloud.ply, report.json, preview.png (empty: the "
                                           "extension's user folder)")
    import_cloud: BoolProperty(name="Import cloud", default=True, description="Bring the cloud into the scene")


CLASSES = (ScannerSettings,)
