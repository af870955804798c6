"""Collision checks along a path: every waypoint and the motion between them.

A path is a list of joint vectors and table angles. Between two of them the robot
moves in joint space and the table turns, both linearly; the motion is sampled so
that no point of the arm, the probe or anything on the table moves more than
``STEP_MM`` between two samples (a bound from each joint's lever arm and the table
radius), and every sample is checked.

Distances are exact (python-fcl: GJK on the primitives, BVH distance on meshes),
found cheaply: a bounding-sphere bound in numpy for every pair and sample, then a
convex-hull distance (a lower bound of the exact one, GJK in a few µs), then the
exact distance only where those bounds cannot decide. The smallest clearance of
each path entry, over its waypoints (the poses where the probe measures), is found by
branch and bound over the same lower bounds, so it is exact too (to NEAREST_TOL_MM, 4 µm:
the hulls are thickened by a hair, see _convex); the motion between
waypoints is checked against the allowed clearance, not searched for its minimum.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
import trimesh

from ..errors import InputError
from ..kinematics.robot import N_JOINTS, Robot
from ..kinematics.turntable import Turntable
from ..optics.probe import Probe
from .bodies import ROBOT_BASE, UNIT_CORNERS, Body, _fcl, carrier_poses, environment_bodies, robot_bodies

STEP_MM = 1.0             # no point moves farther than this between two checked samples
DEFAULT_CLEARANCE_MM = 2.0
CONTACT_MM = 1e-6         # robot bodies closer than this to each other touch


@dataclass(frozen=True)
class Contact:
    """Two bodies at one sample of the path. ``position``: the path position (waypoint index,
    fractional between waypoints); ``distance_mm`` ≤ 0 where they touch or overlap;
    ``point_a`` / ``point_b``: their nearest points (table frame, mm; NaN where they overlap)."""

    distance_mm: float
    body_a: str
    body_b: str
    position: float
    point_a: tuple = (math.nan, math.nan, math.nan)
    point_b: tuple = (math.nan, math.nan, math.nan)
    # A Scanner's move (move_to, turn_table) between frames: ``position`` is then the frame the
    # next measurement takes, which the move does not reach (a sweep moves on from it).
    on_move: bool = False

    @property
    def frame(self) -> int:
        """The waypoint at or just after the sample."""
        return int(math.ceil(self.position - 1e-9))

    def as_dict(self) -> dict:
        def xyz(p):
            return [None if not math.isfinite(v) else round(float(v), 3) for v in p]

        out = {"clearance_mm": round(float(self.distance_mm), 4), "bodies": [self.body_a, self.body_b],
               "frame": self.frame, "position": round(float(self.position), 4),
               "points_mm": [xyz(self.point_a), xyz(self.point_b)]}
        if self.on_move:
            out["on_move"] = True
        return out


@dataclass
class PathClearance:
    """``collisions``: per offending pair, the first and last sample of its first run of samples
    below the allowed clearance; ``nearest``: the smallest clearance to the table, the
    workpiece or a fixture at the waypoints of each path entry (segment number: Contact);
    ``deepest``: per collision, the sample of its run where the bodies come nearest;
    ``samples``: how many poses were checked; ``exact_queries``: how many exact distances
    that took."""

    min_clearance_mm: float
    collisions: list[tuple[Contact, Contact]] = field(default_factory=list)
    deepest: list[Contact] = field(default_factory=list)  # per collision: its nearest sample
    nearest: dict[int, Contact] = field(default_factory=dict)
    samples: int = 0
    exact_queries: int = 0
    bound_queries: int = 0
    waypoints: int = 0  # of the path checked
    moved_from: bool = False  # the motion onto the path from a start pose was checked too
    labels: dict = field(default_factory=dict)  # a body's name for people where it differs ("link 3 (forearm_link)")
    # The bodies of the robot (its links, base and probe): a pair of them must not touch; a
    # pair with anything else keeps the clearance. Empty: told apart by their names.
    robot_bodies: frozenset = frozenset()

    @property
    def ok(self) -> bool:
        return not self.collisions

    @property
    def first_collision(self) -> tuple[Contact, Contact] | None:
        return min(self.collisions, key=lambda c: c[0].position) if self.collisions else None

    def message(self, segment=None) -> str:
        """One line naming the first frames and the two bodies ('' when the path is clear);
        with ``segment`` (n,) (each frame's path entry), the entries those frames belong to."""
        hit = self.first_collision
        if hit is None:
            return ""
        first, last = hit
        worst = self.deepest[self.collisions.index(hit)] if len(self.deepest) == len(self.collisions) else first
        if self.moved_from and self.waypoints == 1 and first.position > -1:
            # One step of a Scanner (move_to, turn_table, ...): it has no frames to name.
            where = ("at the pose moved to" if first.position == 0 else
                     "on the way there and at the pose moved to" if last.position >= 0 else "on the way there")
        elif first.position < 0:  # the pose the motion starts from
            on = "" if last.frame <= 0 else f" and on to frame {last.frame}"
            where = f"at the start pose{on}" if first.position <= -1 else f"moving from the start pose to frame 0{on}"
        else:
            frames = f"frame {first.frame}" if first.frame == last.frame else f"frames {first.frame}-{last.frame}"
            if segment is not None and 0 <= first.frame <= last.frame < len(segment):
                a, b = int(segment[first.frame]) + 1, int(segment[last.frame]) + 1
                frames += f" (path[{a}])" if a == b else f" (path[{a}] to path[{b}])"
            where = f"at {frames}" if float(first.position).is_integer() else f"moving to {frames}"
        # Over a run of frames, the one to look at first: where the two come nearest (or overlap most).
        nearest_at = ""
        if first.frame != last.frame and worst.frame >= 0:
            nearest_at = f" (worst {'at' if float(worst.position).is_integer() else 'moving to'} frame {worst.frame})"
        robot_pair = self.robot_pair(first)
        allowed = ("they must not touch" if robot_pair or self.min_clearance_mm == 0 else
                   f"at least {self.min_clearance_mm:g} mm allowed ([safety] min_clearance_mm)")
        if not robot_pair and any(b.startswith("link ") for b in (first.body_a, first.body_b)):
            # The arm, not the probe: the clearance is not the knob (a UR5 whose elbow met the
            # table scanned the same path once started elbow up).
            allowed += ("; the arm itself is in the way: another posture may clear it (IK takes the branch nearest "
                        "the joints it starts from: [robot] start_deg in a config)")
        # The nearest the run comes, not where it starts: a probe that dives into the part
        # first passes the limit at about the limit.
        return f"{where}: {self.in_words(first, worst.distance_mm)}{nearest_at}; {allowed}"

    def in_words(self, c: Contact, distance_mm: float | None = None) -> str:
        """A contact in a sentence, "the probe touches the workpiece" or "link 3 comes within
        1.20 mm of the table", at ``distance_mm`` (its own where not given)."""
        d = c.distance_mm if distance_mm is None else distance_mm
        shown = f"{d:.2f}"
        if float(shown) >= self.min_clearance_mm > d:
            shown = f"{d:.6g}"  # (to 2 decimals a breach of 1.9999 mm read "within 2.00 mm", the limit)
        how = "touches" if d <= 0 else f"comes within {shown} mm of"
        return f"{_the(self.label(c.body_a))} {how} {_the(self.label(c.body_b))}"

    def robot_pair(self, c: Contact) -> bool:
        """Both bodies are the robot's (links, base, probe)."""
        if self.robot_bodies:
            return c.body_a in self.robot_bodies and c.body_b in self.robot_bodies
        return not any(name in ("table", "workpiece") or name.startswith("fixture") for name in (c.body_a, c.body_b))

    def label(self, body: str) -> str:
        """A body's name for people: a URDF link's own name beside its number."""
        return self.labels.get(body, body)

    def shifted(self, frames: int, move: bool = False) -> "PathClearance":
        """This check with its path positions counted ``frames`` on (a step-by-step scan's move
        or sweep, its frames numbered from 0, placed among the frames taken before it); ``move``:
        a move between frames, its contacts marked ``on_move``."""
        def on(c: Contact) -> Contact:
            return replace(c, position=c.position + frames, on_move=c.on_move or move)

        return replace(self, nearest={k: on(c) for k, c in self.nearest.items()},
                       collisions=[(on(a), on(b)) for a, b in self.collisions], deepest=[on(c) for c in self.deepest])

    @staticmethod
    def merge(parts: list["PathClearance"]) -> "PathClearance":
        """One record of several checks (a scanner's moves): their path entries numbered on, the
        first check's keeping its own numbers (a path scanned from its entry 1, ``--frames``
        picking the sweep, is reported as entry 1, as a farm's merged shards report it)."""
        out = PathClearance(parts[0].min_clearance_mm, robot_bodies=parts[0].robot_bodies)
        for p in parts:
            out.labels.update(p.labels)
            if not out.nearest:
                out.nearest.update(p.nearest)
            else:
                base = max(out.nearest) + 1
                out.nearest.update({base + i: c for i, (_, c) in enumerate(sorted(p.nearest.items()))})
            out.collisions += p.collisions
            out.deepest += p.deepest if len(p.deepest) == len(p.collisions) else [c[0] for c in p.collisions]
            out.samples += p.samples
            out.exact_queries += p.exact_queries
            out.bound_queries += p.bound_queries
        return out

    def report(self) -> dict:
        overall = min(self.nearest.values(), key=lambda c: c.distance_mm) if self.nearest else None
        return {"min_clearance_mm": self.min_clearance_mm,
                "nearest": None if overall is None else overall.as_dict(),
                "per_path": {str(k): v.as_dict() for k, v in sorted(self.nearest.items())},
                "samples_checked": self.samples}


HULL_THICKNESS_MM = 1e-3  # a sheet's hull (one flat triangle, a plate of no thickness) is made this thick
# The smallest clearance is searched to this: two hulls thickened so read up to 2√3 × 1 µm
# nearer than their bodies, so where every pose lies as far as the best found (a table turn
# around a sphere), an exact search would take an exact distance at every one of them.
NEAREST_TOL_MM = 4 * HULL_THICKNESS_MM


def _convex(fcl, points: np.ndarray):
    # Joggled (QJ), so that a flat body (a plate) still has a hull; GJK reads only its points.
    # Copies moved a hair along each axis make any set of points full-dimensional for qhull.
    points = np.vstack([points] + [points + HULL_THICKNESS_MM * e for e in np.eye(3)])
    hull = trimesh.convex.convex_hull(points, qhull_options="QbB Pp Qt QJ", repair=False)
    faces = np.column_stack([np.full(len(hull.faces), 3), hull.faces]).ravel().astype(np.int64)
    return fcl.CollisionObject(fcl.Convex(np.ascontiguousarray(hull.vertices, dtype=np.float64), len(hull.faces),
                                          faces), fcl.Transform())


def _hull_points(body: Body) -> np.ndarray:
    """Points whose convex hull holds the body (cylinders by a circumscribed polygon)."""
    pts = []
    for s in body.shapes:
        g = s.geometry
        name = type(g).__name__
        if name == "Box":
            e = np.asarray(g.side, dtype=np.float64) / 2
            local = UNIT_CORNERS * e
        elif name == "Cylinder":
            n = 24
            r = g.radius / math.cos(math.pi / n)
            a = np.linspace(0, 2 * math.pi, n, endpoint=False)
            ring = np.column_stack([r * np.cos(a), r * np.sin(a)])
            local = np.vstack([np.column_stack([ring, np.full(n, -g.lz / 2)]),
                               np.column_stack([ring, np.full(n, g.lz / 2)])])
        else:  # a mesh: points enclosing it (bodies._enclosing_points)
            local = s.hull_vertices
        pts.append(local @ s.local[:3, :3].T + s.local[:3, 3])
    return np.vstack(pts)


DISC_OVERLAP_MM = 0.05  # a world fixture may touch the table's disc (a pedestal under it), not reach into it


def _refuse_world_fixtures_in_the_disc(fixtures, table: Turntable) -> None:
    """A CollisionError for a world fixture that reaches into the table's disc by more than
    DISC_OVERLAP_MM: the disc turns into itself, so the distance never changes as it turns and
    is a matter of the cell's layout, checked once (a post through the table top, a clamp on
    its rim that does not turn with it). Touching it (a pedestal under it) is allowed. Judged
    on the fixture's vertices and points spread over its surface (a rod through the disc has
    no vertex in it)."""
    from ..errors import CollisionError
    from ..kinematics.turntable import TABLE_RADIUS_MM, TABLE_THICKNESS_MM
    from ..kinematics.transforms import rigid_inverse

    to_table = rigid_inverse(table.table2base(0.0))
    for name, mesh, on in fixtures:
        if on == "table" or not len(mesh.faces):
            continue
        spread, _ = trimesh.sample.sample_surface(mesh, 4000, seed=0)
        P = np.vstack([mesh.vertices, spread]) @ to_table[:3, :3].T + to_table[:3, 3]
        inside = np.minimum.reduce([TABLE_RADIUS_MM - np.hypot(P[:, 0], P[:, 1]), -P[:, 2],
                                    P[:, 2] + TABLE_THICKNESS_MM])
        depth = float(inside.max(initial=0.0))
        if depth > DISC_OVERLAP_MM:
            raise CollisionError(f"{name} reaches {depth:.1f} mm into the rotary table's disc ({TABLE_RADIUS_MM:g} mm "
                                 f"radius, {TABLE_THICKNESS_MM:g} mm thick, its top at z = 0 in the table frame), "
                                 f"which turns: a fixture in the world may touch the table (a pedestal under it), not "
                                 f"stand in it; move it out, or put it on the table (on = \"table\")")


class CollisionModel:
    """The cell's bodies and the pairs to check; see the module and :mod:`.bodies`."""

    def __init__(self, robot: Robot, probe: Probe, table: Turntable, workpiece_mesh=None, fixtures=(),
                 min_clearance_mm: float = DEFAULT_CLEARANCE_MM):
        if not (isinstance(min_clearance_mm, (int, float)) and math.isfinite(min_clearance_mm)
                and min_clearance_mm >= 0):
            raise InputError(f"min_clearance_mm must be a finite number >= 0, got {min_clearance_mm!r}")
        self.fcl = _fcl()
        self.robot, self.probe, self.table = robot, probe, table
        self.min_clearance_mm = float(min_clearance_mm)
        self.bodies = robot_bodies(robot, probe) + environment_bodies(workpiece_mesh, fixtures)
        _refuse_world_fixtures_in_the_disc(fixtures, table)
        for b in self.bodies:
            b.hull = _convex(self.fcl, _hull_points(b))
        self.index = {b.name: i for i, b in enumerate(self.bodies)}
        self.labels = {f"link {k}": robot.link_label(k) for k in range(1, N_JOINTS + 1) if robot.link_names}
        self.robot_names = frozenset(b.name for b in self.bodies if b.robot)
        self.pairs = self._pairs()
        # Lever arm bound for the motion sampling: the farthest any robot point gets from a joint axis.
        self.arm_mm = robot.reach_bound_mm + max(b.radius + np.linalg.norm(b.centre) for b in self.bodies
                                                 if b.name == "probe")
        self.joint_mm = np.where(robot.prismatic, 1.0, self.arm_mm)  # mm moved per unit of each joint
        # The table's disc turns into itself; what stands on it moves by its radius.
        self.table_mm = max([0.0] + [float(np.max(np.linalg.norm(b.support[:, :2], axis=1) + b.support_r))
                                     for b in self.bodies if b.carrier == "table" and b.name != "table"])

    # -- pairs ----------------------------------------------------------------------
    def _pairs(self) -> list[tuple[int, int, float]]:
        robot = [i for i, b in enumerate(self.bodies) if b.robot]
        env = [i for i, b in enumerate(self.bodies) if not b.robot]
        # The probe first: it is nearest the part on a scan path, so the branch and bound that
        # finds the smallest clearance (shared by all pairs) prunes the links at once.
        robot = sorted(robot, key=lambda i: self.bodies[i].name != "probe")
        # Touching counts even where no clearance is asked for (an exact distance of 0 is not below 0).
        limit = max(self.min_clearance_mm, CONTACT_MM)
        # The base never moves: not against the table (a disc turning into itself) nor what the
        # table carries here, but below; the robot's moving bodies against all of it.
        pairs = [(i, j, limit) for i in robot for j in env if not self.bodies[i].name.startswith(ROBOT_BASE)]
        self.reported = set(pairs)  # the pairs whose smallest clearance the report gives
        # What the table carries (the part, its fixtures) against what stands still (the robot's
        # base, the world's fixtures): a table turn swings a long part into them.
        still = [i for i, b in enumerate(self.bodies) if b.name.startswith(ROBOT_BASE) or b.carrier == "world"]
        carried = [j for j in env if self.bodies[j].carrier == "table" and self.bodies[j].name != "table"]
        pairs += [(i, j, limit) for i in still for j in carried]
        q0 = np.zeros((1, 6))
        carriers = carrier_poses(self.robot, self.table, q0, np.zeros(1))
        def place(name: str) -> int:  # in the chain: the base 0, links by their number, the probe 7
            return 0 if name.startswith(ROBOT_BASE) else 7 if name == "probe" else int(name.split()[-1])

        for a in range(len(robot)):
            for b in range(a + 1, len(robot)):
                i, j = robot[a], robot[b]
                ki, kj = place(self.bodies[i].name), place(self.bodies[j].name)
                if abs(ki - kj) < 2 or (7 in (ki, kj) and min(ki, kj) >= 5):
                    continue  # neighbours in the chain (the probe sits on links 5 and 6)
                if self._exact(i, j, carriers, 0)[0] <= CONTACT_MM:
                    continue  # touching at rest: part of the rig's design
                pairs.append((i, j, CONTACT_MM))
        return pairs

    # -- distances ------------------------------------------------------------------
    def _place(self, obj, T: np.ndarray) -> None:
        obj.setTransform(self.fcl.Transform(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3])))

    def _hull_distance(self, i: int, j: int, carriers, s: int) -> float:
        a, b = self.bodies[i], self.bodies[j]
        self._place(a.hull, carriers[a.carrier][s])
        self._place(b.hull, carriers[b.carrier][s])
        return float(self.fcl.distance(a.hull, b.hull, self.fcl.DistanceRequest(), self.fcl.DistanceResult()))

    def _exact(self, i: int, j: int, carriers, s: int, hulls_overlap: bool = True
               ) -> tuple[float, np.ndarray, np.ndarray]:
        """Exact distance of bodies i and j at sample s (≤ 0: touching), and the nearest points.
        ``hulls_overlap``: their convex hulls meet, so one may lie wholly inside the other."""
        a, b = self.bodies[i], self.bodies[j]
        Ta, Tb = carriers[a.carrier][s], carriers[b.carrier][s]
        best = (math.inf, np.full(3, np.nan), np.full(3, np.nan))
        req = self.fcl.DistanceRequest(enable_nearest_points=True)
        for sa in a.shapes:
            self._place(sa.obj, Ta @ sa.local)
            for sb in b.shapes:
                self._place(sb.obj, Tb @ sb.local)
                # Touching is decided by a collision query, which stops at the first contact:
                # FCL's distance query on overlapping meshes visits most of their triangles
                # (59 ms for the probe inside the demo's sphere, against 0.1 ms apart).
                if self.fcl.collide(sa.obj, sb.obj, self.fcl.CollisionRequest(), self.fcl.CollisionResult()):
                    return 0.0, np.full(3, np.nan), np.full(3, np.nan)
                res = self.fcl.DistanceResult()
                d = float(self.fcl.distance(sa.obj, sb.obj, req, res))
                if d < best[0]:
                    pa, pb = (np.full(3, np.nan), np.full(3, np.nan)) if d <= 0 else \
                        (np.asarray(res.nearest_points[0], float), np.asarray(res.nearest_points[1], float))
                    best = (d, pa, pb)
        if best[0] > 0 and hulls_overlap:
            best = self._inside(a, b, Ta, Tb, best)
        return best

    def _inside(self, a: Body, b: Body, Ta, Tb, best):
        """A body wholly inside a closed mesh of the other counts as touching it."""
        for outer, inner, To, Ti in ((b, a, Tb, Ta), (a, b, Ta, Tb)):
            if outer.mesh is None:
                continue
            # A point of each inner shape: a mesh's first vertex (its frame's origin may lie far
            # from it: a part's is the table's centre), else its centre
            centres = np.array([(Ti @ s.local @ np.r_[s.vertices[0] if s.vertices is not None and len(s.vertices)
                                                        else s.centre, 1.0])[:3] for s in inner.shapes])
            local = (centres - To[:3, 3]) @ To[:3, :3]
            if np.any(outer.mesh.contains(local)):
                return (0.0, np.full(3, np.nan), np.full(3, np.nan))
        return best

    # -- the path -------------------------------------------------------------------
    def samples(self, q: np.ndarray, table_rad: np.ndarray, q_start=None, table_start=None):
        """Joint vectors (m, 6), table angles (m,) and path positions (m,) of the poses to check:
        each waypoint, and enough poses between it and the one before (or the start) that
        nothing moves more than STEP_MM from one to the next."""
        q = np.asarray(q, dtype=np.float64).reshape(-1, 6)
        th = np.asarray(table_rad, dtype=np.float64).reshape(-1)
        if q_start is not None:
            q = np.vstack([np.asarray(q_start, dtype=np.float64).reshape(1, 6), q])
            th = np.r_[th[0] if table_start is None else float(table_start), th]
        offset = -1.0 if q_start is not None else 0.0
        out_q, out_t, out_p = [q[:1]], [th[:1]], [np.array([offset])]
        for i in range(1, len(q)):
            dq, dt = q[i] - q[i - 1], th[i] - th[i - 1]
            # A turning joint sweeps at most arm_mm per radian; a sliding one moves its mm.
            move = float(np.sum(np.abs(dq) * self.joint_mm) + abs(dt) * self.table_mm)
            m = max(1, int(math.ceil(move / STEP_MM)))
            f = np.arange(1, m + 1) / m
            out_q.append(q[i - 1] + f[:, None] * dq)
            out_t.append(th[i - 1] + f * dt)
            out_p.append(offset + i - 1 + f)
        return np.vstack(out_q), np.concatenate(out_t), np.concatenate(out_p)

    def check(self, q, table_rad, segment=None, q_start=None, table_start=None, nearest: bool = True,
              relaxed: dict | None = None) -> PathClearance:
        """Check the path (and the move onto it from ``q_start``); see :class:`PathClearance`.
        ``nearest``: also the smallest clearance per path entry (else only the collisions).
        ``relaxed``: {(body a, body b): mm} a smaller limit for those pairs (a move out of a
        pose that already breaks the clearance may not come nearer than it is)."""
        qs, ts, pos = self.samples(q, table_rad, q_start, table_start)
        n_way = len(np.asarray(table_rad).reshape(-1))
        seg = np.zeros(n_way, int) if segment is None else np.asarray(segment, int).reshape(-1)
        seg_of = seg[np.clip(np.ceil(pos - 1e-9).astype(int), 0, n_way - 1)]
        carriers = carrier_poses(self.robot, self.table, qs, ts)
        centres, support = {}, {}
        for i, b in enumerate(self.bodies):
            T = carriers[b.carrier]
            centres[i] = np.einsum("nij,j->ni", T[:, :3, :3], b.centre) + T[:, :3, 3]
            support[i] = np.einsum("nij,kj->nki", T[:, :3, :3], b.support) + T[:, None, :3, 3]
        up = carriers["table"][:, :3, 2]
        out = PathClearance(self.min_clearance_mm, samples=len(qs), waypoints=n_way, moved_from=q_start is not None,
                            labels=self.labels, robot_bodies=self.robot_names)
        closest: dict[int, Contact] = {}
        for i, j, limit in self.pairs:
            bound = self._bound(i, j, centres, support, up)
            env = (i, j, limit) in self.reported
            if relaxed and (self.bodies[i].name, self.bodies[j].name) in relaxed:
                limit = min(limit, relaxed[self.bodies[i].name, self.bodies[j].name])
            # Collisions: the samples whose bound says they might be too close, in path order;
            # the pair's first run of colliding samples ends at the first sample clear of it.
            run: list[Contact] = []
            carried: list[bool] = []  # which of the run's contacts come from carried points (below)
            at: list[int] = []  # the run's samples
            last = -2
            for s in np.flatnonzero(bound < limit):
                if run and s == last + 1 and np.isfinite(run[-1].point_a).all():
                    # Inside a run, the last sample's nearest points carried along with their
                    # bodies are two points on them: their distance bounds the bodies' from
                    # above, and below the limit the sample is in the run without an exact
                    # query (a clearance broken all along a path cost one per sample and pair:
                    # 3 min on the demo's 180 frames against its 82 k-face sphere).
                    near = self._carry(run[-1], i, j, carriers, last, s, float(pos[s]))
                    if near.distance_mm < limit:
                        run.append(near)
                        carried.append(True)
                        at.append(s)
                        last = s
                        continue
                d, pa, pb = self._below(i, j, carriers, s, limit, out)
                if d >= limit or (run and s != last + 1):
                    if run:
                        break  # the first run of this pair is over
                    continue
                run.append(self._contact(d, i, j, float(pos[s]), pa, pb, carriers, s))
                carried.append(False)
                at.append(s)
                last = s
            if run:
                k = min(range(len(run)), key=lambda n: run[n].distance_mm)
                if carried[k]:  # the nearest the run comes, exactly
                    d, pa, pb = self._exact(i, j, carriers, at[k])
                    if d <= run[k].distance_mm:
                        run[k] = self._contact(d, i, j, run[k].position, pa, pb, carriers, at[k])
                out.collisions.append((run[0], run[-1]))
                out.deepest.append(run[k])
            if env and nearest:
                self._nearest(i, j, carriers, bound, pos, seg_of, closest, out)
        out.nearest = closest
        return out

    def _bound(self, i, j, centres, support, up) -> np.ndarray:
        """A lower bound (n,) of the distance of bodies i and j at every sample: the best of
        their bounding spheres and of their separation along three axes (the table's axis,
        the line between their centres, and its horizontal part), each from the bodies'
        support points and margins."""
        a, b = self.bodies[i], self.bodies[j]
        along = centres[i] - centres[j]
        bound = np.linalg.norm(along, axis=1) - a.radius - b.radius
        flat = along - np.sum(along * up, axis=1)[:, None] * up
        for n in (up, along, flat):
            norm = np.linalg.norm(n, axis=1, keepdims=True)
            n = np.where(norm > 1e-9, n / np.maximum(norm, 1e-300), 0.0)
            pa = np.einsum("nki,ni->nk", support[i], n)
            pb = np.einsum("nki,ni->nk", support[j], n)
            gap = np.maximum((pa - a.support_r).min(axis=1) - (pb + b.support_r).max(axis=1),
                             (pb - b.support_r).min(axis=1) - (pa + a.support_r).max(axis=1))
            bound = np.maximum(bound, np.where(norm[:, 0] > 1e-9, gap, -np.inf))
        return bound

    def _contact(self, d, i: int, j: int, position: float, pa, pb, carriers, s: int) -> Contact:
        """A Contact with its points in the table frame, the first on body i. (FCL's nearest
        points come in either order for a primitive against a mesh: each is given to the
        body it lies on.)"""
        a, b = self.bodies[i], self.bodies[j]
        if np.isfinite(pa).all() and self._gap(j, pa, carriers, s) < self._gap(j, pb, carriers, s):
            pa, pb = pb, pa
        table2world = carriers["table"][s]
        R, t = table2world[:3, :3], table2world[:3, 3]
        return Contact(d, a.name, b.name, position, tuple((pa - t) @ R), tuple((pb - t) @ R))

    def _carry(self, c: Contact, i: int, j: int, carriers, s_from: int, s_to: int, position: float) -> Contact:
        """Contact ``c`` (bodies i and j at sample ``s_from``) with its two points carried along
        with their bodies to sample ``s_to``: their distance there bounds the bodies' from above."""
        a, b = self.bodies[i], self.bodies[j]
        table_from, table_to = carriers["table"][s_from], carriers["table"][s_to]
        moved = []
        for body, p in ((a, c.point_a), (b, c.point_b)):
            world = table_from[:3, :3] @ np.asarray(p, float) + table_from[:3, 3]
            T0, T1 = carriers[body.carrier][s_from], carriers[body.carrier][s_to]
            local = T0[:3, :3].T @ (world - T0[:3, 3])
            world = T1[:3, :3] @ local + T1[:3, 3]
            moved.append(table_to[:3, :3].T @ (world - table_to[:3, 3]))
        return Contact(float(np.linalg.norm(moved[0] - moved[1])), a.name, b.name, position,
                       tuple(moved[0]), tuple(moved[1]))

    def _gap(self, j: int, p: np.ndarray, carriers, s: int) -> float:
        """Distance of the world point p from body j."""
        probe = self.fcl.CollisionObject(self.fcl.Sphere(1e-6), self.fcl.Transform(np.eye(3), np.asarray(p, float)))
        b = self.bodies[j]
        best = math.inf
        for sh in b.shapes:
            self._place(sh.obj, carriers[b.carrier][s] @ sh.local)
            best = min(best, abs(float(self.fcl.distance(probe, sh.obj, self.fcl.DistanceRequest(),
                                                           self.fcl.DistanceResult()))))
        return best

    def _below(self, i: int, j: int, carriers, s: int, limit: float, out: PathClearance):
        """(distance, nearest points) of bodies i and j at sample s where it may be below
        ``limit``: the hull distance first, the exact one only where the hulls come nearer;
        (inf, NaN, NaN) where the hulls show it is not below."""
        out.bound_queries += 1
        hull = self._hull_distance(i, j, carriers, s)
        if hull >= limit:
            return math.inf, np.full(3, np.nan), np.full(3, np.nan)
        out.exact_queries += 1
        return self._exact(i, j, carriers, s, hull <= 0)

    def _nearest(self, i, j, carriers, bound, pos, seg_of, nearest, out) -> None:
        """Branch and bound: the smallest exact distance of pair (i, j) in each path entry (to
        NEAREST_TOL_MM: a pose that could be nearer by less is not looked at exactly)."""
        waypoint = (pos >= 0) & (np.abs(pos - np.round(pos)) < 1e-9)
        for k in np.unique(seg_of[waypoint]):
            idx = np.flatnonzero((seg_of == k) & waypoint)
            best = nearest.get(int(k))
            best_d = math.inf if best is None else best.distance_mm
            for s in idx[np.argsort(bound[idx], kind="stable")]:
                if bound[s] >= best_d - NEAREST_TOL_MM:
                    break  # every later sample's bound is larger still
                d, pa, pb = self._below(i, j, carriers, s, best_d - NEAREST_TOL_MM, out)
                if d < best_d:
                    best_d = d
                    best = self._contact(d, i, j, float(pos[s]), pa, pb, carriers, s)
            if best is not None:
                nearest[int(k)] = best

    def clearance_at(self, q, table_rad: float = 0.0) -> PathClearance:
        """The check of a single pose (the panel's clearance readout)."""
        return self.check(np.asarray(q, dtype=np.float64).reshape(1, 6), np.array([float(table_rad)]))


def _the(body: str) -> str:
    """A body's name in a sentence: "link 3" and "fixture clamp" as they are, "the probe"."""
    return body if body.startswith(("link ", "fixture ")) else f"the {body}"
