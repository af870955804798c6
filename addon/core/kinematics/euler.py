"""YZZ′ Euler angles, the Cartesian orientation of the paper's Adept robots.

R = R_z(yaw) · R_y(pitch) · R_z(roll): yaw about Z, then pitch about the new Y,
then roll about the new Z. Angles in radians.

Convention for the angles returned by :func:`matrix_to_yzz`:

- pitch ∈ [0, π]; yaw, roll ∈ (−π, π].
- A negative pitch is never returned: (yaw, −p, roll) is the same rotation as
  (yaw + π, p, roll + π), and that is the form you get back.
- At the singular pitches only one combination of yaw and roll is defined
  (yaw + roll at pitch 0, yaw − roll at pitch π). There roll is set to 0 and yaw
  carries the whole rotation about Z. "Singular" means sin(pitch) < 1e-12.

Near (but not at) the singularities yaw and roll are individually poorly
determined, but roll is always computed from what yaw leaves over, so the pair
reproduces the matrix to rounding.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..tolerances import TOL
from .transforms import _cos_sin, check_rotation, make_pose

SINGULAR_SIN_PITCH = TOL.singular


def yzz_to_matrix(yaw, pitch, roll) -> np.ndarray:
    """Rotation (3, 3) (or (..., 3, 3) for arrays) from YZZ′ angles in radians."""
    angles = [np.asarray(a, dtype=np.float64) for a in (yaw, pitch, roll)]
    for label, a in zip(("yaw", "pitch", "roll"), angles):
        if not np.all(np.isfinite(a)):
            raise InputError(f"{label} must be finite (radians), got {a}")
    cy, sy = _cos_sin(angles[0])
    cp, sp = _cos_sin(angles[1])
    cr, sr = _cos_sin(angles[2])
    cy, sy, cp, sp, cr, sr = np.broadcast_arrays(cy, sy, cp, sp, cr, sr)
    R = np.empty(cy.shape + (3, 3))
    R[..., 0, 0] = cy * cp * cr - sy * sr
    R[..., 0, 1] = -cy * cp * sr - sy * cr
    R[..., 0, 2] = cy * sp
    R[..., 1, 0] = sy * cp * cr + cy * sr
    R[..., 1, 1] = -sy * cp * sr + cy * cr
    R[..., 1, 2] = sy * sp
    R[..., 2, 0] = -sp * cr
    R[..., 2, 1] = sp * sr
    R[..., 2, 2] = cp
    return R


def matrix_to_yzz(R) -> tuple[float, float, float]:
    """YZZ′ angles (yaw, pitch, roll) in radians of a rotation R (3, 3) or the rotation of T (4, 4).

    See the module docstring for the ranges and the convention at pitch 0 and π.
    """
    R = np.asarray(R, dtype=np.float64)
    if R.shape == (4, 4):
        R = R[:3, :3]
    R = check_rotation(R, "rotation for YZZ′ angles")
    sp = float(np.hypot(R[0, 2], R[1, 2]))
    pitch = float(np.arctan2(sp, R[2, 2]))
    if sp < SINGULAR_SIN_PITCH:
        # Pitch 0: R = R_z(yaw + roll). Pitch π: R = R_z(yaw − roll)·diag(−1, 1, −1).
        # With roll = 0, column 0 is (cos yaw, sin yaw, 0), negated at pitch π.
        if R[2, 2] > 0:
            return _wrap(float(np.arctan2(R[1, 0], R[0, 0]))), 0.0, 0.0
        return _wrap(float(np.arctan2(-R[1, 0], -R[0, 0]))), float(np.pi), 0.0
    yaw = float(np.arctan2(R[1, 2], R[0, 2]))
    # Roll from what yaw leaves: R_z(yaw)ᵀ R = R_y(pitch) R_z(roll), whose row 1 is (sin r, cos r, 0).
    cy, sy = np.cos(yaw), np.sin(yaw)
    m10 = -sy * R[0, 0] + cy * R[1, 0]
    m11 = -sy * R[0, 1] + cy * R[1, 1]
    roll = float(np.arctan2(m10, m11))
    return _wrap(yaw), pitch, _wrap(roll)


def _wrap(angle: float) -> float:
    """Wrap to (−π, π]."""
    a = float(np.mod(angle + np.pi, 2 * np.pi) - np.pi)
    return float(np.pi) if a == -np.pi else a


def pose_from_xyz_yzz(xyz_mm, yzz_rad) -> np.ndarray:
    """4x4 pose from a position (3,) mm and YZZ′ angles (yaw, pitch, roll) rad."""
    xyz = np.asarray(xyz_mm, dtype=np.float64)
    ang = np.asarray(yzz_rad, dtype=np.float64)
    if xyz.shape != (3,) or ang.shape != (3,):
        raise InputError(f"a pose needs 3 coordinates and 3 angles, got shapes {xyz.shape} and {ang.shape}")
    if not np.all(np.isfinite(xyz)):
        raise InputError(f"position must be finite (mm), got {xyz.tolist()}")
    return make_pose(yzz_to_matrix(*ang), xyz)


def pose_to_xyz_yzz(T) -> tuple[np.ndarray, np.ndarray]:
    """Position (3,) mm and YZZ′ angles (3,) rad of a 4x4 pose."""
    T = np.asarray(T, dtype=np.float64)
    return T[:3, 3].copy(), np.array(matrix_to_yzz(T[:3, :3]))
