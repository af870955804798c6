"""How the cell's surfaces look to the probe: one home for Blender's materials and meshes and
for the ray-cast engine.

Colours are diffuse (Lambertian) albedos per colour channel, linear RGB. The glossy and
mirror workpiece surfaces are not here: they need light transport (Cycles). Meshes shade
smooth, with edges sharper than ``SHARP_EDGE_DEG`` kept sharp.
"""

from __future__ import annotations

WORKPIECE_GREY = 0.6  # the paper's grey workpiece
DIFFUSE_SURFACES = {"grey": (WORKPIECE_GREY,) * 3, "dark": (0.06, 0.06, 0.06)}  # workpiece surfaces, by name
TABLE_TOP = (0.35, 0.35, 0.37)
FIXTURE = (0.45, 0.45, 0.45)  # table fixtures (clamps, posts): a diffuse grey apart from the part's
# Edges where the faces meet at more than this are sharp (Blender's own "auto smooth" angle).
SHARP_EDGE_DEG = 30.0
