"""Analytic workpiece shapes with exact ground truth: plane patch, sphere, closed cylinder.

Each shape lives in its own local frame, placed by ``pose`` (shape -> table/world,
(4, 4), mm). ``signed_distance`` is exact (positive outside, negative inside;
for the plane patch, positive on the +Z side); ``mesh()`` gives a trimesh for
rendering, coverage sampling and mesh-based checks.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import trimesh

from .errors import InputError
from .transforms import check_transform, rigid_inverse


def _positive(name: str, value: float) -> float:
    if isinstance(value, bool) or not np.isfinite(value) or value <= 0:
        raise InputError(f"{name} must be a positive finite number of millimetres, got {value!r}")
    return float(value)


@dataclass(frozen=True, eq=False)
class _Shape:
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))

    def __post_init__(self) -> None:
        object.__setattr__(self, "pose", check_transform(self.pose, f"{type(self).__name__} pose"))

    def to_local(self, points) -> np.ndarray:
        P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        T = rigid_inverse(self.pose)
        return P @ T[:3, :3].T + T[:3, 3]

    def distance(self, points) -> np.ndarray:
        """Unsigned distance (n,) mm from points (n, 3) to the surface."""
        return np.abs(self.signed_distance(points))

    def mesh(self, **kwargs) -> trimesh.Trimesh:
        m = self._local_mesh(**kwargs)
        m.apply_transform(self.pose)
        return m


@dataclass(frozen=True, eq=False)
class Sphere(_Shape):
    radius_mm: float = 25.0

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "radius_mm", _positive("sphere radius_mm", self.radius_mm))

    def signed_distance(self, points) -> np.ndarray:
        return np.linalg.norm(self.to_local(points), axis=1) - self.radius_mm

    def _local_mesh(self, subdivisions: int = 5) -> trimesh.Trimesh:
        return trimesh.creation.icosphere(subdivisions=subdivisions, radius=self.radius_mm)


@dataclass(frozen=True, eq=False)
class PlanePatch(_Shape):
    """A rectangle |x| ≤ width/2, |y| ≤ height/2 in the local z = 0 plane, facing +Z."""

    width_mm: float = 100.0
    height_mm: float = 100.0

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "width_mm", _positive("plane width_mm", self.width_mm))
        object.__setattr__(self, "height_mm", _positive("plane height_mm", self.height_mm))

    def signed_distance(self, points) -> np.ndarray:
        p = self.to_local(points)
        dx = np.maximum(np.abs(p[:, 0]) - self.width_mm / 2, 0.0)
        dy = np.maximum(np.abs(p[:, 1]) - self.height_mm / 2, 0.0)
        d = np.sqrt(dx * dx + dy * dy + p[:, 2] ** 2)
        return np.where(p[:, 2] < 0, -d, d)

    def _local_mesh(self) -> trimesh.Trimesh:
        w, h = self.width_mm / 2, self.height_mm / 2
        v = np.array([[-w, -h, 0], [w, -h, 0], [w, h, 0], [-w, h, 0]], dtype=np.float64)
        return trimesh.Trimesh(v, np.array([[0, 1, 2], [0, 2, 3]]), process=False)


@dataclass(frozen=True, eq=False)
class Cylinder(_Shape):
    """A closed cylinder on the local XY plane: axis +Z, 0 ≤ z ≤ height."""

    radius_mm: float = 20.0
    height_mm: float = 60.0

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "radius_mm", _positive("cylinder radius_mm", self.radius_mm))
        object.__setattr__(self, "height_mm", _positive("cylinder height_mm", self.height_mm))

    def signed_distance(self, points) -> np.ndarray:
        p = self.to_local(points)
        rho = np.hypot(p[:, 0], p[:, 1])
        z = p[:, 2]
        dr = rho - self.radius_mm
        dz = np.maximum(-z, z - self.height_mm)  # ≤ 0 between the caps
        outside = np.hypot(np.maximum(dr, 0.0), np.maximum(dz, 0.0))
        inside = np.maximum(dr, dz)  # both negative: the nearer wall, negated
        return np.where((dr > 0) | (dz > 0), outside, inside)

    def _local_mesh(self, sections: int = 256) -> trimesh.Trimesh:
        m = trimesh.creation.cylinder(radius=self.radius_mm, height=self.height_mm, sections=sections)
        m.apply_translation([0.0, 0.0, self.height_mm / 2])
        return m
