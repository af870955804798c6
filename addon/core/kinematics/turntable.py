"""The rotary table (paper Eq. 4–5): the workpiece frame R and its angle θ_R.

    T_0^R = R_Z(−θ_R) · T(a_R, 0, d_R)          base2table: robot base (world) -> table
    T_R^0 = T(−a_R, 0, −d_R) · R_Z(θ_R)          table2base: table -> robot base (world)

with a_R = −500 mm and d_R = −200 mm in the paper: the table centre sits 500 mm in
front of the robot and 200 mm above its base, and a point fixed on the table turns
by +θ_R about the table's Z axis (parallel to the robot's Z) as the table turns.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .transforms import rot_z, trans

PAPER_A_R_MM = -500.0
PAPER_D_R_MM = -200.0


@dataclass(frozen=True)
class Turntable:
    """Placement of the rotary table relative to the robot base (Eq. 4), mm."""

    a_mm: float = PAPER_A_R_MM
    d_mm: float = PAPER_D_R_MM

    def __post_init__(self) -> None:
        for name in ("a_mm", "d_mm"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating)) or not np.isfinite(v):
                raise InputError(f"turntable {name} must be a finite number of millimetres, got {v!r}")
            object.__setattr__(self, name, float(v))

    @staticmethod
    def _angle(theta_rad) -> np.ndarray:
        th = np.asarray(theta_rad, dtype=np.float64)
        if not np.all(np.isfinite(th)):
            raise InputError(f"table angle must be finite (radians), got {theta_rad}")
        return th

    def base2table(self, theta_rad) -> np.ndarray:
        """T_0^R (Eq. 4): scalar θ -> (4, 4); θ of shape S -> S + (4, 4)."""
        th = self._angle(theta_rad)
        return rot_z(-th) @ trans(self.a_mm, 0.0, self.d_mm)

    def table2base(self, theta_rad) -> np.ndarray:
        """T_R^0 (Eq. 5), the closed-form inverse of :meth:`base2table`."""
        th = self._angle(theta_rad)
        return trans(-self.a_mm, 0.0, -self.d_mm) @ rot_z(th)


TABLE_RADIUS_MM = 150.0
TABLE_THICKNESS_MM = 20.0
TABLE_SECTIONS = 128  # the disc's sides, as drawn and cast


def table_top_mesh(radius_mm: float = TABLE_RADIUS_MM, thickness_mm: float = TABLE_THICKNESS_MM):
    """The table's disc in the table frame: its top face is z = 0 (a trimesh)."""
    import trimesh

    disc = trimesh.creation.cylinder(radius=radius_mm, height=thickness_mm, sections=TABLE_SECTIONS)
    disc.apply_translation([0.0, 0.0, -thickness_mm / 2])
    return disc


def beyond_table(what: str, nearest_mm: float) -> str | None:
    """"``what`` lies wholly beyond the table ...", where its nearest point to the table's axis,
    seen from above, is ``nearest_mm`` (more than the table's radius and a millimetre); None
    where it reaches over the table."""
    if nearest_mm <= TABLE_RADIUS_MM + 1.0:
        return None
    return (f"{what} lies wholly beyond the table (its nearest point {nearest_mm:.0f} mm from the table's axis, the "
            f"table's radius {TABLE_RADIUS_MM:g} mm)")


def box_beyond_table(lo, hi) -> str | None:
    """Why a part's bounding box (table frame, mm) cannot hold a part on the table: it lies
    wholly beyond the table's rim, seen from above (None where it reaches over the table)."""
    nearest = float(np.hypot(*np.clip(0.0, np.asarray(lo, float)[:2], np.asarray(hi, float)[:2])))
    why = beyond_table("the box", nearest)
    return None if why is None else f"{why}: a part on the table lies within {TABLE_RADIUS_MM:g} mm of it"


def nearest_to_axis_mm(mesh) -> float:
    """How near any point of ``mesh`` (table frame) comes to the table's axis, seen from above:
    0 where its outline covers the axis. Exact on the triangles' projections, not only their
    corners (a bar across the table whose ends lie beyond its rim passes over the axis)."""
    T = np.asarray(mesh.triangles, dtype=np.float64)[:, :, :2]
    if not len(T):
        return float("inf")
    a, b, c = T[:, 0], T[:, 1], T[:, 2]

    def cross(p, q):
        return p[:, 0] * q[:, 1] - p[:, 1] * q[:, 0]

    s = np.column_stack([cross(b - a, -a), cross(c - b, -b), cross(a - c, -c)])
    if np.any((s >= 0).all(axis=1) | (s <= 0).all(axis=1)):
        return 0.0
    nearest = np.inf
    for p, q in ((a, b), (b, c), (c, a)):
        e = q - p
        t = np.clip(-np.einsum("ij,ij->i", p, e) / np.maximum(np.einsum("ij,ij->i", e, e), 1e-300), 0.0, 1.0)
        nearest = min(nearest, float(np.linalg.norm(p + t[:, None] * e, axis=1).min()))
    return nearest
