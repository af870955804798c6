"""Kinematics: frames and transforms, YZZ' angles, DH robots, inverse kinematics, the rotary
table, the cell (robot + table + probe mount) and scan paths. Millimetres and radians;
transforms are 4x4 float64 arrays named ``a2b``."""

from .cell import Cell
from .euler import matrix_to_yzz, pose_from_xyz_yzz, pose_to_xyz_yzz, yzz_to_matrix
from .ik import IKBatch, IKResult
from .path import PathSolution, Waypoints, solve_path
from .robot import Robot
from .transforms import make_pose, rigid_inverse, rot_x, rot_y, rot_z, trans, transform_points
from .turntable import Turntable

__all__ = ["Cell", "IKBatch", "IKResult", "PathSolution", "Robot", "Turntable", "Waypoints", "make_pose",
           "matrix_to_yzz", "pose_from_xyz_yzz", "pose_to_xyz_yzz", "rigid_inverse", "rot_x", "rot_y", "rot_z",
           "solve_path", "trans", "transform_points", "yzz_to_matrix"]
