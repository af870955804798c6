"""Keyframing many frames at once: F-curves filled by bulk array copies."""

from __future__ import annotations

import bpy
import numpy as np

from .compat import fcurve as ensure_fcurve

LINEAR = bpy.types.Keyframe.bl_rna.properties["interpolation"].enum_items["LINEAR"].value


def keyframe_values(id_block, data_path: str, frames, values, index: int = 0) -> None:
    """Replace the F-curve of ``data_path[index]`` on ``id_block`` with (frame, value) keys, linear."""
    frames = np.asarray(frames, dtype=np.float32)
    values = np.asarray(values, dtype=np.float32)
    anim = id_block.animation_data or id_block.animation_data_create()
    if anim.action is None:
        anim.action = bpy.data.actions.new(f"{id_block.name} motion")
    fcurve = ensure_fcurve(anim.action, id_block, data_path, index=index)
    fcurve.keyframe_points.clear()
    fcurve.keyframe_points.add(len(frames))
    fcurve.keyframe_points.foreach_set("co", np.column_stack([frames, values]).ravel())
    fcurve.keyframe_points.foreach_set("interpolation", np.full(len(frames), LINEAR, dtype=np.int32))
    fcurve.update()
