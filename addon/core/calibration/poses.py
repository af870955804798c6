"""Where the probe looks at the board: the board's place on the table and the views the
calibration proposes.

The board lies face up at the table's centre. Each view puts the probe's beam through the
board's centre at a depth inside the probe's range, tilted away from straight down about
an axis that turns from view to view (a golden-angle sequence, so any number of views
spreads evenly) and turned about the beam: Zhang's method and the hand-eye solve both
need rotations about several axes.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from ..kinematics.transforms import rot_x, rot_z, trans
from .board import ChArUcoBoard

GOLDEN_DEG = 137.50776405003785


def board2table(board: ChArUcoBoard) -> np.ndarray:
    """(4, 4) mm: the board frame (pattern's top-left corner, z into the plate) on the table,
    face up and centred, its surface the plate's top."""
    w, h = board.pattern_mm
    return trans(-0.5 * w, 0.5 * h, board.thickness_mm) @ rot_x(math.pi)


def board_views(board: ChArUcoBoard, z_range_mm: tuple[float, float], count: int, *,
                tilt_deg: tuple[float, float] = (10.0, 25.0), turn_deg: float = 30.0,
                depth_share: tuple[float, float] = (0.3, 0.7)) -> np.ndarray:
    """(count, 4, 4) probe poses in the table frame looking at the board's centre.

    View k: depth inside ``depth_share`` of the range, tilt between ``tilt_deg`` about an
    axis at k × 137.5° in the table plane, turn about the beam within ±``turn_deg``."""
    if count < 1:
        raise InputError(f"the number of board views must be at least 1, got {count}")
    z0, z1 = z_range_mm
    centre = board2table(board) @ np.array([0.5 * board.pattern_mm[0], 0.5 * board.pattern_mm[1], 0.0, 1.0])
    out = np.empty((count, 4, 4))
    for k in range(count):
        frac = (k * 0.6180339887498949) % 1.0
        depth = z0 + (depth_share[0] + (depth_share[1] - depth_share[0]) * frac) * (z1 - z0)
        tilt = math.radians(tilt_deg[0] + (tilt_deg[1] - tilt_deg[0]) * ((k * 0.7548776662466927) % 1.0))
        axis = math.radians(k * GOLDEN_DEG)
        turn = math.radians(turn_deg) * math.sin(2.3 * k + 0.5)
        tilt_about = rot_z(axis) @ rot_x(tilt) @ rot_z(-axis)
        out[k] = trans(*centre[:3]) @ tilt_about @ rot_z(turn) @ rot_x(math.pi) @ trans(0.0, 0.0, -depth)
    return out


def load_views(path) -> np.ndarray:
    """(n, 4, 4) probe poses in the table frame from a TOML file of ``[[view]]`` tables, each
    with ``xyz_mm`` (the probe origin) and ``yzz_deg`` (its YZZ' angles), as scan paths give poses."""
    from ..config.toml import load_toml
    from ..errors import ConfigError
    from ..kinematics.euler import pose_from_xyz_yzz

    top = load_toml(path)
    if not top.has("view"):
        raise ConfigError(f"{path}: no [[view]] tables: give each board view as [[view]] with xyz_mm and yzz_deg")
    out = []
    for t in top.tables("view"):
        xyz = t.numbers("xyz_mm", 3, lo=-1e5, hi=1e5)
        yzz = t.numbers("yzz_deg", 3, lo=-720.0, hi=720.0)
        t.finish()
        out.append(pose_from_xyz_yzz(xyz, np.radians(yzz)))
    top.finish()
    return np.array(out)


def flat_views(board: ChArUcoBoard, z_range_mm, count: int) -> np.ndarray:
    """Views that all look straight down (no tilt, no turn): a degenerate set, for tests and
    for showing what the calibration refuses."""
    return board_views(board, z_range_mm, count, tilt_deg=(0.0, 0.0), turn_deg=0.0)
