"""Which objects in the cell's collections the cell made, and what each one is.

The cell finds its objects by what they are ("Robot", "Turntable", ...), kept as a custom
property on each: never by the object's name, which Blender changes to "Turntable.001" where
the artist's scene has a "Turntable" already. An object without the property is the artist's:
rebuilding or removing the cell keeps it (linked to the scene, still parented where it was).
So is a copy the artist made of one of the cell's (Shift+D copies the property): the cell's
collection records the objects its build made (``register_built``).
"""

from __future__ import annotations

import re

import bpy

ROLE_KEY = "scanner_cell_role"
BUILT_OBJECTS_KEY = "scanner_built_objects"  # on the cell's collection: the objects its build made


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


def register_built(root: bpy.types.Collection) -> None:
    """Record the objects the cell's collections hold now as the ones the build made, by
    reference on the cell's collection: a copy the artist makes of one of them (Shift+D copies
    its mark too) is not among them, and a renamed one still is."""
    root[BUILT_OBJECTS_KEY] = {str(i): o for i, o in enumerate(root.all_objects)}


def register_made(root: bpy.types.Collection, obj: bpy.types.Object) -> None:
    """Add ``obj``, made for the cell after its build (a scan's cloud, the calibration's
    board), to the cell's record (:func:`register_built`); nothing for a cell without one."""
    made = recorded_objects(root)
    if made is not None and obj not in made:
        root[BUILT_OBJECTS_KEY] = {str(i): o for i, o in enumerate([*made, obj])}


def disown(root: bpy.types.Collection, obj: bpy.types.Object) -> None:
    """The cell lets ``obj`` go: its mark and its place in the cell's record removed, a rebuild
    keeps it as the artist's (``mark`` and :func:`register_made` take it back)."""
    obj.pop(ROLE_KEY, None)
    made = recorded_objects(root)
    if made is not None:
        root[BUILT_OBJECTS_KEY] = {str(i): o for i, o in enumerate(o for o in made if o != obj)}


def recorded_objects(root: bpy.types.Collection) -> list | None:
    """The objects the cell's record holds (those the artist deleted too, which the record
    keeps from being freed until the cell is removed); None for a cell built before the record."""
    built = root.get(BUILT_OBJECTS_KEY)
    return None if built is None else [o for o in built.values() if o is not None]


def own_objects(root: bpy.types.Collection) -> list:
    """The objects of the cell's collections that the cell made: those its record holds
    (:func:`register_built`, :func:`register_made`); in a cell built before that record, the
    marked ones, or every one where none is marked (a cell built before the marks, which owned
    all it held)."""
    objs = list(root.all_objects)
    made = recorded_objects(root)
    if made is not None:
        made = set(made)
        return [o for o in objs if o in made]
    marked = [o for o in objs if ROLE_KEY in o]
    return marked if marked else objs
