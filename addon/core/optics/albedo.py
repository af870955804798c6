"""The colours of the cell's surfaces: one home for Blender's materials and the ray-cast engine.

Each is a diffuse (Lambertian) albedo per colour channel, linear RGB. The glossy and
mirror workpiece surfaces are not here: they need light transport (Cycles).
"""

from __future__ import annotations

WORKPIECE_GREY = 0.6  # the paper's grey workpiece
DIFFUSE_SURFACES = {"grey": (WORKPIECE_GREY,) * 3, "dark": (0.06, 0.06, 0.06)}  # workpiece surfaces, by name
TABLE_TOP = (0.35, 0.35, 0.37)
