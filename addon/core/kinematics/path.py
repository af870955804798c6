"""Scan paths: where the probe is in each frame, and the joint vectors that put it there.

A path is a list of waypoints, one per frame: the probe pose in the table
(workpiece) frame and the table angle. Kinds:

- **sweep**: the probe moves in a straight line (table frame) with the table
  still; its laser plane stands across the direction of motion.
- **turntable**: the probe stays put in the world while the table turns through
  ``turn_deg`` in N equal steps; the laser plane contains the table axis by
  default, so each profile is a meridian of the part.
- **multi-view**: several of these, one after the other, merged into one cloud.

Orientation is given by two directions in the table frame: ``beam`` (the probe's
+Z, default straight down) and ``line`` (the probe's +Y, along the laser line).
For a sweep the line defaults to across the motion; for a turntable path to the
radial direction.

:func:`solve_path` turns waypoints into joint vectors, each continuous with the
one before (the closed form picks, for every waypoint, the solution nearest the
previous one; the numeric solver is seeded with it), and reports unreachable
waypoints and joint jumps by index.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .cell import Cell
from ..errors import InputError, check_whole
from .ik import ROT_TOL_RAD, all_branches, closed_form_arm, default_pos_tol, default_seed, wrap_to_limits
from .transforms import RIGID_TOL, make_pose, orthonormality_error

DOWN = (0.0, 0.0, -1.0)
MAX_FRAMES = 1_000_000  # the most frames one path entry takes
# Less travel, or less turn, than this over a whole path entry of several frames takes one
# profile over and over (a sweep 1e-8 mm long was let through, as a turn of 1e-9°).
MIN_TRAVEL_MM = 1e-6
MIN_TURN_DEG = 1e-6
JUMP_LIMIT_RAD = np.radians(30.0)  # a joint moving more than this between neighbours is a flip


@dataclass(frozen=True)
class Waypoints:
    """probe2table (n, 4, 4) mm; table_rad (n,); segment (n,) index of the path entry."""

    probe2table: np.ndarray
    table_rad: np.ndarray
    segment: np.ndarray

    def __post_init__(self) -> None:
        """Refuse what no path can be, in one line: poses that are not (n, 4, 4) rigid
        transforms of finite numbers, angles or entry numbers not one per pose (none at all is
        a selection that picked nothing; the Scanner refuses to move along it)."""
        poses, angles, segment = (np.asarray(getattr(self, name)) for name in ("probe2table", "table_rad", "segment"))
        n = len(angles) if angles.ndim == 1 else -1
        if poses.ndim != 3 or poses.shape[1:] != (4, 4) or angles.ndim != 1 or segment.shape != (n,) \
                or len(poses) != n:
            raise InputError(f"waypoints need poses (n, 4, 4), table angles (n,) and entry numbers (n,), one of each "
                             f"per frame; got {poses.shape}, {angles.shape} and {segment.shape}")
        if poses.dtype.kind not in "fiu" or angles.dtype.kind not in "fiu":
            raise InputError(f"waypoints' poses and table angles must be numbers, got {poses.dtype} and {angles.dtype}")
        if segment.dtype.kind not in "iu" and segment.size:
            raise InputError(f"waypoints' entry numbers (segment) must be whole numbers (int), got {segment.dtype}")
        bad = ~(np.isfinite(poses).all(axis=(1, 2)) & np.isfinite(angles))
        if bad.any():
            raise InputError(f"waypoint {int(np.argmax(bad))} is not finite (its pose or its table angle); every "
                             f"pose and angle must be a finite number")
        # The rule of transforms.check_transform, pose by pose (to name the first that breaks it).
        off = (orthonormality_error(poses) > RIGID_TOL) | (np.linalg.det(poses[:, :3, :3]) < 0)
        off |= np.abs(poses[:, 3] - [0.0, 0.0, 0.0, 1.0]).max(axis=1) > RIGID_TOL
        if off.any():
            raise InputError(f"waypoint {int(np.argmax(off))}'s pose is not a rigid transform (a rotation and a "
                             f"translation, last row 0 0 0 1)")
        object.__setattr__(self, "probe2table", poses.astype(np.float64, copy=False))
        object.__setattr__(self, "table_rad", angles.astype(np.float64, copy=False))
        object.__setattr__(self, "segment", segment.astype(np.int64, copy=False))

    def __len__(self) -> int:
        return len(self.table_rad)

    def select(self, index) -> "Waypoints":
        return Waypoints(self.probe2table[index], self.table_rad[index], self.segment[index])


def _vector(v, name: str) -> np.ndarray:
    """``v`` as three float64s, or an InputError naming ``name`` (a string or a list of strings included)."""
    try:
        out = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError):
        out = None
    if out is None or out.shape != (3,):
        raise InputError(f"{name} must be three numbers [x, y, z], got {v!r}")
    return out


def _point(v, name: str) -> np.ndarray:
    p = _vector(v, name)
    if not np.isfinite(p).all():
        raise InputError(f"{name} must be three finite numbers [x, y, z] (mm, table frame), got {p.tolist()}")
    return p


def _unit(v, name: str) -> np.ndarray:
    v = _vector(v, name)
    n = np.linalg.norm(v)
    if not np.isfinite(n) or n < 1e-9:
        raise InputError(f"{name} must be a non-zero direction [x, y, z], got {v.tolist()}")
    return v / n


def _angle(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)) or not math.isfinite(value):
        raise InputError(f"{name} must be a finite number (radians), got {value!r}")
    return float(value)


DECIMALS = 12  # a path entry's mm and degrees: the views scan again as they were, to rounding
ALONG_LINE_DEG = 1.0  # a sweep moving within this angle of its laser line measures one line over and over


def probe_orientation(beam, line) -> np.ndarray:
    """(3, 3) rotation with +Z along ``beam`` and +Y along ``line`` (made perpendicular to the beam)."""
    z = _unit(beam, "beam")
    line = _unit(line, "line")
    y = line - np.dot(line, z) * z
    if np.linalg.norm(y) < 1e-9:
        raise InputError(f"the laser line direction {np.asarray(line).tolist()} is parallel to the beam "
                         f"{z.tolist()}; it must have a component across it")
    y /= np.linalg.norm(y)
    return np.column_stack([np.cross(y, z), y, z])


def sweep(frames: int, from_mm, to_mm, beam=DOWN, line=None, table_rad: float = 0.0, segment: int = 0) -> Waypoints:
    """Probe origin from ``from_mm`` to ``to_mm`` (table frame) in ``frames`` steps, laser plane across the motion."""
    frames = check_whole(frames, "a sweep's frames", 1, MAX_FRAMES)
    a, b = _point(from_mm, "from_mm"), _point(to_mm, "to_mm")
    table_rad = _angle(table_rad, "a sweep's table angle")
    z = _unit(beam, "beam")
    motion = b - a - np.dot(b - a, z) * z  # the probe's travel across the beam
    moves = np.linalg.norm(motion) >= 1e-9
    if frames > 1 and np.linalg.norm(b - a) < MIN_TRAVEL_MM:
        raise InputError(f"a sweep of {frames} frames from and to the same point {a.tolist()} takes one profile "
                         f"{frames} times; give to_mm apart from from_mm (by {MIN_TRAVEL_MM:g} mm or more), or 1 "
                         f"frame with a line")
    if line is None:
        if not moves:
            raise InputError("a sweep must move across the beam (from_mm and to_mm differ only along it) for its "
                             "laser line to stand across the motion; give its line, or to_mm apart across the beam")
        line = np.cross(z, motion)  # the plane (line, beam) stands across the motion
    R = probe_orientation(z, line)
    if frames > 1 and moves:
        along = motion / np.linalg.norm(motion)
        if abs(np.dot(along, R[:, 1])) > math.cos(math.radians(ALONG_LINE_DEG)):
            raise InputError(f"the laser line {np.round(R[:, 1], 4).tolist()} runs along the sweep's motion "
                             f"{np.round(along, 4).tolist()}: each profile would lie on the last one's line; give a "
                             f"line across the motion (or leave line out: it then stands across it)")
    pts = a + np.linspace(0.0, 1.0, frames)[:, None] * (b - a) if frames > 1 else a[None]
    poses = np.stack([make_pose(R, p) for p in pts])
    return Waypoints(poses, np.full(frames, float(table_rad)), np.full(frames, segment))


def turntable(frames: int, probe_mm, beam=DOWN, line=None, start_rad: float = 0.0,
              turn_rad: float = 2 * np.pi, table=None, segment: int = 0) -> Waypoints:
    """Probe fixed in the world (placed at ``probe_mm`` in the table frame at the start angle);
    the table turns by ``turn_rad`` in ``frames`` equal steps (end excluded for a full turn)."""
    frames = check_whole(frames, "a turntable path's frames", 1, MAX_FRAMES)
    start_rad, turn_rad = _angle(start_rad, "a turntable path's start angle"), _angle(turn_rad, "its turn")
    if table is None:
        raise InputError("a turntable path needs the table placement")
    if frames > 1 and abs(turn_rad) < math.radians(MIN_TURN_DEG):
        raise InputError(f"a turntable path of {frames} frames with turn_deg {math.degrees(turn_rad):g} takes one "
                         f"profile {frames} times; give the turn (turn_deg, {MIN_TURN_DEG:g} or more; 360 for a "
                         f"whole turn, the default) or 1 frame")
    p = _point(probe_mm, "probe_mm")
    z = _unit(beam, "beam")
    if line is None:
        radial = p - np.dot(p, z) * z
        radial[2] = 0.0
        # A level beam aimed at the axis leaves no radial part across it: the line then runs up
        # the axis (across the beam), so that the laser plane still holds the axis (it fell back
        # to x, a horizontal line: every frame scanned the same ring, or x along the beam was refused).
        up = np.array([0.0, 0.0, 1.0]) - z[2] * z
        line = radial if np.linalg.norm(radial) > 1e-6 else up if np.linalg.norm(up) > 1e-6 \
            else np.array([1.0, 0.0, 0.0])
    start = make_pose(probe_orientation(z, line), p)
    probe2base = table.table2base(start_rad) @ start
    full_turn = abs(abs(turn_rad) - 2 * np.pi) < 1e-9
    angles = start_rad + turn_rad * np.arange(frames) / (frames if full_turn else max(frames - 1, 1))
    poses = table.base2table(angles) @ probe2base
    return Waypoints(poses, angles, np.full(frames, segment))


def path_entry(wp: Waypoints, kind: str) -> dict:
    """The scan config's [[path]] entry (keys as a config writes them, mm and degrees) that
    gives ``wp``, a sweep's or a table turn's waypoints as :func:`sweep` and :func:`turntable`
    make them (``kind``: "sweep" or "turntable"): a view an adaptive scan chose, to be scanned
    again as a fixed path."""
    P = wp.probe2table
    first = P[0]

    def xyz(v):
        return [round(float(x), DECIMALS) + 0.0 for x in v]  # + 0.0: no -0.0

    entry = {"kind": kind, "frames": int(len(P))}
    if kind == "sweep":
        entry.update(from_mm=xyz(first[:3, 3]), to_mm=xyz(P[-1, :3, 3]),
                     table_deg=round(math.degrees(wp.table_rad[0]), DECIMALS))
    elif kind == "turntable":
        step = float(wp.table_rad[1] - wp.table_rad[0]) if len(P) > 1 else 0.0
        turn = step * len(P)
        if abs(abs(turn) - 2 * np.pi) > 1e-9:  # not a full turn: its last frame is its end
            turn = step * (len(P) - 1)
        entry.update(probe_mm=xyz(first[:3, 3]), start_deg=round(math.degrees(wp.table_rad[0]), DECIMALS),
                     turn_deg=round(math.degrees(turn), DECIMALS))
    else:
        raise InputError(f"a path entry is a sweep or a turntable, got {kind!r}")
    entry.update(beam=xyz(first[:3, 2]), line=xyz(first[:3, 1]))
    return entry


def concatenate(parts: list[Waypoints]) -> Waypoints:
    return Waypoints(np.concatenate([p.probe2table for p in parts]), np.concatenate([p.table_rad for p in parts]),
                     np.concatenate([p.segment for p in parts]))


@dataclass
class PathSolution:
    """q (n, 6) rad; ok (n,); messages per waypoint; jumps: indices where a joint moved more
    than JUMP_LIMIT_RAD from the previous waypoint; max_step_rad (n,) largest joint change."""

    q: np.ndarray
    ok: np.ndarray
    messages: list
    max_step_rad: np.ndarray
    jumps: list = field(default_factory=list)

    @property
    def unreachable(self) -> list[int]:
        return [int(i) for i in np.nonzero(~self.ok)[0]]


AROUND_PART_STANDOFF_MM = 160.0  # the default probe's mid-range
AROUND_PART_TILT_DEG = 45.0


def around_part(mesh, table, frames: int = 60, standoff_mm: float = AROUND_PART_STANDOFF_MM) -> Waypoints:
    """A path for a part that a scanning engineer would set up from its bounding box (table
    frame): a table turn looking down from above, two table turns looking 45° down at its side
    (one at the near side's outside, one across the axis at the far side's inside: walls,
    holes, pockets), and a sweep across its top with half the frames. The laser plane holds
    the table axis in the turns. ``standoff_mm``: the probe's distance to its aim, best the
    middle of its range (the default probe's 160 mm)."""
    lo, hi = mesh.bounds
    radius = float(np.linalg.norm(np.maximum(np.abs(lo[:2]), np.abs(hi[:2]))))
    top = float(hi[2])
    a = np.radians(AROUND_PART_TILT_DEG)
    beam = np.array([0.0, -np.sin(a), -np.cos(a)])  # from the +y side, towards the axis
    near = np.array([0.0, 0.5 * radius, 0.5 * top])
    far = np.array([0.0, -0.4 * radius, 0.6 * top])
    standoff = float(standoff_mm)
    return concatenate([
        turntable(frames, [12.0, 0.0, top + standoff], table=table, segment=0),
        turntable(frames, near - standoff * beam, beam, (0.0, 0.0, 1.0), table=table, segment=1),
        turntable(frames, far - standoff * beam, beam, (0.0, 0.0, 1.0), table=table, segment=2),
        sweep(frames // 2, [-radius - 5.0, 0.0, top + standoff], [radius + 5.0, 0.0, top + standoff], segment=3),
    ])


def solve_path(cell: Cell, waypoints: Waypoints, q_start=None, stop_at_miss: bool = False) -> PathSolution:
    """Joint vectors for every waypoint, each nearest the previous one (no flips between neighbours).
    ``stop_at_miss``: stop at the first waypoint that cannot be reached (those after it are left
    unsolved, not ok, "not tried"): for callers that only ask whether the whole path can be done
    (a numeric IK's failure costs its restarts, per waypoint: tens of seconds for a sweep)."""
    robot = cell.robot
    targets = cell.table.table2base(waypoints.table_rad) @ waypoints.probe2table
    n = len(waypoints)
    q_prev = default_seed(robot) if q_start is None else robot.check_q(q_start, "q_start")
    arm, _ = closed_form_arm(robot) if robot.ik_via is None else (None, None)  # a controller answers each
    q = np.zeros((n, 6))
    ok = np.zeros(n, dtype=bool)
    messages = [""] * n
    first_miss = None  # (waypoint, the joints its solve started from)
    quiet = {} if robot.ik_via is not None else {"explain_limits": False}  # a controller takes no options
    if arm is not None:
        # Every branch of every waypoint at once, then walk along picking the nearest.
        branch_q, inside, pos, rot, _ = all_branches(robot, arm, targets, np.tile(q_prev, (n, 1)))
        good = inside & (pos <= default_pos_tol(robot)) & (rot <= ROT_TOL_RAD)
        for i in range(n):
            if good[i].any():
                cand, _ = wrap_to_limits(robot, branch_q[i], q_prev[None])
                cand = np.where(good[i][:, None], cand, np.inf)
                k = int(np.argmin(np.linalg.norm(cand - q_prev, axis=1)))
                q[i], ok[i], messages[i] = cand[k], True, "ok"
                q_prev = q[i]
            else:
                res = robot.ik(targets[i], q_prev, **quiet)
                q[i], ok[i], messages[i] = res.q, res.success, res.message
                if res.success:
                    q_prev = res.q
                elif first_miss is None:
                    first_miss = (i, q_prev)
                    if stop_at_miss:
                        break
    else:
        for i in range(n):
            res = robot.ik(targets[i], q_prev, **quiet)
            q[i], ok[i], messages[i] = res.q, res.success, res.message
            if res.success:
                q_prev = res.q
            elif first_miss is None:
                first_miss = (i, q_prev)
                if stop_at_miss:
                    break
    if first_miss is not None and stop_at_miss:
        q[first_miss[0] + 1:] = q[first_miss[0]]
        messages[first_miss[0] + 1:] = ["not tried: an earlier waypoint cannot be reached"] * (n - first_miss[0] - 1)
    if first_miss is not None and quiet:  # the first miss, which a refusal quotes, names a limit in the way
        i, seed = first_miss
        messages[i] = robot.ik(targets[i], seed).message
    turning = ~np.array(robot.prismatic)  # a flip is a turn; sliding joints just travel
    step = (np.r_[0.0, np.max(np.abs(np.diff(q[:, turning], axis=0)), axis=1)] if n > 1 and turning.any()
            else np.zeros(n))  # (a chain of sliding joints only: nothing turns, so nothing flips)
    # Between path entries the robot repositions; only steps within one entry can be flips.
    same = np.r_[False, waypoints.segment[1:] == waypoints.segment[:-1]]
    step[~ok | ~same] = 0.0
    jumps = [int(i) for i in np.nonzero((step > JUMP_LIMIT_RAD) & ok & np.r_[False, ok[:-1]])[0]]
    return PathSolution(q, ok, messages, step, jumps)

