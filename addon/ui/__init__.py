"""Blender UI: properties, operators and the Scanner panel.

Each module lists its classes in ``CLASSES``; they are registered in order and
unregistered in reverse, and the settings are attached to every scene as
``scene.scanner``. Unregistering removes all of it, leaving nothing behind.
"""

from . import ops, panel, prefs, props

MODULES = (props, ops, panel, prefs)


def _classes():
    for module in MODULES:
        yield from module.CLASSES


def register() -> None:
    import bpy

    for cls in _classes():
        bpy.utils.register_class(cls)
    bpy.types.Scene.scanner = bpy.props.PointerProperty(type=props.ScannerSettings)
    from . import ops

    ops._SCAN_RUNNING[0] = False  # a scan ended without its operator knowing cannot grey out a fresh start


def unregister() -> None:
    import bpy

    if hasattr(bpy.types.Scene, "scanner"):
        del bpy.types.Scene.scanner
    for cls in reversed(list(_classes())):
        if getattr(cls, "is_registered", False):
            bpy.utils.unregister_class(cls)
