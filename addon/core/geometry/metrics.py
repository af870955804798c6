"""Ground-truth error of a cloud: point-to-surface distances, their statistics, coverage.

Truth is either an analytic shape (:mod:`addon.core.geometry.shapes`, exact distances) or
a mesh: exact closest-point distances to its flat faces through libigl's AABB tree
(25 000 points against 82 000 faces in under a second, where trimesh's proximity query
took about 3 ms per point), signed (positive outside) where the mesh is closed, so that
a mesh part has a bias too. Without libigl (a Python it is not installed in; the extension ships it)
trimesh answers the same distances, unsigned and slower. Statistics are in micrometres.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from ..errors import InputError


OUTLIER_MM = 0.2  # a point farther than this from the part is an outlier (the real-parts goal's limit)


@dataclass(frozen=True)
class ErrorStats:
    """Point-to-surface error of n points, µm. bias: mean signed distance (NaN if unsigned)."""

    n: int
    rms_um: float
    mean_um: float
    p95_um: float
    max_um: float
    bias_um: float

    def as_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "ErrorStats":
        """From ``as_dict`` or its JSON, where NaN was written as null."""
        nan = float("nan")
        return cls(int(d["n"]), *(nan if d[k] is None else float(d[k])
                                  for k in ("rms_um", "mean_um", "p95_um", "max_um", "bias_um")))


def error_stats(distance_mm, signed_mm=None) -> ErrorStats:
    d = np.abs(np.asarray(distance_mm, dtype=np.float64).ravel())
    if d.size == 0:
        nan = float("nan")
        return ErrorStats(0, nan, nan, nan, nan, nan)
    bias = float(np.mean(signed_mm)) * 1e3 if signed_mm is not None else float("nan")
    return ErrorStats(int(d.size), float(np.sqrt(np.mean(d * d))) * 1e3, float(np.mean(d)) * 1e3,
                      float(np.percentile(d, 95)) * 1e3, float(d.max()) * 1e3, bias)


def _check_mesh(mesh) -> trimesh.Trimesh:
    if not isinstance(mesh, trimesh.Trimesh):
        raise InputError(f"ground truth must be a trimesh.Trimesh or an analytic shape, got {type(mesh).__name__}")
    if len(mesh.faces) == 0:
        raise InputError("ground-truth mesh has no faces")
    if not np.all(np.isfinite(mesh.vertices)):
        raise InputError("ground-truth mesh has NaN or inf vertices")
    return mesh


def distances(points, truth) -> tuple[np.ndarray, np.ndarray | None]:
    """(unsigned distance (n,) mm, signed distance (n,) mm or None) from points (n, 3) to the truth."""
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if hasattr(truth, "signed_distance"):
        s = truth.signed_distance(P)
        return np.abs(s), s
    mesh = _check_mesh(truth)
    if len(P) == 0:
        return np.zeros(0), None
    return mesh_distances(P, mesh)


def has_inside(mesh: trimesh.Trimesh) -> bool:
    """Whether distances to ``mesh`` can be signed (inside negative): a closed, consistently
    wound mesh, and libigl to sign them (looked for on each call: once imported, a dictionary
    lookup; a Python without it may be the Blender the extension runs in)."""
    try:
        import igl  # noqa: F401
    except ImportError:
        return False
    return bool(mesh.is_watertight and mesh.is_winding_consistent)


def mesh_distances(points: np.ndarray, mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray | None]:
    """(unsigned (n,) mm, signed (n,) mm positive outside, or None for an open mesh) from
    points (n, 3) to a mesh's faces: exact closest points on the triangles."""
    P = np.ascontiguousarray(points, dtype=np.float64)
    if has_inside(mesh):
        # A closed, consistently wound mesh: the pseudonormal sign is exact (the fast winding
        # number's distances are approximate, up to 37 µm off on a box).
        import igl

        V, F = _igl_mesh(mesh)
        signed = np.asarray(igl.signed_distance(P, V, F, sign_type=igl.SIGNED_DISTANCE_TYPE_PSEUDONORMAL)[0])
        return np.abs(signed), signed
    return _closest_faces(P, mesh)[0], None


def unsigned_distances(points, mesh: trimesh.Trimesh) -> np.ndarray:
    """(n,) mm: exact distances from points (n, 3) to a mesh's faces, unsigned (no inside
    is asked for, so no signing structure is built)."""
    P = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3))
    return _closest_faces(P, mesh)[0] if len(P) else np.zeros(0)


def _igl_mesh(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    return (np.ascontiguousarray(mesh.vertices, dtype=np.float64),
            np.ascontiguousarray(mesh.faces, dtype=np.int64))


def _closest_faces(P: np.ndarray, mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    """(unsigned distance (n,) mm, index (n,) of the closest face) of points P (n, 3) to a
    mesh: libigl's AABB tree, or trimesh's proximity query where libigl is missing."""
    try:
        import igl
    except ImportError:
        _, dist, face = trimesh.proximity.closest_point(mesh, P)
        return np.asarray(dist), np.asarray(face, dtype=np.int64)
    d2, face = igl.point_mesh_squared_distance(P, *_igl_mesh(mesh))[:2]
    return np.sqrt(np.maximum(np.asarray(d2), 0.0)), np.asarray(face, dtype=np.int64).ravel()


class NearMesh:
    """Which points lie within a distance of one mesh (a fixture), asked again and again: the
    mesh's AABB tree (libigl) is built once, and points farther than the distance from the
    mesh's bounding box are answered without it."""

    def __init__(self, mesh: trimesh.Trimesh):
        self.mesh = mesh
        self.lo, self.hi = (np.asarray(b, dtype=np.float64) for b in mesh.bounds)
        self.V, self.F = _igl_mesh(mesh)
        try:
            import igl
        except ImportError:
            self.tree = None
        else:
            self.tree = igl.AABB()
            self.tree.init(self.V, self.F)

    def within(self, points, limit_mm) -> np.ndarray:
        """(n,) bool: points (n, 3) nearer the mesh than ``limit_mm`` (a number or (n,))."""
        P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        limit = np.broadcast_to(np.asarray(limit_mm, dtype=np.float64), (len(P),))
        to_box = np.linalg.norm(np.maximum(np.maximum(self.lo - P, P - self.hi), 0.0), axis=1)
        out = np.zeros(len(P), bool)
        near = np.flatnonzero(to_box < limit)
        if not len(near):
            return out
        Q = np.ascontiguousarray(P[near])
        if self.tree is None:
            d = _closest_faces(Q, self.mesh)[0]
        else:
            d = np.sqrt(np.maximum(np.asarray(self.tree.squared_distance(self.V, self.F, Q)[0]), 0.0))
        out[near] = d < limit[near]
        return out


def evaluate(points, truth) -> ErrorStats:
    d, s = distances(points, truth)
    return error_stats(d, s)


SAME_SURFACE_DEG = 30.0  # a point or hit counts for the surface around it only where their faces turn less than this


def nearest_faces(points, mesh: trimesh.Trimesh) -> np.ndarray:
    """Index (n,) of the mesh face closest to each point."""
    P = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3))
    if len(P) == 0:
        return np.zeros(0, dtype=np.int64)
    return _closest_faces(P, mesh)[1]


def _near_on_same_surface(surface, surface_face, points, mesh, tolerance_mm: float) -> np.ndarray:
    """Per surface sample (m,): is one of ``points`` within ``tolerance_mm`` of it on the same
    piece of surface (the faces nearest the sample and the point turn less than
    SAME_SURFACE_DEG)? Across a sharp edge a point measures the face it lies on, not the
    face beyond the edge: a laser hit on a block's top 0.3 mm from its rim says nothing
    of the side below that rim."""
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    out = np.zeros(len(surface), bool)
    if len(P) == 0:
        return out
    near = cKDTree(P).query_ball_point(surface, r=tolerance_mm, return_sorted=False)
    counts = np.fromiter((len(a) for a in near), dtype=np.int64, count=len(near))
    if not counts.sum():
        return out
    which = np.repeat(np.arange(len(surface)), counts)
    point = np.fromiter((i for a in near for i in a), dtype=np.int64, count=int(counts.sum()))
    normals = mesh.face_normals
    point_face = nearest_faces(P, mesh)
    same = np.einsum("ij,ij->i", normals[point_face[point]], normals[surface_face[which]]) \
        >= np.cos(np.radians(SAME_SURFACE_DEG))
    out[np.unique(which[same])] = True
    return out


def coverage_of_measurable(points, mesh, reachable, tolerance_mm: float, samples: int = 20000,
                           seed: int = 0) -> tuple[float, float]:
    """(coverage, measurable share): of the mesh's surface within ``tolerance_mm`` of a
    ``reachable`` point on the same piece of surface (where the path's laser can measure:
    see ``footprint.measurable_points``), the fraction within ``tolerance_mm`` of a cloud
    point on the same piece of surface; and that surface's share of the whole mesh. Both
    estimated from the same ``samples`` points drawn uniformly over the area (seeded);
    (0, 0) where nothing is measurable. "The same piece of surface": see
    :func:`_near_on_same_surface`."""
    mesh = _check_mesh(mesh)
    surface, face = trimesh.sample.sample_surface(mesh, samples, seed=seed)
    R = np.asarray(reachable, dtype=np.float64).reshape(-1, 3)
    if len(R) == 0:
        return 0.0, 0.0
    measurable = _near_on_same_surface(surface, face, R, mesh, tolerance_mm)
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if not measurable.any() or len(P) == 0:
        return 0.0, float(np.mean(measurable))
    covered = _near_on_same_surface(surface[measurable], face[measurable], P, mesh, tolerance_mm)
    return float(np.mean(covered)), float(np.mean(measurable))


def coverage(points, mesh, tolerance_mm: float, samples: int = 20000, seed: int = 0) -> float:
    """Fraction of the mesh's area that lies within ``tolerance_mm`` of some cloud point on the
    same piece of surface (see :func:`_near_on_same_surface`).

    Estimated from ``samples`` points drawn uniformly over the area (seeded).
    """
    mesh = _check_mesh(mesh.mesh() if hasattr(mesh, "mesh") and not isinstance(mesh, trimesh.Trimesh) else mesh)
    if tolerance_mm <= 0 or not np.isfinite(tolerance_mm):
        raise InputError(f"coverage tolerance must be a positive number of mm, got {tolerance_mm}")
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(P) == 0:
        return 0.0
    surface, face = trimesh.sample.sample_surface(mesh, samples, seed=seed)
    return float(np.mean(_near_on_same_surface(surface, face, P, mesh, tolerance_mm)))
