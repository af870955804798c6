"""The calibration board in the cell: a plate on the table with the ChArUco pattern printed on
its top, and a plain white side for the laser-plane images.

The plate is a child of the turntable, placed by ``board2table`` (the board frame: pattern
origin at its top-left corner, z into the plate). Its print is an image texture sampled
with "Closest" interpolation: the texels are much finer than a sensor pixel and each
square edge falls on a texel edge, so the printed edges lie exactly where the board model
puts them; the pixel filter (a one-pixel box, many samples) integrates each sensor pixel.
"""

from __future__ import annotations

import bpy
import numpy as np

from ..core.calibration.board import ChArUcoBoard
from .materials import bare_material, diffuse
from .ownership import mark
from .units import M_PER_MM, to_blender

BLACK, WHITE = 0.04, 0.85  # diffuse albedo of the printed black and the white paper
PLAIN = "Calibration plate (plain)"


def _print_material(board: ChArUcoBoard, px_per_mm: int) -> bpy.types.Material:
    name = f"Calibration print {board.squares[0]}x{board.squares[1]} {board.square_mm:g} mm"
    mat = bpy.data.materials.get(name)
    if mat is not None:
        return mat
    tex = board.texture(px_per_mm).astype(np.float32) / 255.0
    albedo = BLACK + (WHITE - BLACK) * tex
    h, w = albedo.shape
    image = bpy.data.images.new(name, width=w, height=h, alpha=False, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = albedo[::-1, :, None]  # Blender's rows run bottom-up
    image.pixels.foreach_set(rgba.ravel())
    image.pack()
    mat, out = bare_material(name)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    node = nodes.new("ShaderNodeTexImage")
    node.image = image
    node.interpolation = "Closest"
    node.extension = "CLIP"
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Roughness"].default_value = 0.0
    links.new(node.outputs["Color"], bsdf.inputs["Color"])
    links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return mat


def add_board(collection, board: ChArUcoBoard, board2table: np.ndarray, table_obj, px_per_mm: int = 20
              ) -> bpy.types.Object:
    """The plate's printed face (the pattern, UV-mapped texel for texel) and its white margin,
    as one object parented to the table."""
    w, h = board.pattern_mm
    m = board.margin_mm
    # Board frame: x ∈ [0, w], y ∈ [0, h] is the pattern; UV (0, 0) is the image's bottom-left,
    # i.e. board (0, h). The margin is a frame of four quads around it.
    xs = [-m, 0.0, w, w + m]
    ys = [-m, 0.0, h, h + m]
    verts, faces, uvs, mats = [], [], [], []
    for i in range(3):
        for j in range(3):
            x0, x1, y0, y1 = xs[i], xs[i + 1], ys[j], ys[j + 1]
            base = len(verts)
            quad = [(x0, y0), (x0, y1), (x1, y1), (x1, y0)]  # normal −z in the board frame: up on the table
            verts += [(x, y, 0.0) for x, y in quad]
            faces.append((base, base + 1, base + 2, base + 3))
            uvs += [(x / w, 1.0 - y / h) for x, y in quad]
            mats.append(0 if (i, j) == (1, 1) else 1)
    me = bpy.data.meshes.new("Calibration board")
    me.from_pydata([tuple(np.array(v) * M_PER_MM) for v in verts], [], faces)
    uv = me.uv_layers.new(name="UVMap")
    for loop in me.loops:
        uv.data[loop.index].uv = uvs[loop.vertex_index]
    me.materials.append(_print_material(board, px_per_mm))
    me.materials.append(diffuse(PLAIN, (WHITE,) * 3))
    for poly, k in zip(me.polygons, mats):
        poly.material_index = k
        poly.use_smooth = False
    obj = mark(bpy.data.objects.new("Calibration board", me), "Calibration board")
    collection.objects.link(obj)
    obj.parent = table_obj
    obj.matrix_parent_inverse.identity()
    obj.matrix_basis = to_blender(board2table)
    obj["print"] = me.materials[0].name
    return obj


def show_print(obj: bpy.types.Object, printed: bool) -> None:
    """The printed pattern (board images) or the plate's plain white side (laser images)."""
    obj.data.materials[0] = bpy.data.materials[obj["print"]] if printed else diffuse(PLAIN, (WHITE,) * 3)
