"""The scanning cell: a robot carrying the probe and a rotary table carrying the workpiece.

Paper Eq. 8 prints T_PC = T_R^0 · T_DK, but T_R^0 maps table coordinates to base
coordinates. The transform that takes probe coordinates into the table (workpiece)
frame is

    probe2table = base2table(θ_R) @ probe2base(q) = T_0^R · T_DK,

which is what :meth:`Cell.probe2table` returns (a round-trip test settles it).
Cartesian targets may be given relative to the robot base or to the table, as in
the paper's user interface.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from .ik import IKResult
from .robot import Robot
from .transforms import check_transform
from .turntable import Turntable

FRAMES = ("base", "table")


@dataclass(frozen=True, eq=False)
class Cell:
    """robot: its tool is the probe (T_L^6); table: placement of the rotary table."""

    robot: Robot
    table: Turntable = field(default_factory=Turntable)

    def probe2base(self, q) -> np.ndarray:
        """T_DK (Eq. 3): probe pose in the robot base (world) frame. (6,) -> (4, 4); (n, 6) -> (n, 4, 4)."""
        return self.robot.fk(q)

    def probe2table(self, q, theta_rad) -> np.ndarray:
        """Eq. 8 done right: T_0^R(θ_R) · T_DK(q). Broadcasts over (n, 6) and (n,)."""
        return self.table.base2table(theta_rad) @ self.robot.fk(q)

    def target_in_base(self, T_target, relative_to: str = "base", table_angle_rad: float = 0.0) -> np.ndarray:
        """A probe target pose (4, 4) given relative to 'base' or 'table', expressed in the base frame."""
        if relative_to not in FRAMES:
            raise InputError(f"relative_to must be one of {', '.join(FRAMES)}, got {relative_to!r}")
        T = check_transform(T_target, f"probe target relative to the {relative_to}")
        if relative_to == "table":
            return self.table.table2base(table_angle_rad) @ T
        return T

    def ik(self, T_target, q0=None, *, relative_to: str = "base", table_angle_rad: float = 0.0,
           **options) -> IKResult:
        """Joint vector putting the probe at ``T_target`` relative to the base or the table."""
        return self.robot.ik(self.target_in_base(T_target, relative_to, table_angle_rad), q0, **options)
