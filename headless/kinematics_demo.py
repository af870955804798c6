"""``python -m headless kinematics``: the kinematics core at work.

The tool pose of each bundled robot at a few joint vectors, and one
inverse-kinematics solve per robot for a probe pose given relative to the rotary
table, as in the paper's user interface.
"""

from __future__ import annotations

import time

import numpy as np

from addon.core.kinematics.cell import Cell
from addon.core.config.toml import available_rigs
from addon.core.kinematics.euler import pose_from_xyz_yzz, pose_to_xyz_yzz
from addon.core.config.rigs import load_robot

JOINT_VECTORS_DEG = {
    "zero": [0, 0, 0, 0, 0, 0],
    "ready": [0, 30, -60, 0, 45, 0],
    "turned": [45, 20, -40, 30, -30, 60],
}
# Probe 150 mm above a point of the workpiece, beam pointing down, table at 30°.
TABLE_ANGLE_DEG = 30.0
TARGET_IN_TABLE = dict(xyz_mm=[20.0, -10.0, 150.0], yzz_deg=[0.0, 180.0, 0.0])


def _row(cells, widths, left: int = 2) -> str:
    """One table row: the first ``left`` columns left-aligned (text), the rest right-aligned."""
    return "  ".join(str(c).ljust(w) if i < left else str(c).rjust(w) for i, (c, w) in enumerate(zip(cells, widths)))


def run() -> int:
    robots = [load_robot(name) for name in available_rigs("robots")]
    print("Tool poses (flange, no tool): position in mm, orientation as YZZ' Euler angles in degrees\n")
    widths = [22, 7, 28, 9, 9, 9, 8, 8, 8]
    print(_row(["robot", "pose", "q (deg)", "x", "y", "z", "yaw", "pitch", "roll"], widths))
    print("-" * (sum(widths) + 2 * (len(widths) - 1)))
    for robot in robots:
        for label, q_deg in JOINT_VECTORS_DEG.items():
            xyz, yzz = pose_to_xyz_yzz(robot.fk(np.radians(q_deg)))
            yzz = np.degrees(yzz)
            print(_row([robot.name, label, str(q_deg), *(f"{v:.2f}" for v in xyz), *(f"{v:.2f}" for v in yzz)], widths))
    print()

    target = pose_from_xyz_yzz(TARGET_IN_TABLE["xyz_mm"], np.radians(TARGET_IN_TABLE["yzz_deg"]))
    print(f"Inverse kinematics: probe at {TARGET_IN_TABLE['xyz_mm']} mm, YZZ' {TARGET_IN_TABLE['yzz_deg']}° "
          f"relative to the rotary table turned to {TABLE_ANGLE_DEG:g}°\n")
    widths = [22, 9, 3, 46, 11, 12, 8]
    print(_row(["robot", "method", "ok", "q (deg)", "pos err", "rot err", "time"], widths))
    print("-" * (sum(widths) + 2 * (len(widths) - 1)))
    for robot in robots:
        cell = Cell(robot)
        t = time.perf_counter()
        res = cell.ik(target, relative_to="table", table_angle_rad=np.radians(TABLE_ANGLE_DEG))
        dt = time.perf_counter() - t
        q = "[" + ", ".join(f"{v:.2f}" for v in np.degrees(res.q)) + "]"
        print(_row([robot.name, res.method, "yes" if res.success else "NO", q, f"{res.pos_err_mm:.1e} mm",
                    f"{res.rot_err_rad:.1e} rad", f"{dt * 1e3:.1f} ms"], widths))
        if not res.success:
            print(f"    {res.message}")
    return 0
