"""Scans without Blender: shards of a path, the preview picture."""

from .preview import render_preview
from .shards import Shard, ShardInvalid, ShardResult

__all__ = ["Shard", "ShardInvalid", "ShardResult", "render_preview"]
