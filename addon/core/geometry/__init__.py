"""Geometry: workpieces (analytic shapes and meshes, with their exact truth), point clouds,
error metrics against the truth, and the laser footprint (ray casts of the fan)."""

from .cloud import Cloud, CloudAccumulator, load_ply, save_ply
from .footprint import Footprint, laser_footprint
from .metrics import ErrorStats, coverage, distances, error_stats
from .shapes import Cylinder, PlanePatch, Sphere, StepBlock
from .workpiece import Workpiece, builtin_workpiece, load_workpiece

__all__ = ["Cloud", "CloudAccumulator", "Cylinder", "ErrorStats", "Footprint", "PlanePatch", "Sphere",
           "StepBlock", "Workpiece", "builtin_workpiece", "coverage", "distances", "error_stats",
           "laser_footprint", "load_ply", "load_workpiece", "save_ply"]
