"""Configuration: TOML reading with errors that name file, key and range; rig files
(robots, probes); scan configs (robot, probe, table, workpiece, path, render, detection)."""

from .rigs import load_probe, load_robot
from .scan import LeaveOut, RenderOptions, ScanConfig, load_scan_config
from .toml import Table, available_rigs, load_toml, resolve_rig

__all__ = ["LeaveOut", "RenderOptions", "ScanConfig", "Table", "available_rigs", "load_probe", "load_robot",
           "load_scan_config", "load_toml", "resolve_rig"]
