"""What a scan config says about safety: the clearance it asks for and its fixtures."""

from __future__ import annotations

from dataclasses import dataclass

import trimesh

from .clearance import DEFAULT_CLEARANCE_MM

FIXTURE_CARRIERS = ("table", "world")


@dataclass(frozen=True, eq=False)
class Fixture:
    """A solid the robot must keep clear of: ``mesh`` in the table frame (``on = "table"``, it
    turns with the table) or in the world (robot base) frame (``on = "world"``)."""

    name: str
    mesh: trimesh.Trimesh
    on: str = "table"
    source: str = ""  # the mesh file it was read from ("": made in code)


@dataclass(frozen=True)
class Safety:
    """``check``: collision checks on every path (on unless a config turns them off);
    ``min_clearance_mm``: the least distance allowed between the robot or the probe and the
    table, the workpiece or a fixture."""

    check: bool = True
    min_clearance_mm: float = DEFAULT_CLEARANCE_MM
