"""Safe motion: the cell's bodies and collision checks along paths (python-fcl)."""

from .clearance import DEFAULT_CLEARANCE_MM, CollisionModel, Contact, PathClearance
from .settings import FIXTURE_CARRIERS, Fixture, Safety

__all__ = ["CollisionModel", "Contact", "DEFAULT_CLEARANCE_MM", "FIXTURE_CARRIERS", "Fixture", "PathClearance",
           "Safety"]
