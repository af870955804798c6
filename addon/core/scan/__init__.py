"""Scans without Blender: the plan (IK, reach, range), the band of rows to render, one frame's
profile, the result and its outputs, the typed report, shards of a path, the preview picture.
The rendering loop that drives these is ``addon.pipeline`` (the only part that needs bpy)."""

from .band import Band, needs_full_frame
from .frames import detect_all, frame_profile, merge_stats, new_stats
from .outputs import ScanResult, assemble
from .plan import Plan, cell_surfaces, frame_ranges, plan_frames, plan_scan
from .preview import render_preview
from .report import ScanReport, report_json
from .shards import Shard, ShardInvalid, ShardResult

__all__ = ["Band", "Plan", "ScanReport", "ScanResult", "Shard", "ShardInvalid", "ShardResult", "assemble",
           "cell_surfaces", "detect_all", "frame_profile", "frame_ranges", "merge_stats", "needs_full_frame",
           "new_stats", "plan_frames", "plan_scan", "render_preview", "report_json"]
