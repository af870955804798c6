"""Analytic workpiece shapes with exact ground truth: plane patch, sphere, closed cylinder.

Each shape lives in its own local frame, placed by ``pose`` (shape -> table/world,
(4, 4), mm). ``signed_distance`` is exact (positive outside, negative inside;
for the plane patch, positive on the +Z side); ``mesh()`` gives a trimesh for
rendering, coverage sampling and mesh-based checks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import trimesh

from ..errors import InputError
from ..kinematics.transforms import check_transform, rigid_inverse

# How far the flat facets of a built-in round shape may lie inside the exact shape its error
# is measured against (that much of the error is the drawing's, not the scanner's): the
# meshes take as many facets as keep under it, up to a size (see facet_sag_bound_mm).
FACET_SAG_MM = 0.0025
SPHERE_SAG_PER_MM = {6: 2.1e-3 / 30.0, 7: 2.1e-3 / 30.0 / 4}  # the deepest sag per mm of radius (icosphere)
MAX_CYLINDER_SECTIONS = 4096


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

    def facet_sag_bound_mm(self) -> float:
        """About how far the default mesh's flat facets lie inside the exact shape at most (0
        for a shape of flat faces)."""
        return 0.0


@dataclass(frozen=True, eq=False)
class Sphere(_Shape):
    radius_mm: float = 25.0

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "radius_mm", _positive("sphere radius_mm", self.radius_mm))

    def signed_distance(self, points) -> np.ndarray:
        return np.linalg.norm(self.to_local(points), axis=1) - self.radius_mm

    def _local_mesh(self, subdivisions: int | None = None) -> trimesh.Trimesh:
        # Subdivision 6 (81 920 faces): for r = 30 mm the flat facets lie up to 2.1 µm
        # inside the sphere, 1.35 µm on average over its surface, which the error measured
        # against the exact sphere carries as a bias; subdivision 5: up to 8.5 µm, 5.5 µm on
        # average. Each subdivision quarters the sag: a sphere too large for subdivision 6 to
        # keep it under FACET_SAG_MM takes 7 (327 680 faces), and beyond that says so (facet_sag_mm).
        subdivisions = self._subdivisions() if subdivisions is None else subdivisions
        return trimesh.creation.icosphere(subdivisions=subdivisions, radius=self.radius_mm)

    def _subdivisions(self) -> int:
        return 6 if self.radius_mm * SPHERE_SAG_PER_MM[6] <= FACET_SAG_MM else 7

    def facet_sag_bound_mm(self) -> float:
        return self.radius_mm * SPHERE_SAG_PER_MM[self._subdivisions()]


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

    def _local_mesh(self, sections: int | None = None) -> trimesh.Trimesh:
        # 256 sides: for r = 30 mm the flat sides lie up to 2.3 µm inside the cylinder; a larger
        # one takes as many more as keep that under FACET_SAG_MM (sag = r (1 − cos(π / n))).
        sections = self._sections() if sections is None else sections
        m = trimesh.creation.cylinder(radius=self.radius_mm, height=self.height_mm, sections=sections)
        m.apply_translation([0.0, 0.0, self.height_mm / 2])
        return m

    def _sections(self) -> int:
        need = math.pi / math.acos(max(1.0 - FACET_SAG_MM / self.radius_mm, -1.0))
        return int(min(max(256, 8 * math.ceil(need / 8)), MAX_CYLINDER_SECTIONS))

    def facet_sag_bound_mm(self) -> float:
        return self.radius_mm * (1.0 - math.cos(math.pi / self._sections()))


@dataclass(frozen=True, eq=False)
class StepBlock(_Shape):
    """A staircase block on the local XY plane: ``steps`` columns along X, each
    ``step_mm`` deep, heights ``heights_mm`` (descending), all ``width_mm`` wide in Y,
    centred on the origin in X and Y, standing on z = 0.

    Outside, the exact distance to a union of boxes is the smallest distance to any of
    them. Inside it is not (that is the distance to the faces the columns share, inside
    the part): there the block is a prism along Y, and the depth is the nearer of its
    profile's edges in XZ and its two ends in Y.
    """

    heights_mm: tuple = (45.0, 30.0, 15.0)
    step_mm: float = 25.0
    width_mm: float = 50.0

    def __post_init__(self) -> None:
        super().__post_init__()
        h = tuple(_positive("step height", float(v)) for v in self.heights_mm)
        if not h or any(b >= a for a, b in zip(h, h[1:])):
            raise InputError(f"heights_mm: the step heights must be positive and strictly descending, got "
                             f"[{', '.join(f'{v:g}' for v in h)}]")
        object.__setattr__(self, "heights_mm", h)
        object.__setattr__(self, "step_mm", _positive("step depth", self.step_mm))
        object.__setattr__(self, "width_mm", _positive("step block width", self.width_mm))

    def _boxes(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """(min corner, max corner) of each column, local frame."""
        x0 = -len(self.heights_mm) * self.step_mm / 2
        w = self.width_mm / 2
        return [(np.array([x0 + i * self.step_mm, -w, 0.0]), np.array([x0 + (i + 1) * self.step_mm, w, h]))
                for i, h in enumerate(self.heights_mm)]

    def signed_distance(self, points) -> np.ndarray:
        p = self.to_local(points)
        best = np.full(len(p), np.inf)
        for lo, hi in self._boxes():
            c, half = (lo + hi) / 2, (hi - lo) / 2
            q = np.abs(p - c) - half
            outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
            inside = np.minimum(q.max(axis=1), 0.0)
            best = np.minimum(best, outside + inside)
        within = best <= 0  # (0 on a face the columns share, inside the part)
        if within.any():
            q = p[within]
            ring = self._profile()
            a, b = ring, np.roll(ring, -1, axis=0)  # the profile's edges a -> b, in XZ
            ab = b - a
            xz = q[:, [0, 2]][:, None, :]
            t = np.clip(np.einsum("mkj,kj->mk", xz - a, ab) / np.einsum("kj,kj->k", ab, ab), 0.0, 1.0)
            to_edge = np.linalg.norm(xz - (a + t[..., None] * ab), axis=2).min(axis=1)
            best[within] = -np.minimum(to_edge, self.width_mm / 2 - np.abs(q[:, 1]))
        return best

    def _profile(self) -> np.ndarray:
        """(n, 2) the block's outline in XZ, counter-clockwise: along the bottom, then up and
        left over the stairs."""
        boxes = self._boxes()
        x = [b[0][0] for b in boxes] + [boxes[-1][1][0]]
        h = self.heights_mm
        profile = [(x[0], 0.0), (x[-1], 0.0)]
        for i in range(len(h) - 1, -1, -1):
            profile += [(x[i + 1], h[i]), (x[i], h[i])]
        return np.array(profile)

    def _local_mesh(self) -> trimesh.Trimesh:
        # The XZ profile is star-shaped from its corner (x0, 0) (heights descend), so a
        # fan triangulates each side; risers, treads, ends and bottom are quads.
        w = self.width_mm / 2
        ring = self._profile()
        n = len(ring)
        verts = np.vstack([np.column_stack([ring[:, 0], np.full(n, -w), ring[:, 1]]),
                           np.column_stack([ring[:, 0], np.full(n, w), ring[:, 1]])])
        faces = []
        for i in range(1, n - 1):  # side fans (front y = −w faces −Y, back faces +Y)
            faces.append([0, i + 1, i])
            faces.append([n, n + i, n + i + 1])
        for i in range(n):  # the band around the profile
            j = (i + 1) % n
            faces.append([i, j, n + j])
            faces.append([i, n + j, n + i])
        m = trimesh.Trimesh(verts, np.array(faces), process=True)
        trimesh.repair.fix_normals(m)
        return m
