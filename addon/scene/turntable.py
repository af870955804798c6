"""The rotary table (T_R^0 of Eq. 5, turning about its Z by θ_R) and the workpiece it carries."""

from __future__ import annotations

import bpy
import numpy as np

from ..core.kinematics.turntable import Turntable, table_top_mesh
from ..core.geometry.workpiece import Workpiece, drawn_mesh
from ..core.optics.surfaces import FIXTURE, TABLE_TOP
from .materials import diffuse, surface
from .meshes import mesh_object
from .units import to_blender


def add_turntable(collection, table: Turntable) -> bpy.types.Object:
    """A disc whose top face is the table frame's z = 0, placed at T_R^0(0); θ_R is its Z rotation."""
    obj = mesh_object("Turntable", table_top_mesh(), collection, diffuse("Table top", TABLE_TOP))
    obj.rotation_mode = "XYZ"
    obj.matrix_world = to_blender(table.table2base(0.0))
    return obj


def set_table_angle(obj: bpy.types.Object, theta_rad: float) -> None:
    obj.rotation_euler[2] = float(theta_rad)


def add_fixture(collection, fixture, table_obj: bpy.types.Object) -> bpy.types.Object:
    """A table fixture (``core.safety.Fixture``, mesh in table coordinates) as a child of the
    table, diffuse grey: rendered with the part, so it hides and shadows it as on a real table.
    It has an instance twin, as the part has."""
    obj = mesh_object(fixture.name[:1].upper() + fixture.name[1:], fixture.mesh, collection,
                      diffuse("Scanner fixture", FIXTURE))
    obj.parent = table_obj
    obj.matrix_parent_inverse.identity()
    obj.matrix_basis = to_blender(np.eye(4))
    _add_twin(collection, obj)
    return obj


TWIN_OFFSET_M = (0.0, 0.0, -1000.0)  # a kilometre below the cell: outside every view


def add_workpiece(collection, workpiece: Workpiece, table_obj: bpy.types.Object, material: str = "grey",
                  roughness: float = 0.2) -> bpy.types.Object:
    """The workpiece mesh (already in table coordinates) as a child of the table, grey and diffuse.

    A second object shares its mesh, far outside every view. Cycles bakes the
    transform of a mesh used once into its vertices and then rebuilds that mesh's
    acceleration structure whenever anything in the scene moves, every frame of a
    scan (18 ms per frame for an 82k-face sphere); a mesh with two users keeps its
    own structure, built once (6 ms per frame). The twin is never hit by a ray.
    """
    drawn = drawn_mesh(workpiece)  # without faces lying in the table top, which the table draws
    obj = mesh_object(f"Workpiece {workpiece.name}", workpiece.mesh if drawn is None else drawn, collection,
                      surface(material, roughness))
    obj.hide_render = drawn is None  # a sheet lying flat on the table: shown, but the table is what renders
    obj.parent = table_obj
    obj.matrix_parent_inverse.identity()
    obj.matrix_basis = to_blender(np.eye(4))
    obj["source"] = workpiece.source
    _add_twin(collection, obj)
    return obj


def _add_twin(collection, obj: bpy.types.Object) -> None:
    """A second user of ``obj``'s mesh, out of every view (see :func:`add_workpiece`)."""
    twin = bpy.data.objects.new(f"{obj.name} (instance twin)", obj.data)
    collection.objects.link(twin)
    twin.location = TWIN_OFFSET_M
    twin.hide_viewport = True
    twin.hide_select = True
    twin["purpose"] = (f"a second user of {obj.name}'s mesh, out of every view: Cycles then builds its ray "
                       "structure once per scan instead of every frame")
