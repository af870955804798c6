"""Which objects in the cell's collections the cell made, and what each one is.

The cell finds its objects by what they are ("Robot", "Turntable", ...), kept as a custom
property on each: never by the object's name, which Blender changes to "Turntable.001" where
the artist's scene has a "Turntable" already. An object without the property is the artist's:
rebuilding or removing the cell keeps it (linked to the scene, still parented where it was).
"""

from __future__ import annotations

import re

import bpy

ROLE_KEY = "scanner_cell_role"


def mark(obj: bpy.types.Object, role: str) -> bpy.types.Object:
    """Mark ``obj`` as made by the cell, as ``role``."""
    obj[ROLE_KEY] = role
    return obj


def role_of(obj: bpy.types.Object) -> str:
    """What a cell object is: its mark, or (a cell built before the marks) its name."""
    return obj.get(ROLE_KEY, obj.name)


def built_role(name: str, names_before: set) -> str:
    """The role of an object the cell just built under ``name``: the name it was given, without
    the ".001" Blender added where an object of the scene (one of ``names_before``) had it."""
    m = re.fullmatch(r"(.+)\.\d{3,}", name)
    return m.group(1) if m and m.group(1) in names_before else name


def own_objects(root: bpy.types.Collection) -> list:
    """The objects of the cell's collections that the cell made: the marked ones, or every one
    where none is marked (a cell built before the marks, which owned all it held)."""
    objs = list(root.all_objects)
    marked = [o for o in objs if ROLE_KEY in o]
    return marked if marked else objs
