"""Homogeneous transforms: elementary rotations, translations, rigid inverse, checks.

All transforms are float64 arrays of shape ``(4, 4)`` or stacks ``(..., 4, 4)``.
Lengths are millimetres, angles radians. A transform named ``a2b`` maps
coordinates in frame ``a`` to frame ``b``: ``p_b = a2b @ p_a``.

Rigid transforms are inverted in closed form (Rᵀ, −Rᵀp), never with
``np.linalg.inv``: it is exact to rounding and keeps the result rigid.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError

# Largest ‖RᵀR − I‖ (max-abs) accepted as "a rotation". Loose enough for values
# typed into a config file with 6-8 digits, tight enough to catch a scale or shear.
RIGID_TOL = 1e-6
_IDENTITY3 = np.eye(3)
_BOTTOM_ROW = np.array([0.0, 0.0, 0.0, 1.0])


def _cos_sin(angle):
    """cos and sin of ``angle``, exact (0, ±1) at multiples of 90°.

    DH tables are full of ±90° twists; returning cos = 0 exactly instead of
    6.1e-17 keeps axes that should be orthogonal exactly orthogonal.
    """
    a = np.asarray(angle, dtype=np.float64)
    c = np.cos(a)
    s = np.sin(a)
    quarter = np.round(a / (np.pi / 2))
    exact = np.abs(a - quarter * (np.pi / 2)) < 1e-15 * np.maximum(1.0, np.abs(a))
    if np.any(exact):
        k = np.mod(quarter, 4).astype(int)
        c = np.where(exact, np.choose(k, [1.0, 0.0, -1.0, 0.0]), c)
        s = np.where(exact, np.choose(k, [0.0, 1.0, 0.0, -1.0]), s)
    return c, s


def _rot(axis: int, angle) -> np.ndarray:
    c, s = _cos_sin(angle)
    T = np.zeros(c.shape + (4, 4))
    T[..., 3, 3] = 1.0
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    T[..., axis, axis] = 1.0
    T[..., i, i] = c
    T[..., i, j] = -s
    T[..., j, i] = s
    T[..., j, j] = c
    return T


def rot_x(angle) -> np.ndarray:
    """Rotation about X by ``angle`` (rad): scalar -> (4, 4), shape S -> S + (4, 4)."""
    return _rot(0, angle)


def rot_y(angle) -> np.ndarray:
    """Rotation about Y by ``angle`` (rad): scalar -> (4, 4), shape S -> S + (4, 4)."""
    return _rot(1, angle)


def rot_z(angle) -> np.ndarray:
    """Rotation about Z by ``angle`` (rad): scalar -> (4, 4), shape S -> S + (4, 4)."""
    return _rot(2, angle)


def trans(x, y=None, z=None) -> np.ndarray:
    """Translation: ``trans(x, y, z)`` or ``trans(xyz)`` with xyz of shape (..., 3), mm."""
    if y is None and z is None:
        v = np.asarray(x, dtype=np.float64)
    else:
        v = np.stack(np.broadcast_arrays(*(np.asarray(c, dtype=np.float64) for c in (x, y, z))), axis=-1)
    if v.shape[-1:] != (3,):
        raise InputError(f"translation must have 3 components (x, y, z in mm), got shape {v.shape}")
    T = np.zeros(v.shape[:-1] + (4, 4))
    T[..., :3, :3] = np.eye(3)
    T[..., :3, 3] = v
    T[..., 3, 3] = 1.0
    return T


def make_pose(R: np.ndarray, p) -> np.ndarray:
    """4x4 transform from a rotation R (..., 3, 3) and a translation p (..., 3) in mm."""
    R = np.asarray(R, dtype=np.float64)
    p = np.asarray(p, dtype=np.float64)
    shape = np.broadcast_shapes(R.shape[:-2], p.shape[:-1])
    T = np.zeros(shape + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = p
    T[..., 3, 3] = 1.0
    return T


def rigid_inverse(T: np.ndarray) -> np.ndarray:
    """Closed-form inverse of rigid transform(s) ``(..., 4, 4)``: [Rᵀ, −Rᵀp]."""
    T = np.asarray(T, dtype=np.float64)
    R = T[..., :3, :3]
    Rt = np.swapaxes(R, -1, -2)
    out = np.zeros_like(T)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def transform_points(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply T (4, 4) to points (n, 3) or (3,), mm -> same shape, mm."""
    T = np.asarray(T, dtype=np.float64)
    p = np.asarray(points, dtype=np.float64)
    return p @ T[:3, :3].T + T[:3, 3]


def orthonormality_error(R: np.ndarray) -> np.ndarray:
    """max-abs of RᵀR − I for R (..., 3, 3) (or the rotation part of (..., 4, 4))."""
    R = np.asarray(R, dtype=np.float64)
    if R.shape[-2:] == (4, 4):
        R = R[..., :3, :3]
    RtR = np.swapaxes(R, -1, -2) @ R
    return np.abs(RtR - _IDENTITY3).max(axis=(-2, -1))


def orthonormalize(T: np.ndarray) -> np.ndarray:
    """Nearest rotation (polar decomposition via SVD) of R (..., 3, 3) or T (..., 4, 4).

    Use it after long chains of products, where rounding slowly drifts R away
    from orthonormal; translations are left unchanged.
    """
    T = np.array(T, dtype=np.float64)
    R = T[..., :3, :3] if T.shape[-2:] == (4, 4) else T
    U, _, Vt = np.linalg.svd(R)
    d = np.sign(np.linalg.det(U @ Vt))
    U[..., :, 2] *= d[..., None]
    Rn = U @ Vt
    if T.shape[-2:] == (4, 4):
        T[..., :3, :3] = Rn
        return T
    return Rn


def rotation_angle(R: np.ndarray) -> np.ndarray:
    """Angle (rad, in [0, π]) of rotation(s) R (..., 3, 3), accurate also near 0 and π."""
    R = np.asarray(R, dtype=np.float64)
    if R.shape[-2:] == (4, 4):
        R = R[..., :3, :3]
    # 2 sin(θ) = |vee(R − Rᵀ)|, 2 cos(θ) = tr R − 1; atan2 avoids acos's loss near 0.
    v = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], axis=-1)
    s = np.linalg.norm(v, axis=-1)
    c = R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2] - 1.0
    return np.arctan2(s, c)


def rotation_vector(R: np.ndarray) -> np.ndarray:
    """Axis-angle vector (..., 3) of rotation(s) R (..., 3, 3); the angle (rad) is its norm.

    Below 90° the axis comes from the skew part (R − Rᵀ)/2 = sin θ·[k]ₓ; above, where
    sin θ shrinks towards π, from the symmetric part (R + Rᵀ)/2 − cos θ·I = (1 − cos θ)·k kᵀ,
    which stays well conditioned. At exactly π the sign of the axis is arbitrary.
    """
    R = np.asarray(R, dtype=np.float64)
    if R.shape[-2:] == (4, 4):
        R = R[..., :3, :3]
    v = 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], axis=-1)
    s = np.linalg.norm(v, axis=-1)
    c = 0.5 * (R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2] - 1.0)
    angle = np.arctan2(s, c)
    zero = s == 0.0
    out = v * np.where(zero, 0.0, angle / np.where(zero, 1.0, s))[..., None]
    obtuse = c < 0
    if np.any(obtuse):
        Ro = R[obtuse]
        B = 0.5 * (Ro + np.swapaxes(Ro, -1, -2)) - c[obtuse][..., None, None] * np.eye(3)
        idx = np.argmax(np.diagonal(B, axis1=-2, axis2=-1), axis=-1)
        axis = B[np.arange(len(idx)), :, idx]
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        sign = np.where(np.einsum("ij,ij->i", axis, v[obtuse]) < 0, -1.0, 1.0)
        out[obtuse] = axis * (sign * angle[obtuse])[..., None]
    return out


def check_transform(T, name: str = "transform", tol: float = RIGID_TOL) -> np.ndarray:
    """Validate rigid transform(s) ``(..., 4, 4)``; return them as float64.

    Raises InputError naming ``name`` when the shape is wrong, an entry is not
    finite, the bottom row is not [0, 0, 0, 1], or the rotation part is not
    orthonormal with determinant +1 within ``tol``.
    """
    try:
        T = np.array(T, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a 4x4 array of numbers: {exc}") from None
    if T.shape[-2:] != (4, 4):
        raise InputError(f"{name} must have shape (4, 4) or (n, 4, 4), got {T.shape}")
    if not np.isfinite(T).all():
        raise InputError(f"{name} contains NaN or inf; a rigid transform must be finite")
    if (np.abs(T[..., 3, :] - _BOTTOM_ROW) > tol).any():
        raise InputError(f"{name} bottom row must be [0, 0, 0, 1], got {T[..., 3, :].reshape(-1, 4)[0].tolist()}")
    err = orthonormality_error(T)
    if (err > tol).any():
        raise InputError(
            f"{name} rotation part is not orthonormal: max |RᵀR − I| = {float(np.max(err)):.3g} "
            f"(allowed ≤ {tol:g}); it must be a pure rotation without scale or shear"
        )
    if (np.linalg.det(T[..., :3, :3]) < 0).any():
        raise InputError(f"{name} rotation part has determinant −1 (a reflection); it must be a proper rotation")
    return T


def check_rotation(R, name: str = "rotation", tol: float = RIGID_TOL) -> np.ndarray:
    """Validate rotation matrix/matrices ``(..., 3, 3)``; return them as float64."""
    try:
        R = np.array(R, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a 3x3 array of numbers: {exc}") from None
    if R.shape[-2:] != (3, 3):
        raise InputError(f"{name} must have shape (3, 3), got {R.shape}")
    T = np.zeros(R.shape[:-2] + (4, 4))
    T[..., :3, :3] = R
    T[..., 3, 3] = 1.0
    check_transform(T, name, tol)
    return R
