"""Adaptive scanning: the reference next-best-view planner, driving a Scanner step by step.

It starts from what a real cell knows: the table, the robot, the probe and a bounding box of
the part (never the part's mesh; a config's [[path]] entries are ignored). It takes an
overview pass (a table turn with the probe tilted, which sees the top and every side once),
then repeats: rank candidate sweeps by the new surface they would see per second of
scanning, according to what every laser ray so far has taught (core.scan.next_view over
core.geometry.known_space); ask the Scanner whether the robot can do the best one (solved
and collision-checked without moving: ``Scanner.plan_path``), else the next; scan it; add
its profiles to the model. It stops when no candidate promises ``min_gain`` new cells, when
the model's own coverage estimate reaches ``target_coverage`` (where one is set), or when
the profile budget is spent. The ground truth is used only afterwards, to score.
"""

from __future__ import annotations

import math
import numbers
import time
from dataclasses import dataclass, field

import numpy as np

from .core.config.scan import MAX_PROFILES, AdaptiveSettings
from .core.errors import CollisionError, InputError, UnreachablePose, is_whole
from .core.geometry.known_space import UNKNOWN, KnownSpace, box_arrays
from .core.geometry.metrics import NearMesh
from .core.kinematics.turntable import box_beyond_table
from .core.scan import next_view
from .core.scan.plan import table_fixtures

VOXEL_MM = AdaptiveSettings.voxel_mm
MIN_GAIN = AdaptiveSettings.min_gain  # new surface cells a view must promise
OVERVIEW_MAX_TILT_DEG = 45.0  # steeper turns look at the sides and miss the top: not an overview
MARGIN_MM = 6.0   # the model's box around the part's
TABLE_CLEARANCE_MM = 0.2  # a point this far above the table top is the part's (see part_radius)
PLATE_TOP_MIN_MM = 0.5  # a thin part's top, for its coverage estimate: points this far up at least ...
PLATE_TOP_POINTS = 50   # ... and this many of them (a few noisy table points are no part)
OUTSIDE_WARNING = 0.05  # a share of the points outside the part's box that says the box is too small
FIXTURE_NEAR_MM = 0.5  # a point this near one of the table's fixtures is the fixture's
RUNNERS_UP = 3  # the best candidates after the chosen one that each decision records


@dataclass(frozen=True)
class AdaptiveStep:
    """One decision: the sweep chosen (its description), the profiles it took, the cells it
    taught the model (``new_cells``: air and surface; ``new_surface_cells``: surface only, the
    unit of ``expected_cells``, the new surface the ranking promised), the planning time, the
    candidates refused as unreachable or colliding, and the model's coverage estimate after it
    (KnownSpace.coverage_estimate: the part's surface seen, as the model alone tells it); on
    the first decision, ``setup_s``: the planner's one-off set-up before it (the model, the
    candidate sweeps, the cell's collision model), which no later decision pays again.
    ``runners_up``: the next RUNNERS_UP candidates as ranked for this decision, each with its
    promised gain, seconds, gain per second and whether the robot was found unable to do it.
    ``kind``: "sweep" (the probe moves along a line) or "turn" (the probe still, the table
    turning); ``sweep`` describes either."""

    sweep: str
    table_deg: float
    tilt_deg: float
    profiles: int
    new_cells: int
    expected_cells: int
    planning_s: float
    refused: int
    coverage_estimate: float = 0.0
    setup_s: float = 0.0
    path: dict = field(default_factory=dict)  # the view as a scan config's [[path]] entry
    new_surface_cells: int = 0
    runners_up: tuple = ()
    kind: str = "sweep"  # what ``sweep`` describes: "sweep" (the probe moves) or "turn" (the table turns)

    def as_dict(self) -> dict:
        out = dict(self.__dict__)
        out["runners_up"] = [dict(r) for r in self.runners_up]
        return out


FLAT_BOX_MM = 5.0  # the height of the box a flat part is told (part_box)


def part_box(config, grow: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """The bounding box the planner is told: the config's [adaptive] box, else the workpiece's
    box grown by ``grow`` of its size on each side (what a cell would roughly know)."""
    if config.adaptive.box is not None:
        return tuple(np.asarray(v, dtype=np.float64) for v in config.adaptive.box)
    lo, hi = (np.asarray(v, dtype=np.float64) for v in config.workpiece.mesh.bounds)
    pad = grow * (hi - lo)
    lo, hi = lo - pad, hi + pad
    lo[2] = max(lo[2], 0.0)  # the table top
    # A flat part (a plate of no thickness) still gets a box the model can hold: a few cells high
    # (its box had no height, and the planner refused it with numpy's words).
    hi[2] = max(hi[2], lo[2] + FLAT_BOX_MM)
    return lo, hi


class BudgetBelowView(InputError):
    """A profile budget too small for any of the planner's views: nothing can be scanned.
    ``budget`` and ``smallest`` (the smallest view's profiles) let each front end name its
    own setting."""

    def __init__(self, budget: int, smallest: int):
        self.budget, self.smallest = int(budget), int(smallest)
        super().__init__(f"the budget of {self.budget} profiles is below the smallest view's {self.smallest}: "
                         f"nothing was scanned (give a budget of at least {self.smallest} profiles)")


def checked_box(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """The part's bounding box (table frame, mm) as two float arrays, or InputError naming
    what is wrong: three finite numbers each, lo < hi, its top above the table top."""
    lo_a, hi_a = box_arrays(lo, hi, "the part's bounding box")
    if hi_a[2] <= 0.0:
        raise InputError(f"the part's bounding box {lo_a.tolist()} .. {hi_a.tolist()} mm lies under the table top "
                         f"(z = 0 in the table frame): its top must be above 0")
    beyond = box_beyond_table(lo_a, hi_a)
    if beyond:
        raise InputError(f"the part's bounding box {lo_a.tolist()} .. {hi_a.tolist()} mm: {beyond}")
    return lo_a, hi_a


class NextBestView:
    """The planner's state: the known-space model over the box, the candidate sweeps, and the
    ones done or impossible. ``choose(scanner)`` picks the next view (None: nothing left worth
    it); ``scan(scanner, view)`` scans it and adds what it measured to the model."""

    def __init__(self, scanner, lo, hi, *, min_gain: int = MIN_GAIN, voxel_mm: float = VOXEL_MM):
        lo, hi = checked_box(lo, hi)
        check_min_gain(min_gain)
        self.probe = scanner.config.probe
        self.lo, self.hi, self.min_gain = lo, hi, int(min_gain)
        self.space = KnownSpace(lo - MARGIN_MM, hi + MARGIN_MM, voxel_mm)
        self.pool = next_view.candidates(scanner.config.cell, self.probe, lo, hi)
        self.table = scanner.config.cell.table
        self.reach: float | None = None  # the farthest the part was measured from the table's axis
        self.top_seen: float | None = None  # the highest the part was measured above the table top
        self.top_points = 0  # the points that measured it (PLATE_TOP_MIN_MM up at least)
        self.impossible: set = set()  # candidates done, or that the robot cannot do (unreachable, colliding)
        self.refused: list[str] = []  # why, for the last decision
        self.ranked: list = []  # the candidates the last decision ranked, best first (see runners_up)
        self.looked = False  # the overview pass has been chosen (or there was none to choose)
        self.frames_seen = 0  # the scanner's frames learnt from (catch_up)
        # The table's fixtures are the cell's, known as the table is (never the part's mesh):
        # their points are left out of the part's reach and of the box check.
        self.fixtures = [NearMesh(f.mesh) for f in table_fixtures(scanner.config)]
        self.points_seen = 0  # points above the table top learnt from ...
        self.points_outside = 0  # ... and of them, farther than a cell outside the part's box
        self.warnings: list[str] = []  # what a run noticed about the box (adaptive_steps), for the report
        # Cells a view scanned was expected to see (its fan met the cell first, unknown, in
        # range) that stayed unknown: no camera saw the spot, or every point there was dropped.
        # They no longer count as gain: they drew view after view to the same spot for nothing
        # (on the L-bracket, three sweeps in a row that added nothing).
        self.missed = np.zeros(self.space.shape, dtype=bool)
        # The cell builds its collision model once, at its first check: here, with the rest of
        # the set-up, rather than inside the first decision (the Scanner reads the part for it,
        # as a real cell's safety system knows its fixtures; the planner does not).
        scanner.prepare_checks()

    def choose(self, scanner, budget: int | None = None):
        """The next view: first the overview (:meth:`overview`), then the best candidate the
        robot can do from where it is now (checked without moving), best first down the whole
        ranking, each promising at least ``min_gain`` cells and fitting ``budget`` profiles;
        None where there is none. (It asked the best 12 only, and where the robot could do none
        of them stopped the scan as if no view were left.)"""
        if budget is not None and not (is_whole(budget) and budget >= 0):
            raise InputError(f"choose: the budget is a whole number of profiles, 0 or more (or None: no limit), "
                             f"got {budget!r}")
        probe_now = scanner.pose("table")[:3, 3]
        live = self.live()
        self.refused, self.ranked = [], []
        if not self.looked:  # until a view is scanned (scan) or no overview can be had
            first = self.overview(scanner, live, probe_now, budget)
            if first is not None:
                return first
            # None: the robot can do no overview, and never will be asked again; or none fits
            # this budget, and a larger one may be given later (a look-ahead with a small
            # budget gave up the overview for good).
            if not any(self.is_overview(c) and c.key not in self.impossible for c in live):
                self.looked = True
        ranked = [c for c in next_view.rank(self.space, self.probe, live, scanner.table_deg, probe_now, self.missed)
                  if c.gain >= self.min_gain and (budget is None or c.frames <= budget)]
        self.ranked = ranked
        for c in ranked:
            if self.feasible(scanner, c):
                return c
        return None

    def live(self) -> list:
        """The candidates not done or impossible, each as :meth:`sized` lays it out now."""
        frames = next_view.turn_frames(self.part_radius())
        return [self.sized(c, frames) for c in self.pool if c.key not in self.impossible]

    def sized(self, c, frames: int | None = None):
        """Candidate ``c`` as the planner would scan it now: a table turn with its profiles
        next_view.TURN_SPACING_MM apart at the part's radius as the model knows it so far
        (:meth:`part_radius`; ``frames`` where already worked out) instead of at the box's
        corner (on the sphere in its box, 30 mm against 51 mm: 95 profiles instead of 160);
        a sweep as it is."""
        if c.kind != "turn":
            return c
        frames = next_view.turn_frames(self.part_radius()) if frames is None else frames
        return c if c.frames == frames else next_view.resampled_turn(c, frames, self.table)

    def smallest_view(self) -> int:
        """The profiles of the planner's smallest view as it would lay it out now: a budget
        below this scans nothing."""
        frames = next_view.turn_frames(self.part_radius())
        live = [c for c in self.pool if c.key not in self.impossible] or self.pool
        return min(self.sized(c, frames).frames for c in live)

    def part_radius(self) -> float:
        """How far from the table's axis the part reaches, as measured so far: the farthest
        point inside the part's box and more than TABLE_CLEARANCE_MM above the table top (the
        table itself reaches out to the box's edge); before any, the box's corner. Surface not
        seen yet may lie farther out: there a turn sized to this radius lays its profiles
        farther apart."""
        corner = float(np.hypot(max(abs(self.lo[0]), abs(self.hi[0])), max(abs(self.lo[1]), abs(self.hi[1]))))
        return corner if self.reach is None else min(corner, self.reach)

    def fits(self, lo, hi, voxel_mm: float) -> bool:
        """Whether this planner's model is the one asked for: the same box and cell size."""
        return bool(np.array_equal(self.lo, np.asarray(lo, float)) and np.array_equal(self.hi, np.asarray(hi, float))
                    and self.space.voxel == float(voxel_mm))

    def catch_up(self, scanner) -> int:
        """Learn from every profile the scanner measured that this planner has not seen (a
        scan under way before the planner joined, or moves made between two adaptive runs);
        once anything is known, no overview is needed. Returns the profiles learnt."""
        n = 0
        for frame, probe2table, points in scanner.measurements(self.frames_seen):
            self.learn(probe2table[:3, 3], points)
            self.frames_seen = frame + 1
            n += 1
        if self.points_seen:
            self.looked = True
        return n

    def learn(self, origin, points) -> None:
        """Add one profile's points (n, 3), table frame, measured from the laser at ``origin``
        to the model, and how far from the axis the part reaches (:meth:`part_radius`)."""
        P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if not len(P):
            return
        self.space.add_points(origin, P)
        fixture = np.zeros(len(P), bool)
        for near in self.fixtures:
            fixture |= near.within(P, FIXTURE_NEAR_MM)
        above = P[(P[:, 2] > TABLE_CLEARANCE_MM) & ~fixture]
        self.points_seen += len(above)
        pad = self.space.voxel
        self.points_outside += int(np.sum(np.any((above < self.lo - pad) | (above > self.hi + pad), axis=1)))
        floor = max(self.lo[2], 0.0) + TABLE_CLEARANCE_MM  # the table top is z = 0 in the table frame
        part = np.all((P[:, :2] >= self.lo[:2]) & (P[:, :2] <= self.hi[:2]), axis=1) & (P[:, 2] > floor) \
            & (P[:, 2] <= self.hi[2]) & ~fixture
        if part.any():
            r = float(np.max(np.hypot(P[part, 0], P[part, 1])))
            self.reach = r if self.reach is None else max(self.reach, r)
        # The top of a thin part (coverage_estimate), from points clear of the table's noise: a
        # few table points 0.3 mm up set it and the estimate read 100 % of a part never seen.
        above_noise = part & (P[:, 2] >= PLATE_TOP_MIN_MM)
        if above_noise.any():
            self.top_points += int(np.count_nonzero(above_noise))
            top = float(np.max(P[above_noise, 2]))
            self.top_seen = top if self.top_seen is None else max(self.top_seen, top)

    def overview(self, scanner, live, probe_now, budget):
        """The overview pass, before anything is known: a full table turn with the probe at the
        steepest tilt the robot can hold up to OVERVIEW_MAX_TILT_DEG (45°, else 30°), which
        sees the part's top and every side once. The gain cannot choose it: in an empty model
        every ray meets the unknown where it enters the box, so every view's rays count alike,
        and a turn from straight above, all of whose rays land on the box's top, outranks the
        tilted ones while it finds only the faces that look up (on the step block 23 % of the
        part against 71 %).
        None where no tilted turn fits the budget or the robot can do none."""
        turns = [c for c in live if self.is_overview(c) and (budget is None or c.frames <= budget)]
        ranked = next_view.rank(self.space, self.probe, turns, scanner.table_deg, probe_now, self.missed)
        self.ranked = sorted(ranked, key=lambda c: (-abs(c.tilt_deg), -c.tilt_deg))
        for c in self.ranked:
            if self.feasible(scanner, c):
                return c
        return None

    @staticmethod
    def is_overview(c) -> bool:
        """Whether candidate ``c`` can be the overview: a tilted table turn, tilted no more than
        OVERVIEW_MAX_TILT_DEG."""
        return c.kind == "turn" and 0.0 < abs(c.tilt_deg) <= OVERVIEW_MAX_TILT_DEG

    def runners_up(self, chosen, n: int = RUNNERS_UP) -> tuple:
        """The ``n`` candidates ranked after ``chosen`` in the last decision: what the planner
        weighed against it (sweep, gain, seconds, gain per second, refused: the robot could
        not do it from where it stood)."""
        out = []
        for c in self.ranked:
            if c.key == chosen.key:
                continue
            out.append({"sweep": c.describe(), "kind": c.kind, "gain": int(c.gain),
                        "seconds": round(float(c.seconds), 3), "gain_per_s": round(float(c.utility), 3),
                        "refused": c.key in self.impossible})
            if len(out) == n:
                break
        return tuple(out)

    def feasible(self, scanner, c) -> bool:
        """Whether the robot can do candidate ``c`` from where it is now (nothing moves); an
        impossible one is remembered."""
        try:
            scanner.plan_path(waypoints_from_here(c.waypoints(), scanner.table_deg))
        except (UnreachablePose, CollisionError) as exc:
            self.impossible.add(c.key)
            self.refused.append(f"{c.describe()}: {str(exc)[:160]}")
            return False
        return True

    def coverage_estimate(self) -> float:
        """How much of the part's surface the model says is seen (0..1), from its box alone
        (from the table top up, where the box reaches below it: the table is not the part)."""
        lo, hi = self.lo.copy(), self.hi.copy()
        lo[2] = max(lo[2], 0.0)  # the table top is z = 0 in the table frame
        # A part measured no higher than the layer the estimate leaves out as the table top (a
        # plate under a cell thick: its box is raised to FLAT_BOX_MM, and a 1.9 mm plate read
        # 0 % after a view that saw all of its top) is estimated on the layer holding its top.
        if self.top_seen is not None and self.top_points >= PLATE_TOP_POINTS \
                and self.top_seen < lo[2] + self.space.voxel < hi[2]:
            hi[2] = max(self.top_seen, lo[2] + 1e-6)
        return self.space.coverage_estimate(lo, hi)

    def scan(self, scanner, c, progress=None) -> tuple[list, int]:
        """Scan candidate ``c`` and learn from it: (its profiles, the cells it taught). The
        cells its fans were expected to see and that stayed unknown are marked ``missed``.
        ``progress(stage, done, total)`` after each chunk of its frames."""
        from .scanner import drain

        return drain(self.scan_steps(scanner, c, progress))

    def scan_steps(self, scanner, c, progress=None):
        """:meth:`scan` as a generator: yields (frames done, frames in all) after each chunk."""
        if not callable(getattr(c, "waypoints", None)):
            raise InputError(f"scan: expected a view (a candidate from live() or choose()), got {c!r}"
                             + (": choose() gives None when no view is left worth scanning" if c is None else ""))
        # Profiles measured since this planner last learnt (a manual sweep between its views)
        # first: its own frames below would otherwise count them as seen.
        t = time.perf_counter()
        self.catch_up(scanner)
        before = self.space.counts()["unknown"]
        expected = next_view.new_cells(self.space, self.probe, c.waypoints().probe2table)
        learning = time.perf_counter() - t
        profiles = yield from scanner.scan_path_steps(waypoints_from_here(c.waypoints(), scanner.table_deg), progress)
        t = time.perf_counter()
        for p in profiles:
            self.learn(p.probe2table[:3, 3], p.points)
        self.frames_seen = max(self.frames_seen, profiles[-1].frame + 1) if profiles else self.frames_seen
        if len(expected):
            i, j, k = expected.T
            self.missed[i, j, k] |= self.space.state[i, j, k] == UNKNOWN
        # The same view again would see the same (the scan is deterministic), and so would a
        # table turn's twin from the other side (Candidate.twin_key): on the stepped shaft the
        # twin of the 75° turn promised 17 cells, the profiles between the turn's own, and
        # asking whether the robot could reach over for it took 0.9 s of a decision.
        self.impossible.update((c.key, c.twin_key))
        self.looked = True
        learnt = before - self.space.counts()["unknown"]
        scanner.add_time("planner", learning + time.perf_counter() - t)  # the model's updates
        return profiles, learnt


def waypoints_from_here(waypoints, table_deg_now: float):
    """``waypoints`` with their table angles moved by whole turns to start nearest the table's
    angle now: the same view (the table's frame repeats every turn), reached the short way
    round, as ``next_view.seconds`` counts it. A view at 0° after a turn ending at 354° starts
    at 360°, not 354° back."""
    from .core.kinematics.path import Waypoints

    if not len(waypoints):
        return waypoints
    turns = np.round((math.radians(float(table_deg_now)) - float(waypoints.table_rad[0])) / (2.0 * np.pi))
    return Waypoints(waypoints.probe2table, waypoints.table_rad + 2.0 * np.pi * turns, waypoints.segment)


def check_target_coverage(target) -> None:
    """A coverage target is None or a number in (0, 1]."""
    if target is None:
        return
    if isinstance(target, bool) or not isinstance(target, numbers.Real) or not 0.0 < target <= 1.0:
        raise InputError(f"the target coverage must be a share in (0, 1] (0.9 for 90 %), got {target!r}")


def check_min_gain(min_gain) -> None:
    """The new cells a sweep must promise: a whole number, at least 1."""
    if isinstance(min_gain, bool) or not isinstance(min_gain, (int, np.integer)) or min_gain < 1:
        raise InputError(f"min_gain (the new cells a sweep must promise) must be a whole number ≥ 1, "
                         f"got {min_gain!r}")


def adaptive_scan(scanner, lo, hi, *, max_profiles: int = AdaptiveSettings.max_profiles, min_gain: int = MIN_GAIN,
                  target_coverage: float | None = None, voxel_mm: float = VOXEL_MM, progress=None,
                  log=None, planner: NextBestView | None = None, setup_s: float = 0.0) -> list[AdaptiveStep]:
    """Scan the part inside the box [lo, hi] (table frame, mm) adaptively with ``scanner``;
    returns the decisions. ``target_coverage`` (0..1, None: none): stop once the model's
    coverage estimate reaches it. ``progress(stage, done, total)`` before each sweep and after
    each chunk of its frames (profiles of this run against ``max_profiles``). ``planner``: one
    to go on with (a second run on the same scanner; it first learns whatever the scanner
    measured since), set up in ``setup_s``; None: a new one over [lo, hi]."""
    from .scanner import drain

    return drain(adaptive_steps(scanner, lo, hi, max_profiles=max_profiles, min_gain=min_gain,
                                target_coverage=target_coverage, voxel_mm=voxel_mm, progress=progress, log=log,
                                planner=planner, setup_s=setup_s))


def adaptive_steps(scanner, lo, hi, *, max_profiles: int = AdaptiveSettings.max_profiles, min_gain: int = MIN_GAIN,
                   target_coverage: float | None = None, voxel_mm: float = VOXEL_MM, progress=None,
                   log=None, planner: NextBestView | None = None, setup_s: float = 0.0,
                   steps: list | None = None, numbered_from: int = 0):
    """:func:`adaptive_scan` as a generator: yields the profiles taken so far after each chunk
    of frames and between decisions; returns the decisions, each also appended to ``steps``
    (when given) as soon as its sweep is scanned, so a caller that drops the generator still
    knows what was done. Its arguments are checked when it is first advanced.
    ``numbered_from``: the sweeps an earlier run on the same Scanner took (the log numbers this
    run's after them, as the report lists them)."""
    if isinstance(max_profiles, bool) or not isinstance(max_profiles, (int, np.integer)) \
            or not 1 <= max_profiles <= MAX_PROFILES:
        raise InputError(f"max_profiles must be a whole number from 1 to {MAX_PROFILES}, got {max_profiles!r}")
    check_min_gain(min_gain)
    check_target_coverage(target_coverage)
    for name, value in (("progress", progress), ("log", log)):
        if value is not None and not callable(value):  # found only when first called, after a sweep
            raise InputError(f"{name} must be a function or None, got {value!r}")
    if planner is None:
        t = time.perf_counter()
        planner = NextBestView(scanner, lo, hi, min_gain=min_gain, voxel_mm=voxel_mm)
        setup_s = time.perf_counter() - t
    if log and setup_s:
        log(f"adaptive: planner set up in {setup_s:.2f} s ({len(planner.pool)} candidate sweeps)")
    planner.min_gain = int(min_gain)
    seen, outside = planner.points_seen, planner.points_outside  # this run's share is warned of, once
    t = time.perf_counter()
    caught = planner.catch_up(scanner)
    scanner.add_time("planner", time.perf_counter() - t)
    if log and caught:
        log(f"adaptive: learnt from the {caught} profiles measured before this run")
    steps = [] if steps is None else steps

    def sweeps(n: int) -> str:
        return f"{n} sweep{'s' if n != 1 else ''}" + (f" ({numbered_from + n} in all)" if numbered_from else "")

    taken = 0
    say = progress or (lambda stage, done, total: None)
    smallest = planner.smallest_view()
    if max_profiles < smallest:  # no view fits: nothing is scanned, nothing recorded
        raise BudgetBelowView(max_profiles, smallest)
    estimate = planner.coverage_estimate()
    reached = target_coverage is not None and estimate >= target_coverage  # by an earlier run: no view needed
    if reached and log:
        log(f"adaptive: stopping before any sweep: the coverage estimate {estimate * 100:.1f} % already reaches the "
            f"target {target_coverage * 100:.1f} %")
    while taken < max_profiles and not reached:
        say("adaptive", taken, max_profiles)  # a stop asked for during the last sweep takes effect here
        yield taken
        t, motion = time.perf_counter(), scanner.plan_seconds()
        chosen = planner.choose(scanner, max_profiles - taken)
        planning = time.perf_counter() - t
        # the choice, less the motion planning it asked of the Scanner (already its "plan")
        scanner.add_time("planner", max(planning - (scanner.plan_seconds() - motion), 0.0) + setup_s)
        if log:
            for why in planner.refused:
                log(f"  refused {why}")
        if chosen is None:
            if log:
                log(f"adaptive: stopping after {sweeps(len(steps))}: no reachable sweep promises {min_gain} new surface "
                    f"cells within the budget")
            break
        say("adaptive", taken, max_profiles)  # ... or during the planning
        yield taken
        before = taken
        surface = planner.space.counts()["surface"]
        runners_up = planner.runners_up(chosen)  # before the scan marks the chosen one done
        chunks = planner.scan_steps(scanner, chosen,
                                    lambda stage, done, total: say("adaptive", before + done, max_profiles))
        profiles, learnt = yield from _profiles_taken(chunks, before)
        taken += len(profiles)
        estimate = planner.coverage_estimate()
        step = AdaptiveStep(chosen.describe(), chosen.table_deg, chosen.tilt_deg, len(profiles), learnt,
                            chosen.gain, planning, len(planner.refused), estimate, setup_s,
                            chosen.path_entry(), planner.space.counts()["surface"] - surface, runners_up,
                            chosen.kind)
        steps.append(step)
        setup_s = 0.0
        if log:
            log(f"adaptive: sweep {numbered_from + len(steps)}: {step.sweep}; it found {step.new_surface_cells} new surface "
                f"cells (the model learnt {step.new_cells} cells it knew nothing of, air and surface), coverage estimate "
                f"{estimate * 100:.0f} % (planned in {planning:.2f} s, {step.refused} refused)")
        if progress:
            progress("adaptive", taken, max_profiles)
        if target_coverage is not None and estimate >= target_coverage:
            if log:
                log(f"adaptive: stopping after {sweeps(len(steps))}: the coverage estimate {estimate * 100:.1f} % "
                    f"reached the target {target_coverage * 100:.1f} %")
            break
    new = planner.points_seen - seen
    outside = (planner.points_outside - outside) / new if new else 0.0
    box = f"{planner.lo.round(1).tolist()} .. {planner.hi.round(1).tolist()} mm"
    told = "([adaptive] box_min_mm/box_max_mm or radius_mm/height_mm)"
    warnings = []
    if outside > OUTSIDE_WARNING:
        warnings.append(f"{outside * 100:.0f} % of the points measured above the table lie outside the part's box "
                        f"{box}: the part (or something else on the table) reaches beyond the box the planner was "
                        f"told {told}, which plans and estimates coverage inside it only")
    elif steps and not new:
        z0, z1 = scanner.config.probe.z_range_mm
        size = float(np.max(planner.hi - planner.lo))
        why = "may not hold the part" + (
            f", or be far larger than it ({size:.0f} mm across, against the probe's {z1 - z0:.0f} mm of range: "
            f"views aimed at the box miss a small part inside it)" if size > 2.0 * (z1 - z0) else "")
        warnings.append(f"no point was measured above the table in this run: the part's box {box} the planner was told "
                        f"{told} {why}")
    for w in warnings:
        if log:
            log(f"adaptive: warning: {w}")
    planner.warnings += [w for w in warnings if w not in planner.warnings]  # the Scanner's report takes them
    return steps


def _profiles_taken(steps, before: int):
    """A sweep's chunks as the profiles of the whole run taken so far; returns what it returns."""
    while True:
        try:
            done, _ = next(steps)
        except StopIteration as end:
            return end.value
        yield before + done
