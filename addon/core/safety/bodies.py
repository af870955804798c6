"""The cell's solid bodies for collision checks, in python-fcl.

Bodies and what carries them:

- ``link 1`` … ``link 6``: DH frame k (the rig's link meshes where it has them,
  otherwise the cylinders the Blender cell draws: ``kinematics.link_shapes``);
- ``robot base``: DH frame 0, where the rig gives the base's geometry (a DH rig's
  ``base_mesh``, a URDF's base link and what is fixed to it);
- ``probe``: the probe frame (flange · T_L^6): its housing and the camera and laser
  heads (``Probe.body_boxes``);
- ``table``: the table's disc, in the table frame;
- ``workpiece``: the part's mesh, in the table frame (it turns with the table);
- fixtures: meshes from the scan config, on the table or fixed in the world.

Pairs checked, with the clearance the config asks for: every moving robot body (links
and probe) against the table, the workpiece and the fixtures; what the table carries
(the workpiece, table fixtures) against what stands still (the robot's base, world
fixtures), as a table turn swings it round. Robot bodies against each other (links two
or more apart, the probe against links 1–4 and the base) must not touch. The disc turns
into itself, so neither the base nor a world fixture comes nearer it as it turns: a world
fixture reaching into it is refused once, when the model is made (clearance.py), and the
base is not checked against it (where it stands is the cell's layout). Pairs of robot bodies that touch in the rig's rest pose
(q = 0) are part of its design and are not checked.

A mesh in FCL is a surface: a body wholly inside a closed part would be reported
as near its surface, not inside it. So where a robot body comes near a closed
mesh, the centres of its shapes are also tested for being inside (trimesh's ray test),
and a body inside counts as touching.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import trimesh

from ..errors import InputError, ScannerError
from ..kinematics.link_shapes import base_mesh, link_cylinders, link_mesh
from ..kinematics.robot import N_JOINTS, Robot
from ..kinematics.turntable import TABLE_RADIUS_MM, TABLE_THICKNESS_MM, Turntable
from ..optics.probe import Probe


def _fcl():
    try:
        import fcl
    except ImportError as exc:  # pragma: no cover - the set-up installs it
        raise ScannerError("collision checks need python-fcl (pip install python-fcl; the README's set-up "
                           f"installs it): {exc}") from None
    return fcl


def _pose_z_to(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """(4, 4) pose whose z axis runs from p0 to p1, centred between them."""
    z = p1 - p0
    z = z / np.linalg.norm(z)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = 0.5 * (p0 + p1)
    return T


@dataclass
class Shape:
    """One FCL geometry rigid with its body: ``local`` its pose in the body's frame; ``centre``
    and ``radius`` its bounding sphere in that frame."""

    geometry: object
    local: np.ndarray
    centre: np.ndarray
    radius: float
    obj: object = None
    vertices: np.ndarray | None = None  # a mesh's, in the shape's frame
    hull_vertices: np.ndarray | None = None  # the corners of a mesh's convex hull


@dataclass
class Body:
    """``carrier``: "link1".."link6", "probe", "table" or "world"; ``mesh``: the closed mesh of
    a solid given as a surface (for the inside test), in the body's frame."""

    name: str
    carrier: str
    shapes: list[Shape]
    robot: bool
    mesh: trimesh.Trimesh | None = None
    centre: np.ndarray = field(default_factory=lambda: np.zeros(3))
    radius: float = 0.0
    support: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    support_r: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        if self.shapes:
            cs = np.array([s.local[:3, :3] @ s.centre + s.local[:3, 3] for s in self.shapes])
            self.centre = 0.5 * (cs.min(axis=0) + cs.max(axis=0))
            self.radius = float(max(np.linalg.norm(c - self.centre) + s.radius for c, s in zip(cs, self.shapes)))
            pts, rs = zip(*(_support(s) for s in self.shapes))
            self.support, self.support_r = np.vstack(pts), np.concatenate(rs)


UNIT_CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64)


def _support(s: Shape) -> tuple[np.ndarray, np.ndarray]:
    """Points (k, 3) in the body's frame and margins (k,) whose balls hold the shape: a box's
    corners, a cylinder's two end centres with its radius, a mesh's bounding-box corners."""
    name = type(s.geometry).__name__
    corners = UNIT_CORNERS
    if name == "Box":
        local, r = corners * (np.asarray(s.geometry.side, dtype=np.float64) / 2), np.zeros(8)
    elif name == "Cylinder":
        local = np.array([[0.0, 0.0, -s.geometry.lz / 2], [0.0, 0.0, s.geometry.lz / 2]])
        r = np.full(2, float(s.geometry.radius))
    else:
        lo, hi = s.vertices.min(axis=0), s.vertices.max(axis=0)
        local, r = (lo + hi) / 2 + corners * (hi - lo) / 2, np.zeros(8)
    return local @ s.local[:3, :3].T + s.local[:3, 3], r


def _shape(fcl, geometry, local: np.ndarray, centre, radius: float) -> Shape:
    s = Shape(geometry, np.asarray(local, dtype=np.float64), np.asarray(centre, dtype=np.float64), float(radius))
    s.obj = fcl.CollisionObject(geometry, fcl.Transform())
    return s


def mesh_shape(fcl, mesh: trimesh.Trimesh, local=None) -> Shape:
    if len(mesh.faces) == 0 or not np.isfinite(mesh.vertices).all():
        # (FCL crashes the process on a model without triangles: a URDF cylinder of radius 0)
        raise InputError("a collision mesh has no triangles, or coordinates that are not finite; the loaders "
                         "refuse such meshes: give the part, fixture or link a surface")
    bvh = fcl.BVHModel()
    bvh.beginModel(len(mesh.vertices), len(mesh.faces))
    bvh.addSubModel(np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64))
    bvh.endModel()
    lo, hi = mesh.bounds
    centre = 0.5 * (lo + hi)
    s = _shape(fcl, bvh, np.eye(4) if local is None else local, centre, float(np.linalg.norm(hi - lo) / 2))
    s.vertices = np.asarray(mesh.vertices, dtype=np.float64)
    s.hull_vertices = _enclosing_points(s.vertices)
    return s


HULL_POINTS_MAX = 64


def _enclosing_points(vertices: np.ndarray) -> np.ndarray:
    """Few points whose convex hull holds every vertex: the hull's corners where they are few,
    else the corners of the 26-sided polytope bounding the vertices along the axes and the
    face and corner diagonals (a few per cent larger than a round part, and fast for GJK)."""
    from scipy.spatial import ConvexHull, HalfspaceIntersection

    unique = np.unique(vertices, axis=0)
    if len(unique) < 5:  # fewer points than qhull needs: they are their own hull
        return unique
    corners = unique[ConvexHull(unique, qhull_options="QJ").vertices]  # QJ: a flat plate has a hull too
    if len(corners) <= HULL_POINTS_MAX:
        return corners
    dirs = np.array([d for d in np.ndindex(3, 3, 3) if d != (1, 1, 1)], dtype=np.float64) - 1.0
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    reach = (corners @ dirs.T).max(axis=0)
    inside = corners.mean(axis=0)
    pad = 1e-6 * max(float(np.ptp(corners, axis=0).max()), 1.0)
    halfspaces = np.column_stack([dirs, -(reach + pad)])
    return HalfspaceIntersection(halfspaces, inside).intersections


ROBOT_BASE = "robot base"
MAX_BASE_PIECES = 16  # separate pieces of a robot's base checked apart; more stay one body


def robot_bodies(robot: Robot, probe: Probe) -> list[Body]:
    """Links 1..6, the probe, and the robot's base where the rig gives its geometry."""
    fcl = _fcl()
    bodies = []
    base = base_mesh(robot, collision=True)
    if base is not None and len(base.faces):
        # One body per separate piece (a gantry's two side frames): the bounds and hulls of the
        # whole would hold the work area between them, and decide nothing. Split where the
        # vertices are shared (a textured file keeps them apart at its seams); a base in more
        # pieces than that stays one body.
        joined = base.copy()
        joined.merge_vertices(merge_tex=True, merge_norm=True)
        pieces = joined.split(only_watertight=False) if len(joined.faces) > 1 else [base]
        if not 1 <= len(pieces) <= MAX_BASE_PIECES:
            pieces = [base]
        pieces = sorted(pieces, key=lambda m: tuple(np.round(m.bounds[0], 6)))
        for k, piece in enumerate(pieces):
            name = ROBOT_BASE if len(pieces) == 1 else f"{ROBOT_BASE} (piece {k + 1})"
            bodies.append(Body(name, "link0", [mesh_shape(fcl, piece)], True, piece if piece.is_watertight else None))
    cylinders = link_cylinders(robot)
    for k in range(N_JOINTS):
        name = f"link {k + 1}"
        mesh = link_mesh(robot, k, collision=True)
        if mesh is not None:
            # a closed link mesh also tells a part or fixture wholly inside it (a hollow BVH
            # alone called a part inside a URDF link's cylinder 44 mm clear)
            bodies.append(Body(name, f"link{k + 1}", [mesh_shape(fcl, mesh)], True,
                               mesh if mesh.is_watertight else None))
            continue
        shapes = []
        for c in cylinders[k]:
            length = c.length_mm
            shapes.append(_shape(fcl, fcl.Cylinder(c.radius_mm, length), _pose_z_to(c.p0, c.p1), np.zeros(3),
                                 float(np.hypot(c.radius_mm, length / 2))))
        bodies.append(Body(name, f"link{k + 1}", shapes, True))
    shapes = []
    for _, extents, centre in probe.body_boxes():
        T = np.eye(4)
        T[:3, 3] = centre
        shapes.append(_shape(fcl, fcl.Box(*extents), T, np.zeros(3), float(np.linalg.norm(extents) / 2)))
    bodies.append(Body("probe", "probe", shapes, True))
    return bodies


def environment_bodies(workpiece_mesh: trimesh.Trimesh | None, fixtures=()) -> list[Body]:
    """The table, the workpiece (table frame) and fixtures ((name, mesh, "table" | "world"))."""
    fcl = _fcl()
    T = np.eye(4)
    T[2, 3] = -TABLE_THICKNESS_MM / 2
    table = Body("table", "table", [_shape(fcl, fcl.Cylinder(TABLE_RADIUS_MM, TABLE_THICKNESS_MM), T, np.zeros(3),
                                           float(np.hypot(TABLE_RADIUS_MM, TABLE_THICKNESS_MM / 2)))], False)
    bodies = [table]
    if workpiece_mesh is not None and len(workpiece_mesh.faces):
        closed = workpiece_mesh if workpiece_mesh.is_watertight else None
        bodies.append(Body("workpiece", "table", [mesh_shape(fcl, workpiece_mesh)], False, closed))
    for name, mesh, on in fixtures:
        bodies.append(Body(name, "table" if on == "table" else "world", [mesh_shape(fcl, mesh)], False,
                           mesh if mesh.is_watertight else None))
    return bodies


def carrier_poses(robot: Robot, table: Turntable, q: np.ndarray, table_rad: np.ndarray) -> dict[str, np.ndarray]:
    """World poses (n, 4, 4) of every carrier at joints q (n, 6) and table angles (n,)."""
    frames = robot.link_frames(q)
    out = {f"link{k}": frames[:, k] for k in range(0, N_JOINTS + 1)}  # link0: the base, DH frame 0
    out["probe"] = frames[:, N_JOINTS] @ robot.tool
    out["table"] = table.table2base(table_rad)
    out["world"] = np.broadcast_to(np.eye(4), (len(q), 4, 4))
    return out
