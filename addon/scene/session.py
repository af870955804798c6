"""A clean Blender scene for headless runs, and render-device selection."""

from __future__ import annotations

import bpy  # first: it puts Blender's own modules (addon_utils) on the path

import addon_utils  # noqa: E402

from ..core.config.render import DEVICES, ENGINES, GPU_BACKENDS
from ..core.errors import InputError
from .blender_log import blender_output_captured
from .compat import BLENDER_ENGINES

# Blender's name for each engine the render options allow, but the raycast engine, which runs
# without Blender (what Blender renders for it is Cycles' image: SceneCell.render).
assert set(BLENDER_ENGINES) == set(ENGINES) - {"raycast"}


def new_scene(device: str = "CPU") -> bpy.types.Scene:
    """Reset Blender to an empty factory state (headless use only) with Cycles enabled.

    The factory reset also disables add-ons, Cycles among them, and resets the
    preferences, so the render device is chosen again afterwards.
    """
    bpy.ops.wm.read_factory_settings(use_empty=True)
    addon_utils.enable("cycles", default_set=True)
    scene = bpy.context.scene
    use_device(scene, device)
    return scene


def use_device(scene: bpy.types.Scene, device: str = "CPU") -> str:
    """Select the CPU, the first GPU backend available ("GPU") or a named backend ("OPTIX",
    "CUDA", ...) for Cycles; returns the device actually used (CPU where no GPU answers)."""
    if device not in DEVICES:
        raise InputError(f"render device {device!r} is not one of: {', '.join(DEVICES)}")
    scene.cycles.device = "CPU"
    if device == "CPU":
        return "CPU"
    prefs = bpy.context.preferences.addons["cycles"].preferences
    for backend in GPU_BACKENDS if device == "GPU" else (device,):
        try:
            prefs.compute_device_type = backend
        except TypeError:
            continue
        with blender_output_captured():  # Cycles logs each backend it cannot load (CUEW, HIPEW) to stdout
            prefs.get_devices()
        gpus = [d for d in prefs.devices if d.type == backend]
        if gpus:
            for d in prefs.devices:
                d.use = d.type == backend
            scene.cycles.device = "GPU"
            return f"GPU ({backend}: {', '.join(d.name for d in gpus)})"
    return "CPU"
