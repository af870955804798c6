"""The simulator's Python package.

``addon.core`` is pure numpy (plus OpenCV and trimesh) and never imports bpy;
``addon.scene`` builds the Blender cell from core models; ``addon.ui`` holds the
panel, operators and properties. This file stays import-light so that headless
tools and tests can import the core without Blender.
"""
