"""Materials of the cell: the paper's grey workpiece, table, robot paint, emissive markers."""

from __future__ import annotations

import bpy

from ..core.optics.surfaces import DIFFUSE_SURFACES, WORKPIECE_GREY
from .compat import new_material


def bare_material(name: str) -> tuple[bpy.types.Material, bpy.types.Node]:
    """A new material called ``name`` whose node tree holds only its output node; returns
    (material, output node) for the caller to wire its shader into."""
    mat = new_material(name)
    nodes = mat.node_tree.nodes
    for n in list(nodes):
        if n.bl_idname != "ShaderNodeOutputMaterial":
            nodes.remove(n)
    return mat, nodes.get("Material Output") or nodes.new("ShaderNodeOutputMaterial")


def diffuse(name: str, rgb=(WORKPIECE_GREY,) * 3) -> bpy.types.Material:
    """A pure Lambertian (Diffuse BSDF) material, created once by name."""
    mat = bpy.data.materials.get(name)
    if mat is not None:
        return mat
    mat, out = bare_material(name)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (*rgb, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.0
    links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    mat.diffuse_color = (*rgb, 1.0)  # viewport colour
    return mat


def emission(name: str, rgb=(1.0, 1.0, 1.0), strength: float = 1.0) -> bpy.types.Material:
    mat = bpy.data.materials.get(name)
    if mat is not None:
        return mat
    mat, out = bare_material(name)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    em = nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (*rgb, 1.0)
    em.inputs["Strength"].default_value = strength
    links.new(em.outputs["Emission"], out.inputs["Surface"])
    return mat


MIRROR_ROUGHNESS = 0.05  # polished metal


def surface(kind: str = "grey", roughness: float = 0.2) -> bpy.types.Material:
    """The workpiece's surface: grey (the paper's Lambertian grey), dark (a dull black part),
    glossy (grey with a specular coat of the given roughness: reflections of the line need
    bounces to show) or mirror (polished metal)."""
    if kind == "grey":
        return diffuse("Grey workpiece")
    if kind == "dark":
        return diffuse("Dark workpiece", DIFFUSE_SURFACES["dark"])

    if isinstance(roughness, bool) or not isinstance(roughness, (int, float)) or not 0.0 <= roughness <= 1.0:
        from ..core.errors import InputError

        raise InputError(f"the workpiece's roughness must be a number from 0 to 1, got {roughness!r}")
    if kind != "glossy":  # a mirror is polished whatever roughness it is given (and named so)
        roughness = MIRROR_ROUGHNESS
    # Named by the roughness to 4 digits (to 2, 0.004 took 0.001's material), its values set
    # each time (a material of that name may have been edited)
    name = f"{kind.title()} workpiece r{roughness:.4g}"
    mat = bpy.data.materials.get(name)
    if mat is None or mat.node_tree is None or mat.node_tree.nodes.get("Principled BSDF") is None:
        mat = new_material(name)
    bsdf = mat.node_tree.nodes.get("Principled BSDF")
    bsdf.inputs["Base Color"].default_value = (*(0.6,) * 3, 1.0) if kind == "glossy" else (0.9, 0.9, 0.9, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = 1.0 if kind == "mirror" else 0.0
    return mat
