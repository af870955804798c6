"""Blender scene building (the only place that imports bpy): cell, rig, renders.

Scene units are metres; core units are millimetres. The conversion happens here,
at this one boundary.
"""
