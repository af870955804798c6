"""The Scanner panel in the 3D View's sidebar (tab "Scanner")."""

from __future__ import annotations

import bpy
import numpy as np

from ..core.errors import ScannerError
from . import models


class _ScannerPanel:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Scanner"


class SCANNER_PT_cell(_ScannerPanel, bpy.types.Panel):
    bl_label = "Scanner Cell"

    def draw(self, context):
        s = context.scene.scanner
        col = self.layout.column()
        for prop, file_prop in (("robot", "robot_file"), ("probe", "probe_file"), ("workpiece", "workpiece_file")):
            col.prop(s, prop)
            if getattr(s, prop) == "FILE":
                col.prop(s, file_prop, text="")
                if prop == "workpiece":
                    col.prop(s, "workpiece_scale")
            if prop == "robot":  # where the table stands from this robot
                row = col.row(align=True)
                row.prop(s, "table_a_mm", text="Table a_R")
                row.prop(s, "table_d_mm", text="d_R")
        col.prop(s, "material")
        if s.material == "glossy":
            col.prop(s, "roughness")
        col.prop(s, "laser")
        col.operator("scanner.build_cell", icon="OUTLINER_COLLECTION")


class SCANNER_PT_joints(_ScannerPanel, bpy.types.Panel):
    bl_label = "Joints"
    bl_parent_id = "SCANNER_PT_cell"

    def draw(self, context):
        robot = models.find_robot(context.scene)
        if robot is None:
            self.layout.label(text="Build the cell first", icon="INFO")
            return
        col = self.layout.column(align=True)
        for k in range(1, 7):
            col.prop(robot, f'["q{k}"]', text=f"J{k}", slider=True)
        try:
            mismatch = models.cell_mismatch(context)
        except ScannerError:
            mismatch = None  # the choices cannot be read: their own boxes say why
        if mismatch is not None:
            self.layout.label(text="Build Cell again: the choices above changed", icon="ERROR")
            return
        found = models.clearance_readout(context)
        if found is not None:
            distance, a, b, colliding = found
            row = self.layout.row()
            row.alert = colliding  # drawn in red
            text = (f"Outside {b}: {a}" if distance != distance else  # NaN: joints beyond their limits
                    f"Collision: {a} and {b}" if colliding and distance <= 0 else
                    f"Too near: {a} {distance:.1f} mm from {b}" if colliding else
                    f"Clearance {distance:.1f} mm ({a} to {b})")
            row.label(text=text, icon="ERROR" if colliding else "CHECKMARK")


class SCANNER_PT_cartesian(_ScannerPanel, bpy.types.Panel):
    bl_label = "Cartesian"
    bl_parent_id = "SCANNER_PT_cell"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        s = context.scene.scanner
        col = self.layout.column()
        col.prop(s, "target_frame")
        col.prop(s, "target_location")
        col.prop(s, "target_rotation")
        col.prop(s, "tool_location")
        col.prop(s, "tool_rotation")
        col.operator("scanner.go", icon="CON_KINEMATIC")


class SCANNER_PT_probe(_ScannerPanel, bpy.types.Panel):
    bl_label = "Probe"
    bl_parent_id = "SCANNER_PT_cell"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        s = context.scene.scanner
        col = self.layout.column(align=True)
        for prop in ("probe_a", "probe_b", "probe_phi", "probe_gamma", "probe_rows", "probe_cols"):
            col.prop(s, prop)
        col.operator("scanner.load_probe", icon="IMPORT")
        box = self.layout.box()
        try:
            p = models.probe_from(s)
        except ScannerError as exc:
            box.alert = True
            for line in _wrap(str(exc), 46):
                box.label(text=line)
            return
        z0, z1 = p.z_range_mm
        l0, l1 = p.line_lengths_mm()
        box.label(text=f"Measuring range: {z0:.1f} to {z1:.1f} mm (Eq. 7)")
        box.label(text=f"Line length: {l0:.1f} mm near, {l1:.1f} mm far")
        box.label(text=f"f = {p.f_px:.1f} px; rebuild the cell to apply")


class SCANNER_PT_sensor(_ScannerPanel, bpy.types.Panel):
    bl_label = "Sensor Realism"
    bl_parent_id = "SCANNER_PT_probe"
    bl_options = {"DEFAULT_CLOSED"}

    def draw_header(self, context):
        self.layout.prop(context.scene.scanner, "sensor_realistic", text="")

    def draw(self, context):
        s = context.scene.scanner
        layout = self.layout
        layout.active = s.sensor_realistic
        col = layout.column(heading="Effects", align=True)
        for prop in ("sensor_integrate_pixels", "sensor_saturate", "sensor_noise", "sensor_speckle",
                     "sensor_defocus", "sensor_motion_blur", "sensor_distortion"):
            col.prop(s, prop)
        if s.sensor_distortion:
            row = layout.row(align=True)
            row.prop(s, "sensor_k1")
            row.prop(s, "sensor_k2")
            layout.prop(s, "sensor_undistort")
        col = layout.column(align=True)
        col.prop(s, "sensor_auto_exposure")
        col.prop(s, "sensor_target_peak" if s.sensor_auto_exposure else "sensor_exposure_ms")
        col.prop(s, "sensor_gain")
        col.prop(s, "sensor_bit_depth")
        col = layout.column(align=True)
        col.prop(s, "sensor_f_number")
        col.prop(s, "sensor_focus_mm")
        col.prop(s, "sensor_seed")
        layout.prop(s, "ambient")
        if not s.sensor_realistic:
            return
        try:
            sensor = models.sensor_from(s)
            probe = models.probe_from(s)
            ends = sensor.row_depths_mm(probe, np.array([probe.rows_px - 1.0, 0.0]))
            near, far = sensor.blur_sigma_px(probe, ends)
            grain = float(sensor.speckle_grain_px(probe, ends.mean()))
        except ScannerError as exc:
            box = layout.box()
            box.alert = True
            for line in _wrap(str(exc), 46):
                box.label(text=line)
            return
        box = layout.box()
        box.label(text=f"Lens: f = {sensor.focal_mm(probe):.1f} mm, pixels {sensor.pitch_um(probe):.1f} um")
        box.label(text=f"Speckle grain: {grain:.2f} px")
        box.label(text=f"Defocus sigma: {near:.2f} px near, {far:.2f} px far")
        box.label(text=f"In focus at {sensor.focus_depth_mm(probe):.0f} mm")


class SCANNER_PT_table(_ScannerPanel, bpy.types.Panel):
    bl_label = "Table"
    bl_parent_id = "SCANNER_PT_cell"

    def draw(self, context):
        self.layout.prop(context.scene.scanner, "table_angle")


class SCANNER_PT_views(_ScannerPanel, bpy.types.Panel):
    bl_label = "Probe Views"
    bl_parent_id = "SCANNER_PT_cell"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        self.layout.operator("scanner.render_views", icon="RENDER_STILL")


class SCANNER_PT_scan(_ScannerPanel, bpy.types.Panel):
    bl_label = "Scan"

    def draw(self, context):
        s = context.scene.scanner
        col = self.layout.column()
        col.prop(s, "scan_config")
        if s.scan_config == "FILE":
            col.prop(s, "scan_file", text="")
        col.prop(s, "output_dir")
        col.prop(s, "scan_sensor")
        col.prop(s, "scan_engine")
        col.prop(s, "scan_frames")
        col.prop(s, "adaptive_budget")
        col.prop(s, "import_cloud")
        col.operator("scanner.scan", icon="PLAY")
        col.operator("scanner.adaptive", icon="VIEWZOOM")
        col.operator("scanner.export_ply", icon="EXPORT")
        col.operator("scanner.calibrate", icon="CAMERA_DATA")
        from ..scene.cloud_object import error_scale_um

        top = error_scale_um(models.cell_object(models.CLOUD_NAME, scene=context.scene))
        if top is not None:  # the cloud's colours: one scan's scale, so say it
            col.label(text=f"Cloud colour: error 0 µm (blue) to {top:.1f} µm (red) and more", icon="COLOR")


def _wrap(text: str, width: int) -> list[str]:
    words, lines, line = text.split(), [], ""
    for w in words:
        if len(line) + len(w) + 1 > width and line:
            lines.append(line)
            line = w
        else:
            line = f"{line} {w}".strip()
    return lines + ([line] if line else [])


CLASSES = (SCANNER_PT_cell, SCANNER_PT_joints, SCANNER_PT_cartesian, SCANNER_PT_probe, SCANNER_PT_sensor,
           SCANNER_PT_table, SCANNER_PT_views, SCANNER_PT_scan)
