"""Point clouds as Blender objects: import (shown as points, coloured by error) and read back.

The cloud becomes a mesh of loose vertices in the table frame, parented to the
turntable so it stays on the part when the table turns. Per-point attributes:
``frame`` and ``camera`` (int), ``quality`` and ``error_um`` (float: the distance to what the
point counts as, the part, the table or a fixture) and
``error_colour`` (colour). A small Geometry Nodes modifier turns the vertices
into points (drawn in the viewport, rendered by Cycles as spheres) and gives
them a material that shows ``error_colour``.
"""

from __future__ import annotations

import bpy
import numpy as np

from ..core.geometry.cloud import Cloud
from ..core.scan.preview import FIXTURE_BGR
from .materials import bare_material
from .ownership import mark
from .units import M_PER_MM

CLOUD_ROLE = "Scan cloud"  # the role (ownership.mark) of a scan cloud brought into the scene
POINT_RADIUS_MM = 0.35
_TURBO = None


def _turbo(t: np.ndarray) -> np.ndarray:
    """Colour map (the Turbo palette, as OpenCV ships it) for t in [0, 1] -> (n, 3) linear-ish RGB."""
    global _TURBO
    if _TURBO is None:
        import cv2

        lut = cv2.applyColorMap(np.arange(256, dtype=np.uint8).reshape(-1, 1), cv2.COLORMAP_TURBO).reshape(256, 3)
        _TURBO = (lut[:, ::-1].astype(np.float32) / 255.0) ** 2.2  # BGR sRGB -> RGB linear
    return _TURBO[np.clip(np.round(t * 255), 0, 255).astype(int)]


def _points_modifier(obj: bpy.types.Object, material: bpy.types.Material, radius_mm: float) -> None:
    tree = bpy.data.node_groups.get("Scanner cloud points")
    if tree is None:
        tree = bpy.data.node_groups.new("Scanner cloud points", "GeometryNodeTree")
        tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
        tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
        nin = tree.nodes.new("NodeGroupInput")
        nout = tree.nodes.new("NodeGroupOutput")
        to_points = tree.nodes.new("GeometryNodeMeshToPoints")
        to_points.inputs["Radius"].default_value = radius_mm * M_PER_MM
        set_mat = tree.nodes.new("GeometryNodeSetMaterial")
        set_mat.inputs["Material"].default_value = material
        tree.links.new(nin.outputs[0], to_points.inputs["Mesh"])
        tree.links.new(to_points.outputs["Points"], set_mat.inputs["Geometry"])
        tree.links.new(set_mat.outputs["Geometry"], nout.inputs[0])
    # The material each time (deleted and made again, the group kept pointing at nothing, and
    # later clouds came without colours)
    for node in tree.nodes:
        if node.bl_idname == "GeometryNodeSetMaterial":
            node.inputs["Material"].default_value = material
    mod = obj.modifiers.new("Points", "NODES")
    mod.node_group = tree


def _cloud_material() -> bpy.types.Material:
    mat = bpy.data.materials.get("Scanner cloud")
    if mat is not None:
        return mat
    mat, out = bare_material("Scanner cloud")
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    attr = nodes.new("ShaderNodeAttribute")
    attr.attribute_type = "GEOMETRY"
    attr.attribute_name = "error_colour"
    emit = nodes.new("ShaderNodeEmission")
    emit.inputs["Strength"].default_value = 1.0
    links.new(attr.outputs["Color"], emit.inputs["Color"])
    links.new(emit.outputs["Emission"], out.inputs["Surface"])
    return mat


# Points on the table's fixtures: preview.png's colour for them (sRGB BGR there), made linear
# as the error colours are (_turbo), so that Blender shows the same colour.
FIXTURE_RGB = (np.array(FIXTURE_BGR[::-1], np.float32) / 255.0) ** 2.2

# Custom property of an imported cloud's mesh: the error (µm) its colour scale reaches red at.
ERROR_SCALE_KEY = "error_scale_um"


def error_scale_um(obj) -> float | None:
    """The error (µm) an imported cloud's colours reach red at (blue: 0); None: no error shown."""
    value = obj.data.get(ERROR_SCALE_KEY) if obj is not None and obj.type == "MESH" else None
    return float(value) if value is not None else None


def import_cloud(collection, cloud: Cloud, parent: bpy.types.Object | None, error_um: np.ndarray | None = None,
                 name: str = "Scan cloud", radius_mm: float = POINT_RADIUS_MM,
                 on_part: np.ndarray | None = None, on_fixture: np.ndarray | None = None) -> bpy.types.Object:
    """A cloud (table frame, mm) as a points object under ``parent`` (the turntable).

    Points are coloured by ``error_um`` where ``on_part`` (default: all), from blue (0) to red
    at the part's 95th percentile (kept as the mesh's ``error_scale_um``); those ``on_fixture``
    (the table's clamps and stands) in preview.png's colour for them; the rest (the table) grey.
    """
    n = len(cloud)
    me = bpy.data.meshes.new(name)
    me.vertices.add(n)
    me.vertices.foreach_set("co", (cloud.points * M_PER_MM).astype(np.float32).ravel())
    for attr, data, kind in (("frame", cloud.frame, "INT"), ("camera", cloud.camera.astype(np.int32), "INT"),
                             ("quality", cloud.quality, "FLOAT")):
        a = me.attributes.new(attr, kind, "POINT")
        a.data.foreach_set("value", np.asarray(data))
    colour = np.tile(np.array([0.6, 0.6, 0.6], np.float32), (n, 1))
    if error_um is not None and n:
        err = np.asarray(error_um, dtype=np.float32)
        a = me.attributes.new("error_um", "FLOAT", "POINT")
        a.data.foreach_set("value", err)
        part = np.ones(n, bool) if on_part is None else np.asarray(on_part, bool)
        if part.any():
            top = max(float(np.percentile(err[part], 95)), 1e-6)
            colour[part] = _turbo(err[part] / top)
            me[ERROR_SCALE_KEY] = top  # the colour scale's red end, for the panel's legend
    if on_fixture is not None and n:
        colour[np.asarray(on_fixture, bool)] = FIXTURE_RGB
    rgba = np.column_stack([colour, np.ones(n, np.float32)])
    c = me.color_attributes.new("error_colour", "FLOAT_COLOR", "POINT")
    c.data.foreach_set("color", rgba.ravel())
    me.update()
    obj = mark(bpy.data.objects.new(name, me), CLOUD_ROLE)  # the cell's: a rebuilt cell drops it
    collection.objects.link(obj)
    if parent is not None:
        obj.parent = parent
        obj.matrix_parent_inverse.identity()
    _points_modifier(obj, _cloud_material(), radius_mm)
    return obj


def cloud_from_object(obj: bpy.types.Object) -> Cloud:
    """Read an imported cloud back (table frame, mm), e.g. for PLY export: as the user sees it,
    points deleted in Edit Mode included (the mesh's data there is the edit's, which Blender
    writes back only on leaving it: an export in Edit Mode failed with a traceback)."""
    if obj.mode == "EDIT":
        return _cloud_in_edit_mode(obj)
    me = obj.data
    n = len(me.vertices)
    co = np.empty(n * 3, np.float32)
    me.vertices.foreach_get("co", co)

    def attr(name, dtype):
        a = me.attributes.get(name)
        out = np.zeros(n, dtype)
        if a is not None and a.domain == "POINT" and len(a.data) == n:
            a.data.foreach_get("value", out)
        return out

    return Cloud(co.reshape(-1, 3).astype(np.float64) / M_PER_MM, attr("frame", np.int32), attr("camera", np.int32),
                 attr("quality", np.float32))


def _cloud_in_edit_mode(obj: bpy.types.Object) -> Cloud:
    """The cloud of an object in Edit Mode, from its edit mesh (the mesh's own attributes read
    empty there until Blender leaves the mode)."""
    import bmesh

    bm = bmesh.from_edit_mesh(obj.data)
    n = len(bm.verts)
    co = np.array([v.co[:] for v in bm.verts], dtype=np.float64).reshape(n, 3)

    def attr(layers, name, dtype):
        layer = layers.get(name)
        return (np.array([v[layer] for v in bm.verts], dtype=dtype) if layer is not None
                else np.zeros(n, dtype))

    return Cloud(co / M_PER_MM, attr(bm.verts.layers.int, "frame", np.int32),
                 attr(bm.verts.layers.int, "camera", np.int32), attr(bm.verts.layers.float, "quality", np.float32))
