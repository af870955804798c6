"""The scene's own render settings, put back after the scanner has rendered with its own.

Probe renders need their own engine, resolution, samples, colour management,
output format, multiview and world light (see render.configure). In a user's
scene those settings belong to the artist: the panel's operators take a
:class:`RenderState` before they render and restore it when they are done,
whether they finish, fail or are cancelled.

The snapshot is generic: every writable plain property (numbers, booleans,
strings, enums, fixed-size arrays) of the structs the scanner writes to, plus
the few pointers and collections it changes (the scene camera and world, the stereo
views, the view layers' overrides and Z pass, the frame).
"""

from __future__ import annotations

from contextlib import contextmanager

import bpy

_PLAIN = {"BOOLEAN", "INT", "FLOAT", "STRING", "ENUM"}
# What the probe renders set on each view layer (render.configure).
_LAYER = ("use_pass_z", "material_override", "world_override", "samples", "use_solid", "use_sky", "use_motion_blur")
# Worked out by Blender from others, and setting it sets them: the white point is the white
# balance's temperature and tint over again, and put back after them it moved them by a hair
# (6500 K became 6500.087 K after ten probe renders).
_DERIVED = {"white_balance_whitepoint"}


def _struct_values(struct) -> dict:
    values = {}
    for prop in struct.bl_rna.properties:
        if prop.is_readonly or prop.type not in _PLAIN or prop.identifier in ("rna_type", *_DERIVED):
            continue
        value = getattr(struct, prop.identifier)
        if getattr(prop, "is_array", False):
            value = tuple(value)
        elif prop.type == "ENUM" and getattr(prop, "is_enum_flag", False):
            value = set(value)
        values[prop.identifier] = value
    return values


def _set_values(struct, values: dict) -> None:
    for name, value in values.items():
        try:
            if getattr(struct, name) != value:
                setattr(struct, name, value)
        except (AttributeError, TypeError, ValueError):
            pass  # a property that depends on another (e.g. an enum item only valid for one engine)


class RenderState:
    """What ``scene``'s render settings are now; :meth:`restore` puts them back."""

    def __init__(self, scene: bpy.types.Scene):
        self.scene = scene
        r = scene.render
        self.structs = [r, r.image_settings, scene.view_settings, scene.display_settings]
        for name in ("cycles", "eevee"):
            if hasattr(scene, name):
                self.structs.append(getattr(scene, name))
        self.values = [_struct_values(s) for s in self.structs]
        self.camera = scene.camera
        self.world = scene.world  # (the probe renders light with a world of their own)
        self.views = {v.name: (v.use, v.camera_suffix) for v in r.views}
        self.layers = {layer.name: {name: getattr(layer, name) for name in _LAYER if hasattr(layer, name)}
                       for layer in scene.view_layers}
        self.frame = scene.frame_current

    def restore(self) -> None:
        scene = self.scene
        # Engine first: some settings only exist (or only accept a value) for one engine.
        for struct, values in zip(self.structs, self.values):
            if "engine" in values:
                _set_values(struct, {"engine": values["engine"]})
        for struct, values in zip(self.structs, self.values):
            _set_values(struct, values)
        scene.camera = self.camera if self.camera is None or self.camera.name in bpy.data.objects else None
        scene.world = self.world
        views = scene.render.views
        for view in list(views):
            if view.name not in self.views:
                views.remove(view)
        for name, (use, suffix) in self.views.items():
            view = views.get(name)
            if view is not None:
                view.use, view.camera_suffix = use, suffix
        for layer in scene.view_layers:
            for name, value in self.layers.get(layer.name, {}).items():
                if getattr(layer, name) != value:
                    setattr(layer, name, value)
        if scene.frame_current != self.frame:
            scene.frame_set(self.frame)


@contextmanager
def kept_render_settings(scene: bpy.types.Scene):
    """Render with the scanner's settings inside; the scene's own are back afterwards."""
    state = RenderState(scene)
    try:
        yield state
    finally:
        state.restore()
