"""The simulator's Python package, and its public API for scripts.

    from addon import Scanner
    scanner = Scanner.from_config("demo")

``Scanner`` (``addon.scanner``) is the one way in: scripts, the panel's operators, the
command line, the farm and the benchmarks drive scans through it. ``addon.core`` is pure
numpy (plus OpenCV and trimesh) and never imports bpy; ``addon.scene`` builds the Blender
cell from core models; ``addon.ui`` holds the panel, operators and properties. The names
below are imported on first use, so that importing this package stays light.
"""

__all__ = ["CollisionError", "Profile", "RenderOptions", "ScanConfig", "ScanReport", "Scanner", "UnreachablePose",
           "ScannerError", "load_probe", "load_robot", "load_scan_config", "load_workpiece", "report_json",
           "resting_on_table"]

_HOMES = {
    "Scanner": ".scanner", "Profile": ".scanner",
    "ScanReport": ".core.scan.report", "report_json": ".core.scan.report",
    "RenderOptions": ".core.config.render",
    "ScanConfig": ".core.config.scan", "load_scan_config": ".core.config.scan",
    "load_probe": ".core.config.rigs", "load_robot": ".core.config.rigs",
    "load_workpiece": ".core.geometry.workpiece", "resting_on_table": ".core.geometry.workpiece",
    "UnreachablePose": ".core.errors", "ScannerError": ".core.errors", "CollisionError": ".core.errors",
}


def __getattr__(name):
    if name in _HOMES:
        import importlib

        return getattr(importlib.import_module(_HOMES[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + __all__)
