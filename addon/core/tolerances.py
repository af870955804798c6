"""Numerical tolerances of the core, in one object.

Each is the smallest difference the code treats as real; below it two values are
the same (a joint on its limit, a pitch of zero, a point on the sensor's edge).
Modules read them from ``TOL`` rather than writing their own literals, so that a
change is made once and every test sees it.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Tolerances:
    joint_limit_rad: float = 1e-10   # a joint this far outside its limit still counts as inside
    ik_rotation_rad: float = 1e-9    # IK orientation error accepted as a hit
    ik_position_mm: float = 1e-6     # IK position error accepted as a hit (scaled down for small arms)
    ik_position_rel: float = 1e-9    # ... times the arm's length scale, whichever is smaller
    singular: float = 1e-12          # relative size below which an angle's sine or a lever is zero
    length_mm: float = 1e-9          # a vector shorter than this has no direction
    sensor_edge_px: float = 1e-9     # points this close outside the sensor's edge count as on it


TOL = Tolerances()
