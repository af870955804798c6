"""What differs between the supported Blender releases (4.5 LTS, 5.0, 5.1, 5.2 LTS), in one place.

Everything else in ``addon.scene`` calls these and stays free of version checks.

- Node trees: before 5.0 a new material's, world's or light's ``node_tree`` is None
  until ``use_nodes`` is set; from 5.0 they always have one and ``use_nodes`` is
  deprecated (removed in 6.0), so it is set only where it is still needed.
- F-curves: ``Action.fcurve_ensure_for_datablock`` (4.4 and later, slotted actions);
  the plain ``Action.fcurves`` API before.
- Eevee's engine name: ``BLENDER_EEVEE_NEXT`` in 4.2–4.5, ``BLENDER_EEVEE`` from 5.0.
- Reading rendered EXR files is not done through ``bpy.data.images`` at all: 4.5 loads
  multiview files (``*_L.exr``/``*_R.exr``) as 0 × 0 images. See ``render.read_image``.
"""

from __future__ import annotations

import bpy

VERSION: tuple[int, int, int] = tuple(bpy.app.version)
NODES_ALWAYS_ON = VERSION >= (5, 0, 0)
# The scene's render engine per engine of RenderOptions.
BLENDER_ENGINES = {"cycles": "CYCLES", "eevee": "BLENDER_EEVEE" if VERSION >= (5, 0, 0) else "BLENDER_EEVEE_NEXT"}


def ensure_node_tree(id_block) -> bpy.types.NodeTree:
    """The node tree of a material, world or light, created where this Blender needs
    ``use_nodes`` for that."""
    if id_block.node_tree is None or not NODES_ALWAYS_ON and not id_block.use_nodes:
        id_block.use_nodes = True
    return id_block.node_tree


def new_material(name: str) -> bpy.types.Material:
    """A new node-based material (a Principled BSDF wired to the output, as Blender makes it)."""
    mat = bpy.data.materials.new(name)
    ensure_node_tree(mat)
    return mat


def new_world(name: str) -> bpy.types.World:
    """A new world with its Background node."""
    world = bpy.data.worlds.new(name)
    ensure_node_tree(world)
    return world


def fcurve(action: bpy.types.Action, id_block, data_path: str, index: int = 0) -> bpy.types.FCurve:
    """The F-curve animating ``data_path[index]`` of ``id_block`` in ``action``, created if missing."""
    if hasattr(action, "fcurve_ensure_for_datablock"):
        return action.fcurve_ensure_for_datablock(id_block, data_path, index=index)
    found = action.fcurves.find(data_path, index=index)
    return found if found is not None else action.fcurves.new(data_path, index=index)
