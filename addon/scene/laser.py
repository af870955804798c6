"""The line laser, in two models.

``gobo`` (Cycles): a spot light at the probe origin whose node tree makes its
strength a Gaussian of the emission direction across the laser plane: with n
the direction in the light's frame, strength = exp(−n_x² / 2σ²), σ = the line's
1/e² half-width / 2 at mid-range, divided by that distance (an angular width, so
the line widens with distance like a real fan laser). The spot cone (the fan
angle) limits the line's length. Red, no soft shadow.

``spot`` (Eevee, which ignores light node trees; Cycles samples one of its lights per path,
so there its line is noise, 0.07 px RMS at 16 samples and 0.017 px at 256, and it is
refused): the same Gaussian line made of five coaxial
spot lights, each squeezed across the line by its object's scale and softened by its
blend, their powers, widths and cone angles fitted so that their sum is the gobo's
Gaussian within 0.11 % over ±2.5σ (``addon/core/optics/laser_profile.py``).

``slit`` (Cycles and Eevee): the paper's own model
(Fig. 2), a point light behind an opaque plate with a slit of L × W at distance D
in front of it; the line has a sharp, flat-topped profile of width W·z/D.

Power: see ``addon/core/optics/laser_profile.py`` (:func:`laser_power_w`).
"""

from __future__ import annotations

import math

import bpy
import numpy as np
import trimesh

from ..core.errors import InputError
from ..core.optics.laser_profile import (LASER_RGB, SPOT_COMPONENTS, SPOT_STRETCH, angular_sigma_rad, laser_power_w,
                                         mid_range_mm, spot_squeezes)
from ..core.optics.probe import Probe
from .compat import ensure_node_tree
from .materials import diffuse
from .meshes import mesh_object
from .units import to_blender

LASER_MODELS = ("gobo", "spot", "slit")
SLIT_DISTANCE_MM = 10.0
SPOT_REACH_M = 100.0  # Eevee's light cut-off for the spot model's lights: far beyond any cell
# Light frame -> probe frame: the light shines along its local −Z, which must be the
# probe's +Z (the beam); its local X stays the probe's X (across the laser plane).
LIGHT_IN_PROBE = np.diag([1.0, -1.0, -1.0, 1.0])


def add_laser(collection, probe: Probe, parent: bpy.types.Object, model: str = "gobo",
              power_w: float | None = None) -> list[bpy.types.Object]:
    """Laser objects parented to the probe; returns them (the light that carries most of
    the power first). The first one's ``laser_model`` property names the model."""
    if model not in LASER_MODELS:
        raise InputError(f"laser model {model!r} is not one of: {', '.join(LASER_MODELS)}")
    power = laser_power_w(probe) if power_w is None else float(power_w)
    if not math.isfinite(power) or power <= 0:
        raise InputError(f"laser power must be a positive number of watts, got {power_w}")
    if model == "spot":
        objs = _spot_lights(collection, probe, parent, power)
    else:
        if model == "gobo":
            light = bpy.data.lights.new("Laser", "SPOT")
            light.spot_size = probe.fan_rad
            light.spot_blend = 0.0
            _gobo_nodes(light, angular_sigma_rad(probe))
        else:
            light = bpy.data.lights.new("Laser", "POINT")
        objs = [_light_object(collection, "Laser", light, power, parent)]
    objs[0]["laser_model"] = model
    if model == "slit":
        objs.append(_slit_plate(collection, probe, parent))
    return objs


def _light_object(collection, name: str, light, power: float, parent, scale=(1.0, 1.0)) -> bpy.types.Object:
    light.energy = power
    light.color = LASER_RGB
    light.shadow_soft_size = 0.0
    obj = bpy.data.objects.new(name, light)
    collection.objects.link(obj)
    obj.parent = parent
    obj.matrix_parent_inverse.identity()
    obj.matrix_basis = to_blender(LIGHT_IN_PROBE @ np.diag([scale[0], scale[1], 1.0, 1.0]))
    return obj


def _spot_lights(collection, probe: Probe, parent, power: float) -> list[bpy.types.Object]:
    """The spot model's lights: one per component of ``SPOT_COMPONENTS``, the largest share
    first (named "Laser"), each squeezed across the line to its width, stretched along it,
    and given its share of the power."""
    objs = []
    for i, ((share, _, half_angle_deg), squeeze) in enumerate(zip(SPOT_COMPONENTS,
                                                                  spot_squeezes(angular_sigma_rad(probe)))):
        name = "Laser" if i == 0 else f"Laser {i + 1}"
        light = bpy.data.lights.new(name, "SPOT")
        light.spot_size = 2.0 * math.radians(half_angle_deg)
        light.spot_blend = 1.0
        # Eevee skips a light beyond the distance where its power falls below the scene's
        # light threshold: the faint components would vanish from far surfaces.
        light.use_custom_distance = True
        light.cutoff_distance = SPOT_REACH_M
        objs.append(_light_object(collection, name, light, power * share, parent, (squeeze, SPOT_STRETCH)))
    return objs


def _gobo_nodes(light: bpy.types.Light, sigma: float) -> None:
    nt = ensure_node_tree(light)
    emission = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeEmission")
    coords = nt.nodes.new("ShaderNodeTexCoord")  # for a light: "Normal" is the emission direction, light frame
    split = nt.nodes.new("ShaderNodeSeparateXYZ")
    square = nt.nodes.new("ShaderNodeMath")
    square.operation = "MULTIPLY"
    scale = nt.nodes.new("ShaderNodeMath")
    scale.operation = "MULTIPLY"
    scale.inputs[1].default_value = -1.0 / (2.0 * sigma * sigma)
    gauss = nt.nodes.new("ShaderNodeMath")
    gauss.operation = "EXPONENT"
    nt.links.new(coords.outputs["Normal"], split.inputs[0])
    nt.links.new(split.outputs["X"], square.inputs[0])
    nt.links.new(split.outputs["X"], square.inputs[1])
    nt.links.new(square.outputs[0], scale.inputs[0])
    nt.links.new(scale.outputs[0], gauss.inputs[0])
    nt.links.new(gauss.outputs[0], emission.inputs["Strength"])


def _slit_plate(collection, probe: Probe, parent) -> bpy.types.Object:
    """A closed box around the point light, open only through a slit L × W in its front
    face at z = D: W = line width · D / mid-range, L covers the fan. It stays within
    ±15 mm of the laser, clear of the cameras' views (they sit a mm beside it)."""
    D = SLIT_DISTANCE_MM
    W = probe.line_width_mm * D / mid_range_mm(probe)
    L = 2.0 * D * math.tan(probe.fan_rad / 2)
    half, back, t = max(15.0, L / 2 + 3.0), -10.0, 0.2
    if probe.a_mm <= half + 5.0:
        raise InputError(f"the slit aperture ({2 * half:g} mm wide) would block cameras only {probe.a_mm:g} mm "
                         "from the laser; use the gobo laser for this probe")

    def box(x0, x1, y0, y1, z0, z1):
        return trimesh.creation.box([x1 - x0, y1 - y0, z1 - z0],
                                    trimesh.transformations.translation_matrix([(x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2]))

    walls = [
        box(-half, half, -half, half, back - t, back),          # back
        box(-half - t, -half, -half, half, back, D),             # sides
        box(half, half + t, -half, half, back, D),
        box(-half, half, -half - t, -half, back, D),
        box(-half, half, half, half + t, back, D),
        box(-half, -W / 2, -half, half, D, D + t),               # front, around the slit
        box(W / 2, half, -half, half, D, D + t),
        box(-W / 2, W / 2, L / 2, half, D, D + t),
        box(-W / 2, W / 2, -half, -L / 2, D, D + t),
    ]
    plate = mesh_object("Laser slit", trimesh.util.concatenate(walls), collection, diffuse("Slit plate", (0.02,) * 3))
    plate.parent = parent
    plate.matrix_parent_inverse.identity()
    return plate
