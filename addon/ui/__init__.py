"""Blender UI: properties, operators and the Scanner panel.

Each module lists its classes in ``CLASSES``; this package registers them in
order and unregisters them in reverse. (The panel itself arrives with the
extension issue; until then the add-on registers nothing.)
"""

MODULES: tuple = ()


def _classes():
    for module in MODULES:
        yield from module.CLASSES


def register() -> None:
    import bpy

    for cls in _classes():
        bpy.utils.register_class(cls)


def unregister() -> None:
    import bpy

    for cls in reversed(list(_classes())):
        bpy.utils.unregister_class(cls)
