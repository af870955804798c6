"""Scans without Blender: shards of a path, the preview picture."""

from .preview import render_preview
from .report import ScanReport, report_json
from .shards import Shard, ShardInvalid, ShardResult

__all__ = ["ScanReport", "Shard", "ShardInvalid", "ShardResult", "render_preview", "report_json"]
