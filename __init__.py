"""Blender extension entry point for the laser scanner simulator.

Kept thin and import-light: the repository root is a package (the extension), and
headless tools and tests import ``addon.core`` without Blender. Everything that
needs bpy is imported inside register()/unregister().
"""


def register() -> None:
    from .addon import ui

    ui.register()


def unregister() -> None:
    from .addon import ui

    ui.unregister()
