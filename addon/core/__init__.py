"""Pure-numpy core: frames, kinematics, turntable, probe optics, clouds, config.

Nothing under ``addon.core`` imports bpy or mathutils (a test enforces it).
Units are millimetres and radians throughout; transforms are 4x4 float64 arrays
named ``a2b`` for "maps coordinates in frame a to frame b".
"""
