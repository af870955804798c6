"""The one way in: a scanner that scripts, the panel, the command line and the farm drive.

Step by step (for adaptive scanning: move, measure, look, decide)::

    from addon import Scanner
    s = Scanner.from_config("demo")               # robot, probe, table, part, render, detection
    s.move_to(([0, 0, 210], [90, 180, 0]))        # probe position (mm) and YZZ' angles (deg), table frame
    p = s.measure()                               # one profile: p.points (n, 3) mm, table frame
    s.sweep([-40, 0, 210], [40, 0, 210], 20)      # twenty profiles along a line
    s.turn_table(30)                              # turn the table by 30 degrees
    s.report().error_um.rms_um, len(s.cloud)      # everything measured so far

or a whole configured path: ``Scanner.from_config("step_block").run()``, then ``save(out_dir)``.

A move that cannot be made (unreachable, outside the joint limits) raises
``UnreachablePose`` and moves nothing. Blender is loaded at the first measurement,
not before; the cell is built once and kept.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .core.config.render import RenderOptions
from .core.config.rigs import load_probe, load_robot
from .core.config.scan import ScanConfig, load_scan_config
from .core.errors import CollisionError, InputError, UnreachablePose, check_whole
from .core.geometry.cloud import Cloud
from .core.geometry.workpiece import (BUILTINS, Workpiece, builtin_workpiece, check_on_table, check_over_table,
                                      lift_text, load_workpiece, resting_on_table)
from .core.kinematics.euler import pose_from_xyz_yzz, pose_to_xyz_yzz
from .core.kinematics.path import Waypoints, sweep as sweep_waypoints
from .core.kinematics.robot import Robot
from .core.kinematics.transforms import check_transform
from .core.kinematics.turntable import Turntable
from .core.optics.probe import Probe
from .core.scan.report import ScanReport

RELATIVE_TO = ("table", "base")


@dataclass
class Profile:
    """One measurement: what the probe saw at one pose.

    points : (n, 3) float, mm, table frame
    camera : (n,) uint8, 1 = camera 0, 2 = camera 1, 3 = both (fused)
    sigma_mm : (n,) float, mm, each point's depth uncertainty (see docs/optics.md, point quality)
    quality : (n,) float, 0..1, 1 for points both cameras agree on, lower the less sure the point
    probe2table : (4, 4) float, mm, the probe pose in the table frame
    q : (6,) rad, the robot's joints; table_deg : the table's angle
    codes : {detection code: sensor columns}, over both cameras (OK, NO_LINE, AMBIGUOUS, ...)
    frame : index of the measurement in the scanner's cloud
    """

    points: np.ndarray
    camera: np.ndarray
    sigma_mm: np.ndarray
    probe2table: np.ndarray
    q: np.ndarray
    table_deg: float
    codes: dict = field(default_factory=dict)
    frame: int = 0

    def __len__(self) -> int:
        return len(self.points)

    @property
    def quality(self) -> np.ndarray:
        """(n,) 0..1: 1 for fused points (both cameras agree), 0.5 for points one camera saw."""
        return np.where(self.camera == 3, 1.0, 0.5)


MAX_TABLE_TURN_DEG = 3600.0  # the most a table turns (or is turned to) in one move: ten turns


def _check_table_deg(deg, what: str) -> None:
    if isinstance(deg, (bool, complex, np.complexfloating)) or not isinstance(deg, (int, float, np.number)) \
            or not math.isfinite(deg) or abs(deg) > MAX_TABLE_TURN_DEG:
        raise InputError(f"{what} must be a finite number of degrees within ±{MAX_TABLE_TURN_DEG:g} (ten turns), "
                         f"got {deg!r}")


def _robot(value) -> Robot:
    if not isinstance(value, (Robot, str, Path)):
        raise InputError(f"robot must be a Robot, a bundled rig's name or a rig or URDF file's path, got {value!r}")
    return value if isinstance(value, Robot) else load_robot(value)


def _probe(value) -> Probe:
    if not isinstance(value, (Probe, str, Path)):
        raise InputError(f"probe must be a Probe, a bundled probe's name or a probe file's path, got {value!r}")
    return value if isinstance(value, Probe) else load_probe(value)


def _workpiece(value) -> tuple[Workpiece, str | None]:
    """A part given as an object (checked: not sunk into the table), a built-in shape's name or
    a mesh file (no pose of its own: it is put on the table, its lowest point on the top), and
    a line saying so where the file's part was moved."""
    if isinstance(value, Workpiece):
        check_on_table(value, "move it up (its mesh and truth in the table frame, z = 0 the table top; "
                              "resting_on_table(part)[0] puts a loaded file's part on the table)")
        check_over_table(value, "move it over the table (its mesh and truth in the table frame, the axis x = y = 0)")
        return value, None
    if not isinstance(value, (str, Path)):
        raise InputError(f"workpiece must be a Workpiece, a built-in shape's name ({', '.join(BUILTINS)}) or a mesh "
                         f"file's path, got {value!r}")
    if value in BUILTINS:
        return builtin_workpiece(value), None
    part, lift = resting_on_table(load_workpiece(value))
    moved = lift_text(lift, decimals=2)
    return part, None if moved is None else f"the part from {value} was put on the table: {moved}"


def drain(steps):
    """Run a generator of steps (a scan's chunks) to its end; returns what it returns."""
    while True:
        try:
            next(steps)
        except StopIteration as done:
            return done.value


class Scanner:
    """A simulated cell: a robot carrying the probe over a part on the rotary table.

    ``Scanner(robot=..., probe=..., workpiece=..., table=..., render=..., detect=...)`` takes
    objects or names (a rig name under rigs/, a path, a built-in shape name or a mesh file);
    ``Scanner.from_config(name_or_path, **overrides)`` takes a scan config and the command
    line's overrides (engine, samples, resolution, detect, frames, device).
    """

    def __init__(self, robot: Robot | str = "adept_viper_s650", probe: Probe | str = "default",
                 workpiece: Workpiece | str = "sphere", table: Turntable | None = None,
                 render: RenderOptions | None = None, detect: str = "gauss", *, config: ScanConfig | None = None,
                 scene=None):
        moved = None
        if table is not None and not isinstance(table, Turntable):
            raise InputError(f"table must be a Turntable (None: the paper's), got {table!r}")
        if config is not None and not isinstance(config, ScanConfig):
            raise InputError(f"config must be a ScanConfig (load_scan_config(name or path)), got {config!r}")
        if render is not None and not isinstance(render, RenderOptions):
            raise InputError(f"render must be a RenderOptions (None: the demo's), got {render!r}; for another "
                             f"engine: Scanner.from_config(config, engine=...) or config.with_overrides(engine=...)")
        if config is None:
            base = load_scan_config("demo")  # the detection, filter and leave-out defaults of a scan
            part, moved = _workpiece(workpiece)
            robot, table = _robot(robot), table or Turntable()
            config = replace(base, name="Scanner", source="", robot=robot, probe=_probe(probe), table=table,
                             workpiece=part, waypoints=Waypoints(np.zeros((0, 4, 4)), np.zeros(0), np.zeros(0, int)),
                             q_start=base.start_joints_for(robot, table), render=render or base.render)
            config = config.with_overrides(detect=detect)
        self.config = config  # (and the renderers, built at the first measurement: see config)
        self._scene = scene
        self._q = self._start_joints()
        self._table_rad = float(config.waypoints.table_rad[0]) if len(config.waypoints) else 0.0
        self._parts: list[Cloud] = []
        self._stats: list[dict] = []
        self._timing = {"plan": 0.0, "scene": 0.0, "render": 0.0, "detect": 0.0, "triangulate": 0.0}
        self._cameras: set[int] = set()
        self._warnings: list[str] = [moved] if moved else []
        self._empty_frames: list[int] = []  # frames that put no surface inside the probe's range
        self._off_path = False  # measured anything but the config's path (run())
        self._path_again = False  # run() after something was measured: no path frame numbers
        self._t0 = time.perf_counter()
        self._cached = None  # (key, ScanResult, config) of the last result(): report() after save() is free
        self._extra: dict = {}  # what joins the report besides the scan itself (an adaptive scan's sweeps)
        self._poses: list[tuple[np.ndarray, np.ndarray]] = []  # (q (n, 6), table_rad (n,)) of every measurement
        self._clearances: list = []  # the collision check of every move and path (PathClearance)
        self._planner = None  # the adaptive planner of the last adaptive() call, to go on from
        self._planner_config = None  # the config that planner was made for
        self._last_plan = None  # (what was planned, with clearance, the plan): _plan_waypoints
        # False: sweeps and paths are still refused where they would collide, but their nearest
        # clearance is not measured for the report (two thirds of a raycast sweep's time; a
        # training loop's choice, see headless/scan_env.py).
        self.keep_clearance = True
        self._fixture_frames: dict = {}  # {fixture: frames it stood in the way of the laser or a camera}
        # (a config file's own start_deg stands: one without [[path]], as the adaptive planner
        # takes, started elsewhere than the same file with a path)
        if not len(config.waypoints) and not (config.source and config.q_start is not None):
            self._look_at_the_table()

    @property
    def frames_taken(self) -> int:
        """Profiles measured so far (the report's ``frames``; the next one's frame number),
        without measuring them against the part as report() does: a planner's budget count."""
        return sum(len(q) for q, _ in self._poses)


    def _look_at_the_table(self) -> None:
        """Without a path, start with the probe looking straight down at the table's centre from
        the middle of its range, where the robot can reach that (else at the start joints)."""
        z0, z1 = self.config.probe.z_range_mm
        try:
            self.move_to(((0.0, 0.0, 0.5 * (z0 + z1)), (90.0, 180.0, 0.0)))
        except (UnreachablePose, CollisionError):
            pass

    @classmethod
    def from_config(cls, name_or_path: str | Path, scene=None, **overrides) -> "Scanner":
        """A scanner for a scan config (a name under rigs/scenes/ or a path), with overrides
        as on the command line: engine, samples, resolution (W, H), detect, frames (a slice), device."""
        allowed = ("engine", "samples", "resolution", "detect", "frames", "device")
        unknown = sorted(set(overrides) - set(allowed))
        if unknown:
            raise InputError(f"Scanner.from_config: unknown override {unknown[0]!r}; allowed: {', '.join(allowed)}")
        return cls(config=load_scan_config(name_or_path, path_required=False).with_overrides(**overrides),
                   scene=scene)

    # -- state ---------------------------------------------------------------------------
    def _start_joints(self) -> np.ndarray:
        cfg = self.config
        if cfg.q_start is not None:
            return np.array(cfg.q_start, dtype=np.float64)
        lo, hi = cfg.robot.q_min_rad, cfg.robot.q_max_rad
        return np.clip(np.zeros(6), lo, hi)

    @property
    def q(self) -> np.ndarray:
        """(6,) rad: the robot's joints now."""
        return self._q.copy()

    @property
    def table_deg(self) -> float:
        """The table's angle now, in degrees (to 1e-9°: turned to 30°, it reads 30.0, not the
        29.999999999999996 that radians and back make of it)."""
        return round(math.degrees(self._table_rad), 9)

    @property
    def config(self) -> ScanConfig:
        """The scan config: the cell, the part, the probe, the render settings. Replaced by
        assignment, it takes effect from the next measurement on: what renders and what is ray
        cast are built again for it (they scanned the old part before)."""
        return self._config

    @config.setter
    def config(self, value) -> None:
        if not isinstance(value, ScanConfig):
            raise InputError(f"config must be a ScanConfig (load_scan_config(name or path)), got {value!r}")
        self._config = value
        self._sc = None  # the Blender cell, built at the first measurement
        self._raycaster = None  # with engine raycast: its renderer, built at the first measurement
        self._surfaces = None  # the part and table for ray casts, built at the first measurement

    def pose(self, relative_to: str = "table") -> np.ndarray:
        """(4, 4) mm: the probe frame's pose (laser at the origin, beam along +Z) now, in the
        table frame or ("base") the world frame: the robot's base frame unless its rig gives a
        [base] pose."""
        if relative_to not in RELATIVE_TO:
            raise InputError(f"relative_to must be one of {', '.join(RELATIVE_TO)}, got {relative_to!r}")
        cell = self.config.cell
        return cell.probe2table(self._q, self._table_rad) if relative_to == "table" else cell.probe2base(self._q)

    @property
    def scene_cell(self):
        """The Blender cell the scanner renders in (None before the first measurement)."""
        return self._sc

    @property
    def planner(self):
        """The adaptive planner of the last :meth:`adaptive` call (``addon.adaptive.NextBestView``),
        None before one: its model of what is known (``planner.space``, a KnownSpace of unknown,
        free and surface cells), its candidates (``planner.pool``) and ``planner.feasible(scanner, c)``,
        for a planner of one's own to read or build on. A later adaptive() call goes on from it.
        To build on one before any adaptive() call: ``addon.adaptive.NextBestView(scanner,
        *part_box(config))`` (docs/adaptive.md, *A planner of your own*)."""
        return self._planner

    @property
    def cloud(self) -> Cloud:
        """Every profile's points so far (table frame), as measured: the neighbouring profiles
        have not judged them yet. The cloud a report counts and save() writes is
        ``result().cloud``: these less the points the profiles across the line drop (uncertain,
        steep surface; report.points_dropped)."""
        return Cloud.concatenate(self._parts)

    def _note_fixtures(self, fixture_frames: dict, first: int) -> None:
        """Add a plan's fixtures in the laser's way (frames from 0) as frames from ``first``."""
        for name, frames in fixture_frames.items():
            self._fixture_frames[name] = np.union1d(self._fixture_frames.get(name, []),
                                                    np.asarray(frames) + first).astype(int)

    def measurements(self, first: int = 0):
        """Every profile measured from frame ``first`` on, in order, as (its frame, the probe's
        pose in the table frame (4, 4), its points (n, 3), table frame): what a planner that
        joins a scan under way learns from."""
        first = check_whole(first, "measurements(first): the frame to start from", 0, 2**62)
        if first >= self.frames_taken:
            return
        q = np.concatenate([p[0] for p in self._poses])[first:]
        table_rad = np.concatenate([p[1] for p in self._poses])[first:]
        probe2table = self.config.cell.probe2table(q, table_rad)
        cloud = self.cloud
        order = np.argsort(cloud.frame, kind="stable")
        frames, points = cloud.frame[order], cloud.points[order]
        cuts = np.searchsorted(frames, np.arange(first, self.frames_taken + 1))
        for i in range(len(q)):
            yield first + i, probe2table[i], points[cuts[i]:cuts[i + 1]]

    # -- moves ---------------------------------------------------------------------------
    def move_to(self, pose, relative_to: str = "table") -> np.ndarray:
        """Put the probe at ``pose``: a (4, 4) transform, or (xyz_mm, yzz_deg), relative to the
        table or the robot base ("base": the world frame, the robot's base frame unless its rig
        gives a [base] pose). IK takes the branch nearest the current joints. Returns the
        new joints; raises UnreachablePose where the pose cannot be reached and CollisionError
        where the pose or the motion to it comes too near the table, the part or a fixture (or
        the robot to itself), naming the two bodies: in either case nothing moves."""
        q = self._joints_for(pose, relative_to)
        self._check_move(q, self._table_rad)
        self._q = q
        return self.q

    def check_move_to(self, pose, relative_to: str = "table"):
        """What :meth:`move_to` would do, with nothing moved: (the joints it would take, the
        clearance at the pose moved to: a PathClearance whose ``nearest`` gives its smallest
        distance to the table, the part or a fixture, None where the config turns the checks
        off). Raises as move_to does where the pose cannot be reached or the motion there
        collides or comes nearer than the clearance allows (the motion is checked all along;
        its own smallest distance on the way is not reported)."""
        q = self._joints_for(pose, relative_to)
        return q, self._check_path(q[None, :], np.array([self._table_rad]), "move")

    def _joints_for(self, pose, relative_to: str) -> np.ndarray:
        """The joints that put the probe at ``pose`` (the IK branch nearest the current joints),
        or UnreachablePose naming the pose."""
        T = self._as_pose(pose)
        if relative_to not in RELATIVE_TO:
            raise InputError(f"relative_to must be one of {', '.join(RELATIVE_TO)}, got {relative_to!r}")
        res = self.config.cell.ik(T, self._q, relative_to=relative_to, table_angle_rad=self._table_rad)
        if not res.success:
            xyz, yzz = pose_to_xyz_yzz(T)
            raise UnreachablePose(f"probe pose {np.round(xyz, 3).tolist()} mm, YZZ' "
                                  f"{np.round(np.degrees(yzz), 3).tolist()} deg relative to the {relative_to} "
                                  f"cannot be reached: {res.message}", res)
        return np.array(res.q, dtype=np.float64)

    def move_joints(self, q) -> np.ndarray:
        """Set the robot's joints (6,) rad; raises UnreachablePose outside the limits and
        CollisionError where the pose or the motion to it collides (and moves nothing)."""
        q = self.config.robot.check_q(q)
        if q.shape != (6,):
            raise InputError(f"move_joints takes 6 joint angles, got shape {q.shape}")
        bad = self.config.robot.limit_violations(q)
        if bad:
            raise UnreachablePose("joints outside the robot's limits: " + "; ".join(bad))
        self._check_move(np.array(q, dtype=np.float64), self._table_rad)
        self._q = np.array(q, dtype=np.float64)
        return self.q

    def turn_table(self, deg: float) -> float:
        """Turn the table by ``deg`` degrees; returns its new angle (degrees). Raises
        CollisionError (and turns nothing) where the part or a fixture would hit the robot."""
        _check_table_deg(deg, "table turn")
        return self._turn_table_by(math.radians(deg))

    def _turn_table_by(self, rad: float) -> float:
        return self._turn_table_to_rad(self._table_rad + rad)

    def _turn_table_to_rad(self, rad: float) -> float:
        self._check_move(self._q, rad)
        self._table_rad = rad
        return self.table_deg

    def turn_table_to(self, deg: float) -> float:
        """Turn the table to the angle ``deg`` (degrees; :meth:`turn_table` turns it by an angle);
        returns the new angle. Raises CollisionError (and turns nothing) as turn_table does."""
        _check_table_deg(deg, "table angle")
        return self._turn_table_to_rad(math.radians(float(deg)))

    def _check_move(self, q: np.ndarray, table_rad: float) -> None:
        """Collision checks on the motion from the current joints and table angle to these."""
        found = self._check_path(q[None, :], np.array([table_rad]), "move")
        if found is not None:  # the pose moved to: where the next frame will be taken
            self._clearances.append(found.shifted(self.frames_taken, move=True))

    def _check_path(self, q: np.ndarray, table_rad: np.ndarray, what: str = "sweep", record: bool = True):
        """Collision checks on the motion from the current joints and table angle through q (n, 6):
        the clearance found where ``record`` (else only collisions are looked for), for the caller
        to keep once the motion has been made."""
        from .core.scan.plan import check_motion

        t = time.perf_counter()
        try:
            found = check_motion(self.config, q, table_rad, None, self._q, self._table_rad, nearest=record,
                                 may_back_away=what == "move")
        except CollisionError as exc:
            raise CollisionError(f"{what} refused, nothing moved: {exc}") from None
        finally:
            self._timing["plan"] += time.perf_counter() - t
        return found

    def clearance(self):
        """The collision check of the current pose (a PathClearance: ``nearest`` gives the
        smallest clearance and its bodies); None where the config turns the checks off."""
        from .core.scan.plan import collision_model

        if not self.config.safety.check:
            return None
        return collision_model(self.config).clearance_at(self._q, self._table_rad)

    def _check_can_move(self, what: str) -> None:
        """CollisionError where the robot stands in a collision now: no motion starts from
        there (every move was refused with the budget or the box blamed: a start_deg that put
        the probe in a tall part)."""
        here = self.clearance()
        if here is None or here.first_collision is None:
            return
        hit = here.first_collision[0]
        at_start = np.array_equal(self._q, self._start_joints()) and self._table_rad == (
            float(self.config.waypoints.table_rad[0]) if len(self.config.waypoints) else 0.0)
        # (a Scanner made without a config file has a start pose of its own, not a start_deg)
        where = ("at the start pose (the config's [robot] start_deg)"
                 if at_start and self.config.q_start is not None and self.config.source
                 else "at the start pose" if at_start else "where the robot stands now")
        raise CollisionError(f"{what}: {where} {here.in_words(hit)} (at least "
                             f"{self.config.safety.min_clearance_mm:g} mm allowed), and no motion starts from a "
                             f"colliding pose: give a start pose that keeps the robot and probe clear of the part")

    def add_time(self, stage: str, seconds: float) -> None:
        """Count ``seconds`` to report.json's ``time_s[stage]`` (a planner's own work: the
        reference planner counts its model's updates and its choices as "planner")."""
        self._timing[stage] = self._timing.get(stage, 0.0) + float(seconds)

    def plan_seconds(self) -> float:
        """The seconds counted so far to the "plan" stage (motion planning and its collision
        checks), for a planner that times its own work apart from the Scanner's."""
        return self._timing["plan"]

    @staticmethod
    def _as_pose(pose) -> np.ndarray:
        if isinstance(pose, tuple) and len(pose) == 2:
            try:
                xyz, yzz_deg = (np.asarray(v, dtype=np.float64) for v in pose)
            except (TypeError, ValueError):
                xyz = yzz_deg = np.full(0, np.nan)
            if xyz.shape != (3,) or yzz_deg.shape != (3,) or not (np.isfinite(xyz).all() and np.isfinite(yzz_deg).all()):
                raise InputError(f"a pose as (xyz_mm, yzz_deg) needs three finite numbers in each, got {pose!r}")
            return pose_from_xyz_yzz(xyz, np.radians(yzz_deg))
        return check_transform(pose, "probe pose")

    # -- measuring -----------------------------------------------------------------------
    def measure(self) -> Profile:
        """One profile at the current pose (nothing moves). A pose whose laser meets nothing
        in the probe's range gives an empty profile without rendering."""
        return self._scan_frames(self._q[None, :], np.array([self._table_rad]))[0]

    def sweep(self, from_mm, to_mm, frames: int, *, beam=(0.0, 0.0, -1.0), line=None,
              table_deg: float | None = None) -> list[Profile]:
        """``frames`` profiles with the probe moving in a straight line from ``from_mm`` to
        ``to_mm`` (table frame), beam straight down unless given, the laser line across the
        motion; with ``table_deg``, the table turned to that angle on the way to the first pose
        (the robot and the table move together, and that motion is what is checked). Every pose
        is solved before anything moves or renders; the probe ends at the last one."""
        return self._scan_waypoints(self._sweep_waypoints(from_mm, to_mm, frames, beam, line, table_deg), "sweep")

    def plan_sweep(self, from_mm, to_mm, frames: int, *, beam=(0.0, 0.0, -1.0), line=None,
                   table_deg: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The joints (frames, 6) and table angles (frames,) rad of that sweep, solved and
        checked for collisions from where the robot and the table are now, without moving or
        rendering anything (a planner's question: can the robot do this?). Raises
        UnreachablePose or CollisionError as ``sweep`` would."""
        return self._plan_waypoints(self._sweep_waypoints(from_mm, to_mm, frames, beam, line, table_deg),
                                    what="sweep")[:2]

    def _cell_surfaces(self):
        """The part, table and table fixtures for ray casts, built at the first need."""
        if self._surfaces is None:
            from .pipeline import cell_surfaces

            self._surfaces = cell_surfaces(self.config)
        return self._surfaces

    def frames_out_of_range(self, q: np.ndarray, table_rad: np.ndarray) -> np.ndarray:
        """Indices of the frames at joints q (n, 6) and table angles (n,) rad (what plan_sweep
        and plan_path give) whose laser puts no surface (part, table, table fixture) inside the
        probe's range: such frames would measure nothing. Ray casts only, nothing moves.

        It casts against the part's own mesh, as a cell designer checking a path would: a
        planner that must not know the part (as the reference planner does not) asks its own
        model instead (``scanner.planner.space``, ``core.scan.next_view.gain``)."""
        from .core.geometry.footprint import laser_footprint

        q = np.asarray(q, dtype=np.float64)
        table_rad = np.asarray(table_rad, dtype=np.float64)
        if q.ndim != 2 or q.shape[1] != 6 or table_rad.shape != (len(q),):
            raise InputError(f"frames_out_of_range needs joints (n, 6) and table angles (n,), got shapes "
                             f"{q.shape} and {table_rad.shape}")
        if not (np.isfinite(q).all() and np.isfinite(table_rad).all()):
            raise InputError(f"frames_out_of_range needs finite joints and table angles; frames "
                             f"{np.flatnonzero(~(np.isfinite(q).all(axis=1) & np.isfinite(table_rad))).tolist()[:5]} "
                             f"hold NaN or infinity")
        foot = laser_footprint(self.config.probe, self.config.cell.probe2table(q, table_rad), self._cell_surfaces())
        return np.asarray(foot.empty_frames, dtype=int)

    def _sweep_waypoints(self, from_mm, to_mm, frames, beam, line, table_deg) -> Waypoints:
        """A sweep's waypoints (table frame); path.sweep checks the frames, ends, beam and line."""
        if table_deg is not None:
            _check_table_deg(table_deg, "sweep table_deg")  # as turn_table_to's angle
        table_rad = self._table_rad if table_deg is None else math.radians(float(table_deg))
        return sweep_waypoints(frames, from_mm, to_mm, beam, line, table_rad=table_rad)

    def _plan_waypoints(self, wp: Waypoints, record: bool = False, what: str = "path"):
        """(joints, table angles, clearance) of waypoints: solved from the current joints and
        collision-checked from where the robot and the table are now; nothing moves."""
        from .core.kinematics.path import solve_path

        if not isinstance(wp, Waypoints):
            raise InputError(f"a path is Waypoints (addon.core.kinematics.path: sweep, turntable, concatenate), "
                             f"got {type(wp).__name__}")
        if len(wp) == 0:
            raise InputError(f"the {what} has no waypoints: give at least one")
        # The same waypoints planned again from the same joints and table angle with the same
        # config plan the same (a planner asks plan_path whether a view is possible, then scans
        # it: the Gym environment's steps planned every view twice, 30 % of a step's time).
        key = (self._config, wp.probe2table.tobytes(), wp.table_rad.tobytes(), self._q.tobytes(), self._table_rad)
        memo = self._last_plan
        if memo is not None and memo[0][0] is key[0] and memo[0][1:] == key[1:] and (memo[1] or not record):
            q, table_rad, found = memo[2]
            return q.copy(), table_rad.copy(), found
        # The turn from where the table stands, as turn_table's (a 1e6 rad path asked the collision
        # check for a sample per millimetre of the turn; a table already turned far may go on)
        _check_table_deg(float(np.max(np.abs(np.degrees(wp.table_rad - self._table_rad)))),
                         f"the {what}'s table turn from where the table stands")
        # Stopped at the first pose out of reach: the refusal names that one (a numeric IK's
        # failure costs its restarts at every pose after it: a planner asking whether a view on
        # the URDF gantry can be done waited 14-64 s for each one it could not).
        sol = solve_path(self.config.cell, wp, self._q, stop_at_miss=True)
        if not sol.ok.all():
            first = sol.unreachable[0]
            raise UnreachablePose(f"the {what} cannot be reached at its pose {first} of {len(wp.table_rad)} (the "
                                  f"poses after it were not tried): {sol.messages[first]}")
        found = self._check_path(sol.q, wp.table_rad, what, record=record)
        q, table_rad = np.array(sol.q, dtype=np.float64), np.array(wp.table_rad, dtype=np.float64)
        self._last_plan = (key, record, (q.copy(), table_rad.copy(), found))
        return q, table_rad, found

    def prepare_checks(self) -> None:
        """Build the cell's collision model now rather than inside the first collision check
        (for callers that time their decisions, such as the adaptive planner while it sets up);
        nothing when the config turns the checks off."""
        from .core.scan.plan import collision_model

        if self.config.safety.check:
            collision_model(self.config)

    def plan_path(self, waypoints: Waypoints) -> tuple[np.ndarray, np.ndarray]:
        """``plan_sweep`` for any waypoints (core.kinematics.path: a turntable pass, a sweep,
        several concatenated): (joints, table angles rad), nothing moved."""
        return self._plan_waypoints(waypoints)[:2]

    def scan_path(self, waypoints: Waypoints, progress=None) -> list[Profile]:
        """A profile at each of ``waypoints`` (probe poses in the table frame and table angles,
        e.g. ``core.kinematics.path.turntable``: the probe still while the table turns), solved
        and checked before anything moves; the robot and the table end at the last one.
        ``progress(stage, done, total)`` after each chunk of frames."""
        return drain(self.scan_path_steps(waypoints, progress))

    def scan_path_steps(self, waypoints: Waypoints, progress=None):
        """:meth:`scan_path` as a generator, for callers that must stay responsive (the panel):
        yields (frames done, frames in all) after each chunk; returns the profiles. The path is
        solved and checked before the first yield."""
        return self._waypoints_steps(waypoints, "path", progress)

    def _scan_waypoints(self, waypoints: Waypoints, what: str, progress=None) -> list[Profile]:
        return drain(self._waypoints_steps(waypoints, what, progress))

    def _waypoints_steps(self, waypoints: Waypoints, what: str, progress=None):
        q, table_rad, found = self._plan_waypoints(waypoints, record=self.keep_clearance, what=what)
        return (yield from self._frames_steps(q, table_rad, progress=progress,
                                              clearance=found if self.keep_clearance else None))

    def run(self, progress=None) -> ScanReport:
        """Scan the configured path ([[path]] entries) from its start joints; the probe ends at
        the path's last pose. ``progress(stage, done, total)`` is called after each chunk of
        frames. Returns the report of everything measured so far."""
        for _ in self.run_steps(progress):
            pass
        return self.report()

    def run_steps(self, progress=None):
        """The configured path chunk by chunk, for callers that must stay responsive (the
        panel): a generator that yields (frames done, frames in all) after each chunk. The
        path is planned (IK, reach, range) before the first yield; a refusal raises then."""
        cfg = self.config
        if not len(cfg.waypoints):
            raise InputError("this scanner has no path to run (give one in a scan config, or use sweep/measure)")
        from .pipeline import plan_scan

        t = time.perf_counter()
        plan = plan_scan(cfg)
        self._timing["plan"] += time.perf_counter() - t
        # plan_scan checks the motion from the config's start joints; the robot may stand
        # elsewhere (moved, or a scan done before): the way from there to the path's start too
        # (its time counted in "plan" by the check itself).
        self._check_path(plan.q[:1], plan.table_rad[:1], "the move to the path's start", record=False)
        again = self.frames_taken > 0
        out = yield from self._frames_steps(plan.q, plan.table_rad, plan=plan, progress=progress,
                                            clearance=plan.clearance, warnings=plan.warnings)
        # Run again after anything measured (the path twice): its frame numbers no longer say
        # which frame of the path each is (report.json's path_frames listed the first run's only).
        self._path_again |= again
        return out

    def _scene_cell(self):
        # Built at the first measurement, and again where another Scanner's cell (or the
        # panel's) has replaced it in this Blender session since.
        if self._sc is None or not self._sc.alive():
            from .pipeline import build_scan_cell

            t = time.perf_counter()
            self._sc = build_scan_cell(self.config, self._scene)
            self._timing["scene"] += time.perf_counter() - t
        return self._sc

    def _renderers(self) -> dict:
        """What renders the frames, built once: the Blender cell, or with engine raycast the
        ray-cast renderer (and the Blender cell only where a scene was given, for the panel,
        which shows the cell and imports the cloud into it)."""
        if self.config.render.engine != "raycast":
            return {"scene_cell": self._scene_cell()}
        if self._raycaster is None:
            from .pipeline import build_raycaster

            t = time.perf_counter()
            self._raycaster = build_raycaster(self.config)
            self._timing["scene"] += time.perf_counter() - t
        return {"scene_cell": None if self._scene is None else self._scene_cell(), "raycaster": self._raycaster}

    def _scan_frames(self, q: np.ndarray, table_rad: np.ndarray, progress=None) -> list[Profile]:
        """Render, detect and triangulate the frames at joints q (n, 6) and table angles (n,);
        their points join the cloud under the next frame numbers."""
        return drain(self._frames_steps(q, table_rad, progress=progress))

    def _frames_steps(self, q: np.ndarray, table_rad: np.ndarray, plan=None, progress=None, clearance=None,
                      warnings=()):
        """The work of :meth:`_scan_frames` as a generator: yields (done, total) after each
        chunk of frames and returns the profiles. The frames join this Scanner (poses, points,
        the motion's ``clearance`` and the plan's ``warnings``, the robot and the table at the
        last frame) only once they have all been measured: a run dropped or interrupted (Esc,
        Ctrl-C) midway leaves it as it was before, ready for the next measurement."""
        from .core.scan.frames import new_stats
        from .pipeline import ScanRun, plan_frames

        cfg = self.config
        t = time.perf_counter()
        own_step = plan is None  # a step of its own (measure, sweep, a path, an adaptive sweep), not run()
        if plan is None:
            plan = plan_frames(cfg, q, table_rad, allow_blind=True, surfaces=self._cell_surfaces())
            self._timing["plan"] += time.perf_counter() - t
        first = self.frames_taken
        n = len(q)
        probe2table = cfg.cell.probe2table(q, table_rad)
        if not plan.cameras:  # the laser meets nothing any camera sees: nothing to render
            self._stats.append({**new_stats(), "band_rows": [0] * n})  # measured all the same: no row rendered
            self._keep_frames(q, table_rad, plan, clearance, warnings)
            self._off_path |= own_step
            return [Profile(np.zeros((0, 3)), np.zeros(0, np.uint8), np.zeros(0), probe2table[i], q[i].copy(),
                            math.degrees(table_rad[i]), {}, first + i) for i in range(n)]
        # The configured path keeps its entries and frame numbers; a step of its own is one entry,
        # numbered as its frames join this Scanner (the sensor's noise and the motion blur read both).
        if not own_step and len(cfg.waypoints) == n:  # the path's own, whatever this Scanner measured before
            segment = cfg.waypoints.segment
            numbers = cfg.path_frames if cfg.path_frames is not None else np.arange(n)
        else:
            segment, numbers = np.zeros(n, int), np.arange(first, first + n)
        run = ScanRun(replace(cfg, waypoints=Waypoints(probe2table, table_rad, segment), path_frames=numbers), None,
                      progress, plan=plan, **self._renderers())
        while not run.step():
            yield run.done, run.n
        yield run.done, run.n
        for stage, seconds in run.stage_times().items():
            self._timing[stage] += seconds
        cloud = run.acc.cloud()
        parts, out = [], []
        for i in range(n):
            part = cloud.select(cloud.frame == i)
            parts.append(Cloud(part.points, np.full(len(part), first + i), part.camera, part.quality))
            out.append(Profile(part.points, part.camera, part.quality.astype(np.float64), probe2table[i],
                               q[i].copy(), math.degrees(table_rad[i]), run.frame_codes.get(i, {}), first + i))
        self._stats.append(run.stats)
        self._cameras |= set(plan.cameras)
        self._parts += parts
        self._keep_frames(q, table_rad, plan, clearance, warnings)
        self._off_path |= own_step
        return out

    def _keep_frames(self, q, table_rad, plan, clearance, warnings) -> None:
        """Frames measured: their poses, the fixtures their laser met, the motion's clearance and
        the plan's warnings join the scan; the robot and the table stay at the last frame."""
        self._note_fixtures(plan.fixture_frames, self.frames_taken)
        # allowed step by step (a sweep may run past the part), never silent: see _range_warning
        self._empty_frames += [self.frames_taken + int(i) for i in getattr(plan, "empty_frames", ())]
        self._poses.append((np.array(q, dtype=np.float64), np.array(table_rad, dtype=np.float64)))
        if clearance is not None:  # its frames numbered among the scan's
            self._clearances.append(clearance.shifted(self.frames_taken - len(q)))
        self._warnings += list(warnings)
        self._q = np.array(q[-1], dtype=np.float64)
        self._table_rad = float(table_rad[-1])

    def adaptive(self, box=None, *, max_profiles: int | None = None, min_gain: int | None = None,
                 target_coverage: float | None = None, progress=None, log=None) -> list:
        """Scan the part adaptively with the reference next-best-view planner (``addon.adaptive``)
        from here on, told only ``box`` = (lo, hi) (table frame, mm; default: the config's
        [adaptive] box, else the part's bounding box grown by 10 %), never the part's mesh.
        ``max_profiles``, ``min_gain`` and ``target_coverage`` (stop once the planner's own
        coverage estimate reaches this share) default to the config's [adaptive] table. Returns the
        sweeps chosen (``AdaptiveStep``); they join the report under ``adaptive``, and
        ``save(out_dir)`` writes what a scan writes. ``progress(stage, done, total)`` before each
        sweep and after each chunk of its frames; ``log(line)`` for each decision. A second call
        goes on from what the planner learnt. A budget below the planner's smallest view raises
        ``addon.adaptive.BudgetBelowView`` (an InputError), scanning and recording nothing."""
        return drain(self.adaptive_steps(box, max_profiles=max_profiles, min_gain=min_gain,
                                         target_coverage=target_coverage, progress=progress, log=log))

    def adaptive_steps(self, box=None, *, max_profiles: int | None = None, min_gain: int | None = None,
                       target_coverage: float | None = None, progress=None, log=None):
        """:meth:`adaptive` as a generator, for callers that must stay responsive (the panel,
        which stops it on Esc by dropping it): yields the profiles taken so far after each chunk
        of frames and between decisions; returns the sweeps. Dropped before its end (Esc), it
        keeps the sweeps finished until then and nothing of the one under way, so this Scanner
        (and its planner) can go on."""
        from .adaptive import NextBestView, adaptive_steps, checked_box, part_box

        settings = self.config.adaptive
        if box is None:
            lo, hi = part_box(self.config)
        elif isinstance(box, (str, bytes)) or not hasattr(box, "__len__") or len(box) != 2:
            raise InputError(f"box must be (lo, hi), two corners of three numbers each (table frame, mm), got {box!r}")
        else:
            lo, hi = checked_box(*box)
        budget = settings.max_profiles if max_profiles is None else max_profiles
        target = settings.target_coverage if target_coverage is None else target_coverage
        gain = settings.min_gain if min_gain is None else min_gain
        # Checked in adaptive_steps; numpy's integers (a training loop's) become Python's for the report.
        budget = int(budget) if isinstance(budget, np.integer) else budget
        gain = int(gain) if isinstance(gain, np.integer) else gain
        target = float(target) if isinstance(target, np.floating) else target
        # A second call goes on from what the first learnt (and from anything measured since),
        # instead of planning the same views again; a different box or cell size starts afresh.
        setup = 0.0
        # A call refused before its first sweep (a bad argument, a budget below the smallest
        # view) or stopped in it keeps the planner that was (a view done is never taken again).
        kept = (self._planner, self._planner_config)
        # The planner's candidates, probe and table are the config's: a config replaced since
        # (another probe, table or fixtures) gets a new planner, which learns what was measured.
        self._check_can_move("the planner cannot start")
        if self._planner is None or not self._planner.fits(lo, hi, settings.voxel_mm) \
                or self._planner_config is not self.config:
            t = time.perf_counter()
            self._planner = NextBestView(self, lo, hi, voxel_mm=settings.voxel_mm)
            self._planner_config = self.config
            setup = time.perf_counter() - t
        done = self._extra.get("adaptive", {}).get("sweeps", [])
        steps: list = []
        finished = False
        earlier = self._extra.get("adaptive", {}).get("max_profiles", 0)

        def record():
            # Over every adaptive() call on this Scanner: the sweeps all of them took, within
            # the budgets all of them were given; kept up to date after each sweep, so that a
            # result saved between two sweeps lists those done (it had no record at all).
            self._extra["adaptive"] = {"box_mm": [lo.tolist(), hi.tolist()], "max_profiles": earlier + budget,
                                       "target_coverage": target, "sweeps": done + [s.as_dict() for s in steps]}

        run = adaptive_steps(self, lo, hi, max_profiles=budget, min_gain=gain, target_coverage=target,
                             voxel_mm=settings.voxel_mm, progress=progress, log=log, planner=self._planner,
                             setup_s=setup, steps=steps, numbered_from=len(done))
        try:
            recorded = 0
            for taken in run:
                if len(steps) != recorded:
                    record()
                    recorded = len(steps)
                yield taken
            finished = True
            # What the run noticed about the box joins the report's warnings (printed under --quiet too).
            self._warnings += [w for w in self._planner.warnings if w not in self._warnings]
        finally:  # a run dropped or stopped after some sweeps still lists them beside their frames
            run.close()
            if not (finished or steps):
                self._planner, self._planner_config = kept
            else:
                record()
        return steps

    # -- results -------------------------------------------------------------------------
    def result(self, out_dir: str | Path | None = None, extra: dict | None = None):
        """Everything measured so far, measured against the truth (a ScanResult: cloud, the
        report's dict, per-point error and part/table split, files), and with ``out_dir``
        written there; ``extra`` joins the report (an adaptive scan's sweeps). Kept until the
        next measurement, so report() after save() is free, and save() after report() only writes."""
        from .pipeline import Plan, assemble, merge_stats, render_device

        import json

        if extra is not None and not isinstance(extra, dict):
            raise InputError(f"extra must be a dict of what joins the report, got {extra!r}")
        if extra is not None:
            from .core.scan.report import as_json

            extra = as_json(extra)  # numpy's numbers and arrays as JSON's; anything else refused now, not after
        if out_dir is not None:
            self._check_out_dir(out_dir)
        # Everything the report tells: the frames, what joins it, its warnings, the moves' clearances.
        key = (self.frames_taken, json.dumps(self._extra, sort_keys=True),
               json.dumps(extra or {}, sort_keys=True, default=str), len(self._warnings), len(self._clearances))
        # The path's frame numbers hold only while this Scanner has run nothing but its path.
        config = self.config if not (self._off_path or self._path_again) else replace(self.config, path_frames=None)
        # (A config set on the Scanner since is measured afresh: the cache holds the one it measured.)
        cached = self._cached is not None and self._cached[0] == key and self._cached[2] is self.config
        if cached:
            if out_dir is None:
                return self._cached[1]
            from .core.scan.outputs import written

            # Measured once, then written.
            self._cached = (key, written(self._cached[1], config, out_dir, self._t0), self.config)
            return self._cached[1]
        q = np.concatenate([p[0] for p in self._poses]) if self._poses else np.zeros((0, 6))
        table_rad = np.concatenate([p[1] for p in self._poses]) if self._poses else np.zeros(0)
        from .core.safety import PathClearance

        warnings = list(self._warnings) + self._range_warning()
        warnings += [w for w in self._part_check() if w not in warnings]  # run() has it from its plan
        plan = Plan(q, table_rad, tuple(sorted(self._cameras)), np.zeros((len(q), 2)), warnings,
                    PathClearance.merge(self._clearances) if self._clearances else None,
                    fixture_frames=self._fixture_frames)
        result = assemble(config, plan, self.cloud, merge_stats(self._stats), self._timing, out_dir, self._t0,
                          {"render_device": render_device(self._raycaster, self._sc), **self._extra},
                          step_by_step=self._off_path, user_extra=extra)
        self._cached = (key, result, self.config)
        return result

    def _part_check(self) -> list[str]:
        """What plan.part_warnings says of the part (an open mesh, table fixtures reaching into
        it; kept per config), once something has been measured."""
        if not self.frames_taken:
            return []
        from .core.scan.plan import part_warnings

        return part_warnings(self.config)

    def _range_warning(self) -> list[str]:
        """One line naming the frames that put no surface inside the probe's range (none: [])."""
        if not self._empty_frames:
            return []
        from .pipeline import frame_ranges

        z0, z1 = self.config.probe.z_range_mm
        n = len(self._empty_frames)
        return [f"{'frames' if n > 1 else 'frame'} {frame_ranges(self._empty_frames)} put no surface inside the "
                f"probe's range {z0:.4g}-{z1:.4g} mm and measured nothing: the probe was too near or too far from "
                f"the part and the table"]

    def report(self) -> ScanReport:
        """The report of everything measured so far: error against the part's exact shape,
        coverage, detection codes, timing (typed; ``report_json`` gives its JSON)."""
        return ScanReport.from_dict(self.result().report)

    def save(self, out_dir: str | Path) -> dict[str, Path]:
        """Write cloud.ply, report.json and preview.png into ``out_dir`` (each atomically);
        returns their paths."""
        if out_dir is None:  # result(None) would write nothing; result checks any other folder
            raise InputError("save needs an output folder (a path), got None")
        return self.result(out_dir).files

    def _check_out_dir(self, out_dir) -> None:
        """An output folder save() and result(out_dir) can write to, or one line saying why not."""
        if not isinstance(out_dir, (str, Path)) or not str(out_dir):
            raise InputError(f"save needs an output folder (a path), got {out_dir!r}")
        from .core.files import check_output_folder
        from .core.scan.outputs import OUTPUT_FILES

        # A file in the way, no permission, the part's own mesh where cloud.ply goes: one line.
        check_output_folder(out_dir, OUTPUT_FILES.values(), inputs=self.config.input_files())
