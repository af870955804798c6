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


SCAN_MOTION_KEY = "scanner_scan_motion"      # on an action: the scan's own keyframed motion
ARTIST_ACTION_KEY = "scanner_artist_action"  # on an object: its own action, set aside while a scan keys it


def set_aside_own_motion(obj) -> None:
    """Before a scan keys ``obj``'s motion: its own action (an artist's animation) is kept on
    the object's custom property, so that the scan writes into an action of its own and
    :func:`drop_scan_motion` gives the artist's back."""
    anim = obj.animation_data
    if anim is None or anim.action is None or anim.action.get(SCAN_MOTION_KEY):
        return
    obj[ARTIST_ACTION_KEY] = anim.action  # an ID property: a user, so the action survives meanwhile
    anim.action = None


def mark_scan_motion(obj) -> None:
    """The action ``obj`` now holds is a scan's motion (see :func:`drop_scan_motion`)."""
    if obj.animation_data is not None and obj.animation_data.action is not None:
        obj.animation_data.action[SCAN_MOTION_KEY] = True


def drop_scan_motion(obj) -> None:
    """After a scan: the scan's motion off ``obj`` (and out of the file where nothing else uses
    it), and the object's own action, set aside by :func:`set_aside_own_motion`, back on it."""
    anim = obj.animation_data
    if anim is not None and anim.action is not None and anim.action.get(SCAN_MOTION_KEY):
        motion = anim.action
        anim.action = None
        if motion.users == 0:
            bpy.data.actions.remove(motion)
    own = obj.get(ARTIST_ACTION_KEY)
    if own is not None:
        del obj[ARTIST_ACTION_KEY]
        obj.animation_data_create().action = own
    elif anim is not None and anim.action is None and not anim.drivers and not anim.nla_tracks:
        obj.animation_data_clear()
