"""The demo cell for headless tools until scene configs exist: a robot, a probe and a workpiece
on the turntable, and a simple sweep of the probe over the workpiece."""

from __future__ import annotations

import numpy as np

from addon.core.kinematics.cell import Cell
from addon.core.errors import UnreachablePose
from addon.core.kinematics.euler import pose_from_xyz_yzz
from addon.core.config.rigs import load_robot
from addon.core.config.rigs import load_probe
from addon.core.geometry.workpiece import builtin_workpiece

STAND_OFF_MM = 150.0
READY_DEG = (0.0, 40.0, -100.0, 0.0, -30.0, 0.0)  # the IK seed of the sweep below (elbow up)


def build(scene, robot: str = "adept_viper_s650", probe: str = "default", workpiece: str = "sphere",
          laser: str = "gobo"):
    from addon.scene.cell import build_cell

    wp = builtin_workpiece(workpiece)
    return build_cell(scene, Cell(load_robot(robot)), load_probe(probe), wp, laser)


def sweep(sc, frames: int, length_mm: float = 60.0, table_angle_rad: float = 0.0) -> range:
    """Keyframe the probe moving across the workpiece's top, beam down, at the stand-off."""
    top = float(sc.workpiece.mesh.bounds[1][2])
    qs, q = [], np.radians(READY_DEG)
    for x in np.linspace(-length_mm / 2, length_mm / 2, frames):
        T = pose_from_xyz_yzz([x, 0.0, top + STAND_OFF_MM], [np.pi / 2, np.pi, 0.0])
        res = sc.cell.ik(T, q, relative_to="table", table_angle_rad=table_angle_rad)
        if not res.success:
            raise UnreachablePose(f"demo sweep: {res.message}", res)
        q = res.q
        qs.append(q)
    return sc.keyframe(np.array(qs), np.full(frames, table_angle_rad))
