"""Blender scene building (the only place that imports bpy): cell, rig, renders.

Scene units are metres; core units are millimetres. The conversion happens here,
at this one boundary.
"""

import sys

if "bpy" not in sys.modules:  # a headless run: Blender starts here, inside Blender it has started
    from .blender_log import blender_output_captured

    with blender_output_captured():  # its start-up log ("Using OCIO=..." where OCIO is set)
        import bpy  # noqa: F401
