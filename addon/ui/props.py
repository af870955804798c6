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

from ..core.config.toml import available_rigs
from ..core.config.scan import MATERIALS
from ..core.config.rigs import load_probe
from ..core.config.scan import MAX_PROFILES
from ..core.optics.probe import MAX_PIXELS, MIN_PIXELS
from ..core.optics.sensor import BIT_DEPTHS, SensorModel
from ..core.geometry.workpiece import BUILTINS
from ..core.kinematics.turntable import PAPER_A_R_MM, PAPER_D_R_MM

FILE = "FILE"


def _rig_items(kind: str, label: str):
    return [(n, n.replace("_", " "), f"Bundled {label}") for n in available_rigs(kind)] + [
        (FILE, "File...", f"A {label} file (TOML) chosen below")]


_SENSOR = SensorModel()  # the panel's defaults are the core's
_PROBE = load_probe("default")  # (rigs/probes/default.toml)


# Enum items are built once: Blender keeps pointers to these strings.
ROBOT_ITEMS = _rig_items("robots", "robot rig")
PROBE_ITEMS = _rig_items("probes", "probe rig")
CELL = "CELL"  # the scan source that is the Cell panel's own cell
SCENE_ITEMS = _rig_items("scenes", "scan config")
# Appended, not inserted: Blender saves an enum's choice by its number, so the bundled
# configs and File... keep theirs in .blend files saved before this item was added.
SCENE_ITEMS.append((CELL, "The Cell Built Here", "The Cell panel's robot, probe, workpiece and material, "
                       "scanned along a path laid out for the part: a table turn from above, two from 45° at "
                       "its side, a sweep across it (as bench parts does)"))
MATERIAL_ITEMS = [(m, m.title(), f"{m.title()} surface") for m in MATERIALS]
BIT_DEPTH_ITEMS = [(str(b), f"{b} bit", f"{b}-bit analogue-to-digital converter") for b in BIT_DEPTHS]
WORKPIECE_ITEMS = [(k, k.replace("_", " ").title(), f"Built-in {k.replace('_', ' ')} with exact ground truth")
                   for k in BUILTINS] + [(FILE, "Mesh file...", "STL, OBJ, PLY or GLB (mm; GLB in metres)")]


# Paths may be //-relative to the saved .blend file (the operators resolve them with bpy.path.abspath).
BLEND_RELATIVE = {"PATH_SUPPORTS_BLEND_RELATIVE"}


def _table_angle_changed(self, context):
    from ..scene.cell import cell_object

    # This scene's cell only (the angle set in another scene turned this one's table)
    table = cell_object("Turntable", scene=self.id_data)
    if table is not None and math.isfinite(self.table_angle):  # NaN is refused by the operators, never shown
        table.rotation_euler[2] = self.table_angle


def _probe_changed(self, context):
    """A probe chosen in the list (or its file) brings its optics into the fields below, as
    Load from Rig does: the list's choice is what Build Cell then builds. A file that cannot
    be read leaves them as they were (Build Cell says why)."""
    from ..core.errors import ScannerError
    from . import models

    try:
        models.show_probe_optics(self, models.chosen_probe_rig(self))
    except (ScannerError, OSError):
        pass


class ScannerSettings(bpy.types.PropertyGroup):
    # -- cell ----------------------------------------------------------------------
    robot: EnumProperty(name="Robot", items=ROBOT_ITEMS, default=ROBOT_ITEMS[0][0],
                        description="Robot rig: a DH table with joint limits")
    robot_file: StringProperty(name="Robot file", subtype="FILE_PATH", options=BLEND_RELATIVE,
                               description="Robot file: a rig (TOML, a DH table) or a URDF")
    table_a_mm: FloatProperty(name="Table a_R (mm)", default=PAPER_A_R_MM, min=-10000.0, max=10000.0,
                              soft_min=-3000.0, soft_max=3000.0,
                              description="The turntable's axis from the robot base's, along the base's x (Eq. 4's "
                                          "a_R; a gantry's table stands under it at 0)")
    table_d_mm: FloatProperty(name="Table d_R (mm)", default=PAPER_D_R_MM, min=-10000.0, max=10000.0,
                              soft_min=-3000.0, soft_max=3000.0,
                              description="The table top's height from the robot base's origin (Eq. 4's d_R)")
    probe: EnumProperty(name="Probe", items=PROBE_ITEMS, default="default", update=_probe_changed,
                        description="Probe rig: laser, cameras and mount; choosing one loads its optics into "
                                    "the fields below, where they can be edited")
    probe_file: StringProperty(name="Probe file", subtype="FILE_PATH", options=BLEND_RELATIVE,
                               description="Probe rig file (TOML)",
                               update=_probe_changed)
    workpiece: EnumProperty(name="Workpiece", items=WORKPIECE_ITEMS, default="sphere")
    workpiece_file: StringProperty(name="Mesh file", subtype="FILE_PATH", options=BLEND_RELATIVE,
                                   description="Workpiece mesh")
    workpiece_scale: FloatProperty(name="Scale", default=0.0, min=0.0, soft_max=1000.0,
                                   description="Millimetres per unit of the mesh file: 1 for a file in mm, 1000 "
                                               "for one in metres (Blender's own STL/OBJ export), 25.4 for "
                                               "inches; 0: by the format (mm, glTF/GLB in metres)")
    material: EnumProperty(name="Material", items=MATERIAL_ITEMS, default="grey",
                           description="Workpiece surface; glossy and mirror need render bounces to show reflections")
    roughness: FloatProperty(name="Roughness", default=0.2, min=0.0, max=1.0,
                             description="Glossy surface roughness (0: mirror-like)")
    laser: EnumProperty(name="Laser", items=[("gobo", "Gobo (Cycles)", "Spot light with a Gaussian slit gobo"),
                                             ("spot", "Spots (Eevee)",
                                              "The gobo's Gaussian line from five squeezed spot lights, for Eevee "
                                              "(Cycles renders it as noise: it samples one light per path)"),
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
    probe_a: FloatProperty(name="Baseline a (mm)", default=_PROBE.a_mm, min=0.001, soft_max=500.0,
                           description="Each camera's distance from the laser plane")
    probe_b: FloatProperty(name="Offset b (mm)", default=_PROBE.b_mm, soft_min=-200.0, soft_max=200.0,
                           description="Camera offset along the beam")
    probe_phi: FloatProperty(name="Camera angle φ", subtype="ANGLE", default=_PROBE.phi_rad, min=0.0,
                             max=math.pi / 2, description="Angle between the beam and each camera's axis")
    probe_gamma: FloatProperty(name="Half view γ", subtype="ANGLE", default=_PROBE.gamma_rad, min=0.0,
                               max=math.pi / 2, description="Half field of view along the triangulation direction")
    probe_rows: IntProperty(name="Rows", default=_PROBE.rows_px, min=MIN_PIXELS, max=MAX_PIXELS,
                            description="Sensor rows (H), along the triangulation direction")
    probe_cols: IntProperty(name="Columns", default=_PROBE.cols_px, min=MIN_PIXELS, max=MAX_PIXELS,
                            description="Sensor columns (W), along the laser line")
    # -- sensor realism (off: the ideal sensor of the paper) --------------------------
    sensor_realistic: BoolProperty(name="Realistic sensor", default=False,
                                   description="Apply the sensor effects ticked below to the probe views "
                                               "(and to scans, when the scan uses the panel's sensor)")
    sensor_integrate_pixels: BoolProperty(name="Pixel integration", default=False,
                                          description="Integrate light over each pixel's area (box filter)")
    sensor_saturate: BoolProperty(name="Exposure and saturation", default=False,
                                  description="Exposure, gain, full-well clipping and quantisation")
    sensor_noise: BoolProperty(name="Noise", default=False,
                               description="Shot noise, read noise, dark offset, fixed-pattern gain")
    sensor_speckle: BoolProperty(name="Laser speckle", default=False,
                                 description="Multiplicative speckle; grain size from aperture and wavelength")
    sensor_defocus: BoolProperty(name="Defocus", default=False,
                                 description="Blur from the lens aperture, by depth along the range")
    sensor_motion_blur: BoolProperty(name="Motion blur", default=False,
                                     description="The probe keeps moving while the shutter is open (scans)")
    sensor_distortion: BoolProperty(name="Lens distortion", default=False,
                                    description="Brown-Conrady radial distortion (removed by calibration)")
    sensor_k1: FloatProperty(name="k1", default=-0.1, min=-10.0, max=10.0, soft_min=-1.0, soft_max=1.0,
                             description="Radial k1 (within ±10, as a config's)")
    sensor_k2: FloatProperty(name="k2", default=0.0, min=-10.0, max=10.0, soft_min=-1.0, soft_max=1.0,
                             description="Radial k2 (within ±10, as a config's)")
    sensor_undistort: BoolProperty(name="Calibrated", default=True,
                                   description="Detections are undistorted before triangulation")
    sensor_exposure_ms: FloatProperty(name="Exposure (ms)", default=_SENSOR.exposure_ms, min=1e-4, max=1e7,
                                      soft_max=20.0)
    sensor_auto_exposure: BoolProperty(name="Auto-exposure", default=_SENSOR.auto_exposure,
                                       description="Set the exposure so the line peak sits at the target level")
    sensor_target_peak: FloatProperty(name="Target peak", default=_SENSOR.target_peak, min=0.01, max=1.0,
                                      subtype="FACTOR", description="Auto-exposure: peak as a fraction of full scale")
    sensor_gain: FloatProperty(name="Gain", default=_SENSOR.gain, min=1e-3, max=1e7, soft_max=16.0)
    sensor_bit_depth: EnumProperty(name="Bit depth", items=BIT_DEPTH_ITEMS, default=str(_SENSOR.bit_depth))
    sensor_f_number: FloatProperty(name="f-number", default=_SENSOR.f_number, min=0.5, max=1e7, soft_max=32.0,
                                   description="Lens aperture: sets defocus and speckle grain")
    sensor_focus_mm: FloatProperty(name="Focus (mm)", default=0.0, min=0.0, max=1e7, soft_max=1000.0,
                                   description="Depth in focus along the camera axis (0: balanced over the "
                                               "probe's range)")
    sensor_seed: IntProperty(name="Seed", default=_SENSOR.seed, min=0, description="Noise and speckle seed")
    ambient: FloatProperty(name="Ambient light", default=0.08, min=0.0, max=100.0, soft_max=1.0,
                           description="Ambient light level in the probe views (fraction of the laser's full scale)")
    # -- table ------------------------------------------------------------------------
    table_angle: FloatProperty(name="Table angle", subtype="ANGLE", default=0.0, update=_table_angle_changed,
                               description="Rotary table angle theta_R")
    # -- scan -------------------------------------------------------------------------
    scan_config: EnumProperty(name="Scan", items=SCENE_ITEMS, default="demo", description="Scan config")
    scan_file: StringProperty(name="Scan file", subtype="FILE_PATH", options=BLEND_RELATIVE,
                              description="Scan config file (TOML)")
    output_dir: StringProperty(name="Output", subtype="DIR_PATH", options=BLEND_RELATIVE, default="",
                               description="Folder for cloud.ply, report.json, preview.png (empty: the "
                                           "extension's user folder, which Blender deletes with the "
                                           "extension when it is uninstalled)")
    scan_sensor: EnumProperty(name="Sensor", items=[
        ("CONFIG", "From the scan config", "Use the scan config's [sensor] table and material"),
        ("PANEL", "From the probe panel", "Use the probe panel's realistic sensor, material and ambient light")],
        default="CONFIG")
    import_cloud: BoolProperty(name="Import cloud", default=True, description="Bring the cloud into the scene")
    scan_engine: EnumProperty(name="Engine", items=[
        ("CONFIG", "From the scan config", "Render with the scan config's [render] engine"),
        ("cycles", "Cycles", "Path-traced laser line: the reference (slowest)"),
        ("eevee", "Eevee", "Rasterised laser line (fast with a GPU, software OpenGL without one)"),
        ("raycast", "Raycast", "Cycles' ideal image by Embree without Blender's renderer: fastest, ideal sensor "
                               "and grey or white surfaces only")],
        default="CONFIG")
    scan_frames: StringProperty(name="Frames", default="",
                                description="Part of the config's path for Scan, as A:B or A:B:STEP "
                                            "(frames from 0; empty: the whole path)")
    adaptive_budget: IntProperty(name="Profile Budget", default=0, min=0, max=MAX_PROFILES,
                                 description="Profiles Adaptive Scan may take (0: the config's [adaptive] budget)")


CLASSES = (ScannerSettings,)
