"""The rotary table (T_R^0 of Eq. 5, turning about its Z by θ_R) and the workpiece it carries."""

from __future__ import annotations

import bpy
import numpy as np
import trimesh

from ..core.turntable import Turntable
from ..core.workpiece import Workpiece
from .materials import diffuse
from .meshes import mesh_object
from .units import to_blender

TABLE_RADIUS_MM = 150.0
TABLE_THICKNESS_MM = 20.0


def add_turntable(collection, table: Turntable) -> bpy.types.Object:
    """A disc whose top face is the table frame's z = 0, placed at T_R^0(0); θ_R is its Z rotation."""
    disc = trimesh.creation.cylinder(radius=TABLE_RADIUS_MM, height=TABLE_THICKNESS_MM, sections=128)
    disc.apply_translation([0.0, 0.0, -TABLE_THICKNESS_MM / 2])
    obj = mesh_object("Turntable", disc, collection, diffuse("Table top", (0.35, 0.35, 0.37)))
    obj.rotation_mode = "XYZ"
    obj.matrix_world = to_blender(table.table2base(0.0))
    return obj


def set_table_angle(obj: bpy.types.Object, theta_rad: float) -> None:
    obj.rotation_euler[2] = float(theta_rad)


def add_workpiece(collection, workpiece: Workpiece, table_obj: bpy.types.Object) -> bpy.types.Object:
    """The workpiece mesh (already in table coordinates) as a child of the table, grey and diffuse."""
    obj = mesh_object(f"Workpiece {workpiece.name}", workpiece.mesh, collection, diffuse("Grey workpiece"))
    obj.parent = table_obj
    obj.matrix_parent_inverse.identity()
    obj.matrix_basis = to_blender(np.eye(4))
    obj["source"] = workpiece.source
    return obj
