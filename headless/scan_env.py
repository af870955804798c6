"""A Gymnasium environment for learning view planners: each step chooses the next sweep of a
Scanner over a part that only its bounding box reveals.

- **action** ``MultiDiscrete([table angles, views, 2])``: a table angle (one of
  ``next_view.TABLE_STEPS``), a view (straight down, or tilted by one of the tilts from
  either side) and the kind (0 a sweep at that angle, 1 a full table turn from that view):
  the candidates the reference planner chooses among. Sweeps go no steeper than
  ``next_view.MAX_SWEEP_TILT_DEG``; a steeper one is refused like a sweep the robot cannot do.
  A table turn covers every angle, so its table step is ignored (each turn has 8 actions), and
  sweeps tilted beyond ``MAX_SWEEP_TILT_DEG`` (the ±75° views) are always refused.
- **action mask** ``env.action_mask()`` and ``info["action_mask"]``: a bool array shaped like
  the action space's ``nvec`` (table step, view, kind), False for the actions known to earn
  nothing: sweeps steeper than ``MAX_SWEEP_TILT_DEG``, views over the profile budget left,
  and views already scanned (scans are deterministic: the same view again finds next to
  nothing). Whether a view is reachable and collision-free depends on where the robot is
  and takes planning the motion (about 0.6 s a view), so it is left True: a view refused
  from one pose is allowed again, as it may be done from the next. ``sample_allowed(rng)``
  draws uniformly from the allowed actions; flatten the mask for a ``Discrete`` wrapper or
  a maskable agent.
- **observation** ``Dict(grid=Box(0, 2, (G, G, G), uint8), probe=Box((7,), float32),
  budget=Box(0, 1, (1,), float32), scanned=MultiBinary(nvec))``: the known-space model (0 unknown, 1 free, 2 surface)
  pooled to G³ cells over the part's box (a cell of the grid is surface where any model cell
  in it is, else unknown where any is, else free: no surface found is lost to the pooling),
  the probe's position (mm, table frame), beam direction and the table angle / 360, the
  share of the profile budget left, and the views scanned this episode (shaped like the
  action space, 1 where that action's view is done; a table turn's eight actions together).
- **reward**: the new coverage, the model's surface cells the sweep found, in hundreds, minus
  its time in seconds times ``time_cost``; a sweep the robot cannot do (unreachable, colliding)
  scans nothing and costs ``refusal_cost``. A view already scanned (masked) is scanned again:
  it finds next to nothing and costs its time only, a small penalty next to a new view's
  reward, so an agent that ignores the mask learns little from its repeats. (Free air the laser crossed teaches the model too,
  ``info["learnt"]``, but earns nothing.)
- the episode ends when the profiles left in the budget fit no view (its smallest as laid out
  now), or every view has been scanned (terminated), or after ``max_steps`` steps (truncated); ``info`` has the same keys after ``reset`` and every ``step``: the sweep
  (None after reset) and why it was refused (None: it was scanned), the profiles so far, the
  cells learnt and the surface cells found by the last step, the model's surface cells and its
  own coverage estimate (``KnownSpace.coverage_estimate``, a guide: it may run above or below the
  truth, see docs/adaptive.md).
- a step after the episode ended (terminated or truncated) is refused until ``reset()``.
- ``render_mode="rgb_array"``: ``render()`` gives the cloud so far over the part, coloured by
  its error against the mesh (the scan's preview), for people watching, never for the agent.
- ``engine``: the renderer, else the config's; ``"raycast"`` is the fast one for training.
  The Scanner measures no per-path clearance for its report (``keep_clearance`` off): paths
  are still refused where they would collide (measuring it took two thirds of a step's time).

Scans are deterministic, so equal actions give equal episodes: the part, its pose and the
cell are the config's in every episode (unless ``turn_part``, below), and ``reset(seed=...)``
only seeds ``env.np_random`` (Gymnasium's generator, for a policy that wants one). With
``turn_part=True`` each reset puts
the part down at an angle about the table's axis drawn from ``env.np_random`` (so the seed
decides it, and equal seeds still give equal episodes): a policy that learnt one pose by
heart meets others. The planner is told the box of the turned part (grown by 10 %), or the
config's ``[adaptive]`` box turned with it; ``info["part_turn_deg"]`` says the angle, which
the observation does not. Registered as ``ScanPlanning-v0``:
``gymnasium.make("headless.scan_env:ScanPlanning-v0", config="step_block", engine="raycast")``
imports this module and passes the keywords on. Each step renders a
whole sweep (seconds on a CPU): this is a test bench, not a fast simulator of views.
"""

from __future__ import annotations

import os

import gymnasium as gym
import numpy as np
import trimesh
from gymnasium import spaces

from addon.adaptive import NextBestView, part_box
from addon.core.config.scan import MAX_PROFILES
from addon.core.errors import InputError, check_number, check_whole
from addon.core.geometry.known_space import FREE, SURFACE, UNKNOWN
from addon.core.scan import next_view


PROBE_REACH_MM = 5000.0  # bounds of the probe's position in the observation (table frame)
ENV_ID = "ScanPlanning-v0"


MAX_COST = 1e6  # time_cost and refusal_cost at most (the reward stays finite)


class ScanPlanningEnv(gym.Env):
    metadata = {"render_modes": ["rgb_array"], "render_fps": 1}

    def __init__(self, config: str = "demo", *, max_profiles: int = 600, grid: int = 16, max_steps: int = 32,
                 time_cost: float = 0.01, refusal_cost: float = 0.5, engine: str | None = None,
                 turn_part: bool = False, render_mode: str | None = None):
        from addon.core.config.scan import load_scan_config

        if render_mode not in (None, *self.metadata["render_modes"]):
            raise InputError(f"render_mode {render_mode!r} is not one of: None, "
                             f"{', '.join(map(repr, self.metadata['render_modes']))}")
        self.render_mode = render_mode

        # numpy's integers too (check_whole takes them: a training loop's sweep passes np.int64)
        max_profiles = check_whole(max_profiles, "max_profiles (the episode's profile budget)", 1, MAX_PROFILES)
        grid = check_whole(grid, "grid (cells per side of the observation)", 2, 256)
        max_steps = check_whole(max_steps, "max_steps (sweeps per episode)", 1, 10**5)
        for value, what in ((time_cost, "time_cost"), (refusal_cost, "refusal_cost")):
            # ≥ 0 and at most a million per second or refusal (1e308 passed as finite and made
            # the reward −inf)
            check_number(value, what, 0.0, MAX_COST)
        if not isinstance(turn_part, (bool, np.bool_)):
            raise InputError(f"turn_part must be True or False, got {turn_part!r}")
        if isinstance(config, (str, os.PathLike)):
            config = load_scan_config(os.fspath(config), path_required=False)
        elif not hasattr(config, "adaptive"):
            raise InputError(f"config must be a scan config's name, a path to its .toml file or a loaded ScanConfig, "
                             f"got {config!r}")
        if engine is not None:
            from addon.core.config.render import ENGINES

            if engine not in ENGINES:
                raise InputError(f"engine must be one of {', '.join(ENGINES)} (None: the config's), got {engine!r}")
            config = config.with_overrides(engine=engine)
        self.config = config
        self.max_profiles, self.grid, self.max_steps = int(max_profiles), int(grid), int(max_steps)
        self.time_cost, self.refusal_cost = float(time_cost), float(refusal_cost)
        self.turn_part = bool(turn_part)
        self.part_turn_deg = 0.0
        self.tilts = [0.0] + [t * sign for t in next_view.TILTS_DEG[1:] for sign in (1.0, -1.0)]
        self.action_space = spaces.MultiDiscrete([next_view.TABLE_STEPS, len(self.tilts), 2])
        self.observation_space = spaces.Dict({
            "grid": spaces.Box(0, 2, (self.grid,) * 3, dtype=np.uint8),
            "probe": spaces.Box(np.array([-PROBE_REACH_MM] * 3 + [-1.0] * 3 + [0.0], dtype=np.float32),
                                np.array([PROBE_REACH_MM] * 3 + [1.0] * 3 + [1.0], dtype=np.float32)),
            # The share of the profile budget left: what ends the episode and masks the views
            # too large for it (an RL user's trial: a policy saw it only through the mask).
            "budget": spaces.Box(0.0, 1.0, (1,), dtype=np.float32),
            # The views scanned this episode, shaped like the action space (1: that action's view
            # is done; a table turn's eight actions together): with the model and the budget the
            # observation then says all that decides what an action can still earn (an RL user's
            # trial: only info's action mask told a policy which views it had done).
            "scanned": spaces.MultiBinary([int(n) for n in self.action_space.nvec]),
        })
        self.scanner = None
        self.planner = None

    def _smallest_at_any_turn(self) -> int:
        """The smallest view's profiles at the part's worst angle: its box (the turned part's
        bounds, grown as part_box grows them) is worked out every degree, and the views laid out
        for the angles where it reaches farthest along x, along y and from the axis. Worked out
        once."""
        if "_any_turn" not in self.__dict__:
            settings = self.config.adaptive
            if settings.cylinder:  # the same box at every angle
                angles = [0.0]
            elif settings.box is not None:
                corners = trimesh.bounds.corners(np.asarray(settings.box, dtype=np.float64))
                angles = _widest_turns(corners[:, :2])
            else:
                # (a turned point set reaches farthest at its convex hull's vertices: a few hundred of
                # the bunny's 50 000)
                angles = _widest_turns(np.asarray(self.config.workpiece.mesh.convex_hull.vertices)[:, :2])
            worst = 0
            for deg in angles:
                lo, hi = part_box(turned_part(self.config, deg))
                view = NextBestView(self.scanner, lo, hi, min_gain=settings.min_gain, voxel_mm=settings.voxel_mm)
                worst = max(worst, view.smallest_view())
            self.__dict__["_any_turn"] = worst
        return self.__dict__["_any_turn"]

    # -- the episode ------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        from addon import Scanner

        config, self.part_turn_deg = self.config, 0.0
        if self.turn_part:
            self.part_turn_deg = float(self.np_random.uniform(0.0, 360.0))
            config = turned_part(config, self.part_turn_deg)
        self.scanner = Scanner(config=config)
        self.scanner.keep_clearance = False  # collisions are still refused; the report's clearance is not measured
        lo, hi = part_box(config)
        settings = config.adaptive  # the model's cell and the gain a view must promise, as the command's
        self.planner = NextBestView(self.scanner, lo, hi, min_gain=settings.min_gain, voxel_mm=settings.voxel_mm)
        smallest = self.planner.smallest_view()
        if self.turn_part:
            # A turned part's box, and with it the views, grow and shrink with the angle: a budget
            # is held to the largest of them, so that every seed's reset takes it (one seed's
            # angle refused a budget another's took, in the middle of a training run).
            smallest = max(smallest, self._smallest_at_any_turn())
        if smallest > self.max_profiles:
            self.__dict__.pop("_by_key", None)  # no step, mask or reference action until a reset that works
            at_any = " at the worst angle turn_part may put the part down at" if self.turn_part else ""
            raise InputError(f"max_profiles {self.max_profiles} is below the smallest view's {smallest} profiles on "
                             f"{self.config.name}{at_any}: every action would be refused (give at least {smallest})")
        self._by_key = {c.key: c for c in self.planner.pool}
        # Views scanned this episode, by key, as they were scanned: one asked for again is
        # scanned the same way (a table turn first scanned before the part's radius was known,
        # laid out anew with fewer profiles, found new cells and earned a reward though masked).
        self._scanned: dict = {}
        self.profiles, self.steps, self._ended = 0, 0, None
        return self._observation(), self._info({"sweep": None, "refused": None}, 0, 0)

    def _info(self, info: dict, learnt: int, found: int) -> dict:
        """The step's ``info``: the same keys after reset and after every step."""
        return {**info, "part_turn_deg": self.part_turn_deg, "profiles": self.profiles, "learnt": int(learnt),
                "new_surface_cells": int(found), "surface_cells": self._surface_cells(), "coverage_estimate": self.planner.coverage_estimate(),
                "action_mask": self.action_mask()}

    def action_mask(self) -> np.ndarray:
        """Bool (table steps, views, 2): False where the action is known to earn nothing (see
        the module's notes); True where it may still scan something."""
        if not hasattr(self, "_by_key"):
            raise RuntimeError("call reset() before action_mask()")
        left = self.max_profiles - self.profiles
        frames = next_view.turn_frames(self.planner.part_radius())
        mask = np.zeros(tuple(int(n) for n in self.action_space.nvec), bool)
        for index in np.ndindex(mask.shape):
            c = self._by_key.get(self._key(*index))
            mask[index] = (c is not None and c.key not in self._scanned
                           and self.planner.sized(c, frames).frames <= left)
        return mask

    def _scanned_views(self) -> np.ndarray:
        """int8 (table steps, views, 2): 1 where the action's view was scanned this episode."""
        done = np.zeros(tuple(int(n) for n in self.action_space.nvec), np.int8)
        for index in np.ndindex(done.shape):
            done[index] = self._key(*index) in self._scanned
        return done

    def sample_allowed(self, rng: np.random.Generator) -> np.ndarray | None:
        """An action drawn uniformly from those :meth:`action_mask` allows (None: none is)."""
        allowed = np.argwhere(self.action_mask())
        return None if not len(allowed) else allowed[rng.integers(len(allowed))].astype(np.int64)

    def _surface_cells(self) -> int:
        return int((self.planner.space.state == SURFACE).sum())

    def _feasible_now(self, c) -> bool:
        """Whether the robot can do view ``c`` from where it stands. A refusal holds for this
        step only (the mask leaves the view open), so the reference planner's choice
        (reference_action) may still take it from another pose; a view already done stays done."""
        done = c.key in self.planner.impossible
        if self.planner.feasible(self.scanner, c):
            return True
        if not done:
            self.planner.impossible.discard(c.key)
        return False

    def step(self, action):
        if not hasattr(self, "_by_key"):
            raise RuntimeError("call reset() before step()")
        try:
            a = np.asarray(action)
        except (ValueError, TypeError):  # ragged ([[1, 2], [3]]): numpy's own words before
            a = np.zeros(0)
        if a.shape != (3,) or a.dtype.kind not in "iu" or not self.action_space.contains(a.astype(np.int64)):
            raise InputError(f"action {_short(action)} is not in the action space {self.action_space}: three integers "
                             f"(an integer array, as action_space.sample() gives; floats are not taken, whole ones "
                             f"neither), a table step 0..{next_view.TABLE_STEPS - 1}, a view 0..{len(self.tilts) - 1} "
                             f"and the kind (0 a sweep, 1 a table turn)")
        if self._ended:
            raise InputError(f"the episode has ended ({self._ended}); call reset() before the next step")
        table_step, view, kind = (int(v) for v in a)
        key = self._key(table_step, view, kind)
        c = self._by_key.get(key)
        # a table turn laid out for the part as known now; a view done, as it was done
        c = None if c is None else self._scanned.get(key) or self.planner.sized(c)
        self.steps += 1
        if c is None:  # a sweep steeper than next_view.MAX_SWEEP_TILT_DEG: only table turns look that low
            info = {"sweep": f"sweep at table {360.0 * table_step / next_view.TABLE_STEPS:.0f} deg, tilt "
                             f"{self.tilts[view]:.0f} deg", "refused": "no sweep is that steep (only table turns)"}
            reward, learnt, found = -self.refusal_cost, 0, 0
        elif c.frames > self.max_profiles - self.profiles:
            info = {"sweep": c.describe(), "refused": "over the profile budget"}
            reward, learnt, found = -self.refusal_cost, 0, 0
        elif not self._feasible_now(c):
            info = {"sweep": c.describe(), "refused": self.planner.refused[-1]}
            reward, learnt, found = -self.refusal_cost, 0, 0
        else:
            info = {"sweep": c.describe(), "refused": None}
            seconds = next_view.seconds(c, self.scanner.table_deg, self.scanner.pose("table")[:3, 3])
            before = self._surface_cells()
            profiles, learnt = self.planner.scan(self.scanner, c)
            self._scanned[c.key] = c
            found = max(self._surface_cells() - before, 0)
            self.profiles += len(profiles)
            reward = found / 100.0 - self.time_cost * seconds
        info = self._info(info, learnt, found)
        frames = next_view.turn_frames(self.planner.part_radius())
        terminated = self.profiles + min(self.planner.sized(c, frames).frames for c in self.planner.pool) \
            > self.max_profiles or not info["action_mask"].any()  # the budget spent, or every view scanned
        truncated = self.steps >= self.max_steps
        self._ended = "terminated" if terminated else "truncated after max_steps" if truncated else None
        return self._observation(), float(reward), bool(terminated), bool(truncated), info

    def render(self):
        """With ``render_mode="rgb_array"``: the cloud measured so far over the part, coloured by
        its error (the scan's preview.png, as an RGB array); scored against the part's mesh, which
        the observation never holds. None without a render mode, or before reset()."""
        if self.render_mode != "rgb_array" or self.scanner is None:
            return None
        from addon.core.scan.preview import render_preview

        r = self.scanner.result()
        e = r.report["error_um"]
        title = (f"step {self.steps}: {self.profiles} profiles, RMS {e['rms_um']:.1f} um, "
                 f"covers {r.report['coverage'] * 100:.0f} % of the part")
        bgr = render_preview(self.scanner.config.workpiece.mesh, r.cloud.points, r.error_um, r.on_part, title,
                             on_fixture=r.on_fixture)
        return np.ascontiguousarray(bgr[:, :, ::-1])

    # -- what the agent sees ----------------------------------------------------------------
    def _observation(self) -> dict:
        grid = pooled(self.planner.space.state, self.grid)
        pose = self.scanner.pose("table")
        probe = np.r_[np.clip(pose[:3, 3], -PROBE_REACH_MM, PROBE_REACH_MM), pose[:3, 2],
                      self.scanner.table_deg % 360.0 / 360.0].astype(np.float32)
        left = max(0.0, 1.0 - self.profiles / self.max_profiles)
        return {"grid": grid, "probe": probe, "budget": np.array([left], dtype=np.float32),
                "scanned": self._scanned_views()}

    def _key(self, table_step: int, view: int, kind: int) -> tuple:
        table_deg = 0.0 if kind == 1 else 360.0 * table_step / next_view.TABLE_STEPS
        return ("turn" if kind == 1 else "sweep", round(table_deg, 6), round(self.tilts[view], 6))

    def reference_action(self) -> np.ndarray | None:
        """The reference planner's choice as an action (None: it would stop)."""
        if not hasattr(self, "_by_key"):
            raise RuntimeError("call reset() before reference_action()")
        c = self.planner.choose(self.scanner, self.max_profiles - self.profiles)
        if c is None:
            return None
        step = int(round(c.table_deg * next_view.TABLE_STEPS / 360.0)) % next_view.TABLE_STEPS
        view = min(range(len(self.tilts)), key=lambda v: abs(self.tilts[v] - c.tilt_deg))
        return np.array([step, view, 1 if c.kind == "turn" else 0])


def _short(value) -> str:
    """``value`` for a one-line message: its repr up to 80 characters, an array's shape and type
    where its repr is longer or runs over lines."""
    text = repr(value)
    if len(text) <= 80 and "\n" not in text:
        return text
    a = np.asarray(value, dtype=object) if not isinstance(value, np.ndarray) else value
    return f"(an array of shape {a.shape}, {a.dtype})" if a.ndim else text.replace("\n", " ")[:80] + "..."


if ENV_ID not in gym.registry:  # a module imported twice (by path and by name) registers once
    # (by name, not the class: a spec with a callable cannot be written out, spec.to_json())
    gym.register(id=ENV_ID, entry_point="headless.scan_env:ScanPlanningEnv")


# Pooling order: a grid cell shows the most telling state of the model cells in it.
_RANK = np.zeros(3, np.uint8)
_RANK[[FREE, UNKNOWN, SURFACE]] = (0, 1, 2)
_STATE = np.array([FREE, UNKNOWN, SURFACE], np.uint8)


def turned_part(config, deg: float):
    """``config`` with its part turned by ``deg`` about the table's axis, the fixtures on the
    table with it (they hold the part), and its [adaptive] box (where it gives one) replaced by
    the bounds of that box turned with it."""
    from dataclasses import replace

    from addon.core.geometry.workpiece import turned_on_table
    from addon.core.kinematics.transforms import rot_z

    import trimesh

    R = rot_z(np.radians(deg))
    adaptive = config.adaptive
    if adaptive.box is not None and not adaptive.cylinder:  # (a cylinder on the axis is the same turned)
        corners = trimesh.bounds.corners(np.asarray(adaptive.box, dtype=np.float64)) @ R[:3, :3].T
        adaptive = replace(adaptive, box=(corners.min(axis=0), corners.max(axis=0)))  # the box's bounds once turned
    fixtures = tuple(replace(f, mesh=f.mesh.copy().apply_transform(R)) if f.on == "table" else f
                     for f in config.fixtures)
    return replace(config, workpiece=turned_on_table(config.workpiece, deg), adaptive=adaptive, fixtures=fixtures)


def _widest_turns(xy: np.ndarray) -> list[float]:
    """The angles (degrees, a whole number each) at which points ``xy`` turned about the
    table's axis reach farthest along x, along y, and in their bounds' corner from the axis."""
    a = np.radians(np.arange(180.0))
    c, s = np.cos(a)[:, None], np.sin(a)[:, None]
    x, y = c * xy[:, 0] - s * xy[:, 1], s * xy[:, 0] + c * xy[:, 1]
    wide_x = np.maximum(np.abs(x.min(axis=1)), np.abs(x.max(axis=1)))
    wide_y = np.maximum(np.abs(y.min(axis=1)), np.abs(y.max(axis=1)))
    picks = {int(np.argmax(wide_x)), int(np.argmax(wide_y)), int(np.argmax(np.hypot(wide_x, wide_y)))}
    return [float(k) for k in sorted(picks)]


def pooled(state: np.ndarray, cells: int) -> np.ndarray:
    """The model's states (nx, ny, nz) on ``cells``³ cells: each the surface where any model cell
    in it is surface, else unknown where any is unknown, else free; axes with fewer model cells
    than ``cells`` repeat theirs."""
    ranked = _RANK[state]
    for axis, n in enumerate(state.shape):
        if n >= cells:
            starts = np.floor(np.linspace(0, n, cells + 1)[:-1]).astype(int)
            ranked = np.maximum.reduceat(ranked, starts, axis=axis)
        else:
            ranked = np.take(ranked, np.linspace(0, n - 1, cells).round().astype(int), axis=axis)
    return _STATE[ranked].astype(np.uint8)


def coverage_curve(env: ScanPlanningEnv, policy, seed: int = 0) -> list[tuple[int, float]]:
    """Run one episode with ``policy(env, rng) -> action or None``; returns (profiles, coverage
    of the whole part against the truth) after each step (the truth used only to score)."""
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    curve = []
    while True:
        action = policy(env, rng)
        if action is None:
            break
        _, _, terminated, truncated, info = env.step(action)
        if info["refused"] is None:
            curve.append((info["profiles"], env.scanner.result().report["coverage"]))
        if terminated or truncated:
            break
    return curve


def random_policy(env, rng):
    """Any table angle and view, uniformly (seeded by ``rng``)."""
    return np.array([rng.integers(n) for n in env.action_space.nvec])


def allowed_random_policy(env, rng):
    """Any action the mask allows, uniformly (seeded by ``rng``): random views that never repeat
    a view scanned or ask for more profiles than are left."""
    return env.sample_allowed(rng)


def reference_policy(env, rng):
    return env.reference_action()


POLICIES = (("reference planner", reference_policy), ("random sweeps", random_policy),
            ("random allowed", allowed_random_policy))


def add_arguments(parser) -> None:
    from addon.core.config.render import ENGINES

    parser.add_argument("--config", default="demo", help="scan config whose cell and part to use (default demo)")
    parser.add_argument("--max-profiles", type=int, default=300, help="profile budget per episode (default 300)")
    parser.add_argument("--seed", type=int, default=0,
                        help="seed of the random baselines and the environment (default 0)")
    parser.add_argument("--seeds", type=int, default=1,
                        help="run the random baselines with this many seeds from --seed on and give their "
                             "median (default 1: one curve each)")
    parser.add_argument("--engine", choices=ENGINES, default=None,
                        help="render engine (default: the config's; raycast is the fast one)")
    parser.set_defaults(run=run)


def run(args) -> int:
    """The baselines through the environment (the reference planner, random actions, random
    actions the mask allows), their coverage curves printed one under the other."""
    check_whole(args.seeds, "--seeds", 1, 1000)
    check_whole(args.seed, "--seed", 0, 2 ** 63 - 1)  # Gymnasium's seeds are whole numbers from 0
    check_whole(args.max_profiles, "--max-profiles", 1, MAX_PROFILES)
    env = ScanPlanningEnv(args.config, max_profiles=args.max_profiles, engine=args.engine)
    try:
        env.reset(seed=args.seed)  # a budget below the smallest view is refused before anything is printed
    except InputError as exc:  # in the command's words (the option, not the constructor's argument)
        raise InputError(str(exc).replace(f"max_profiles {args.max_profiles} ", f"--max-profiles {args.max_profiles} ",
                                          1)) from None
    seeds = list(range(args.seed, args.seed + args.seeds))
    print(f"ScanPlanningEnv on {env.config.name}: {args.max_profiles} profiles per episode, "
          f"seed{'s' if len(seeds) > 1 else ''} {seeds[0]}{f'-{seeds[-1]}' if len(seeds) > 1 else ''}")
    for name, policy in POLICIES:
        if len(seeds) > 1 and policy is not reference_policy:  # the planner does not draw: one run says it
            finals = [(coverage_curve(env, policy, seed=k) or [(0, 0.0)])[-1][1] for k in seeds]
            print(f"  {name:<18} final coverage {', '.join(f'{c * 100:.1f}' for c in finals)} %: median "
                  f"{np.median(finals) * 100:.1f} %, {min(finals) * 100:.1f}-{max(finals) * 100:.1f} %")
            continue
        curve = coverage_curve(env, policy, seed=args.seed)
        points = ", ".join(f"{p} profiles {c * 100:.1f} %" for p, c in curve) or "nothing scanned"
        print(f"  {name:<18} {points}")
    return 0
