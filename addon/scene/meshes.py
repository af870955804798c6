"""trimesh meshes (mm) -> Blender mesh objects (m), built with bulk array copies."""

from __future__ import annotations

import math

import bpy
import numpy as np
import trimesh

from ..core.optics.surfaces import SHARP_EDGE_DEG
from .units import M_PER_MM


def mesh_data(name: str, mesh: trimesh.Trimesh) -> bpy.types.Mesh:
    v = (np.asarray(mesh.vertices, dtype=np.float64) * M_PER_MM).astype(np.float32)
    f = np.asarray(mesh.faces, dtype=np.int32)
    me = bpy.data.meshes.new(name)
    me.vertices.add(len(v))
    me.vertices.foreach_set("co", v.ravel())
    me.loops.add(f.size)
    me.loops.foreach_set("vertex_index", f.ravel())
    me.polygons.add(len(f))
    me.polygons.foreach_set("loop_start", np.arange(0, f.size, 3, dtype=np.int32))
    me.update()
    # Faces added this way are smooth-shaded (no "sharp_face" attribute) and trimesh shares
    # vertices across edges: every face of a box would be shaded with its corners' averaged
    # normals, tilted by up to 55°, lighting faces the laser cannot reach and dimming others,
    # as Cycles treats light between shading and true normal (5.0 and 5.2 differently).
    # Creases stay sharp; the fine mesh of a curved part stays smooth.
    me.set_sharp_from_angle(angle=math.radians(SHARP_EDGE_DEG))
    return me


def mesh_object(name: str, mesh: trimesh.Trimesh, collection: bpy.types.Collection,
                material: bpy.types.Material | None = None) -> bpy.types.Object:
    obj = bpy.data.objects.new(name, mesh_data(name, mesh))
    if material is not None:
        obj.data.materials.append(material)
    collection.objects.link(obj)
    return obj
