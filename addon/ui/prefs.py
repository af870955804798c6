"""Add-on preferences, keyed by the extension's package name."""

from __future__ import annotations

import bpy

from .models import ROOT_PACKAGE, default_output_dir


class ScannerPreferences(bpy.types.AddonPreferences):
    bl_idname = ROOT_PACKAGE or __package__

    def draw(self, context):
        col = self.layout.column()
        col.label(text="Scans are written to the folder set in the Scan panel, or by default to:")
        col.label(text=str(default_output_dir()))
        col.label(text="Blender deletes that folder with the extension when it is uninstalled: keep scans "
                       "you need elsewhere.", icon="ERROR")


# Only an installed extension has a preferences entry to attach to.
CLASSES = (ScannerPreferences,) if ROOT_PACKAGE else ()
