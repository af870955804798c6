"""Next-best-view planning on the known-space model: candidate views around a part's bounding
box, what each would newly see, and its cost in scan time. Never reads the part's mesh.

A candidate is a straight sweep across the box at a table angle and a tilt of the beam
from vertical (the probe on the robot's side of the table), or a full table turn with the
probe still (see ``candidates``). Its **gain** is estimated by casting its laser fan
(a subset of its frames and rays) through the model (geometry.known_space): a ray whose
first cell that is not free is unknown, within the probe's range, would measure
something new there; the gain is the number of distinct such cells. Its **cost** is the
time it takes: its frames at the scanner's rate, the table's turn and the probe's travel
to its start. The planner scans the candidate with the most gain per second among those
the robot can reach without collision (checked by the caller, best first).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..errors import InputError
from ..geometry.footprint import fan_rays
from ..geometry.known_space import UNKNOWN, KnownSpace
from ..kinematics import path as scanpath
from ..optics.probe import Probe

FRAME_S = 0.05            # one profile (the scanner's rate, about 20 profiles/s on two cores)
TABLE_DEG_PER_S = 45.0    # rotary table
PROBE_MM_PER_S = 250.0    # probe travel between sweeps
SPACING_MM = 1.5          # profile spacing along a sweep
# A table turn's profiles, at the part's outermost radius: the coverage tolerance (1 mm either
# side of a point) asks for 2 mm at most. (At 1.5 mm, as a sweep's, the overview alone took 180
# of the benchmark's 270 profiles, and a planner could not reach the table turns' coverage with
# 60 % of their profiles on any but the thin-walled tube.)
TURN_SPACING_MM = 2.0
# 75°, aimed at a fifth of the part's height: near the horizon, the sides down to the table and
# what hangs over them (at 70° aimed at 0.3 of the height, the round parts of the benchmark kept
# less of their lower sides: docs/adaptive.md).
TILTS_DEG = (0.0, 30.0, 45.0, 75.0)
TABLE_STEPS = 8
MAX_SWEEP_TILT_DEG = 45.0  # steeper views are table turns only
MAX_TURN_FRAMES = 180   # a table turn's profiles at most
SAMPLE_FRAMES = 24        # frames of a candidate cast into the model (see rank)
SAMPLE_RAYS = 17          # rays of the fan per cast frame


@dataclass(frozen=True)
class Candidate:
    """A view to scan: ``kind`` "sweep" (the probe moves in a line) or "turn" (the probe still,
    the table turning a full circle), its table angle at the start and tilt, and its waypoints
    (probe poses in the table frame, table angles); gain and seconds once ranked."""

    kind: str
    table_deg: float
    tilt_deg: float
    wp: scanpath.Waypoints
    gain: int = 0
    seconds: float = 0.0

    @property
    def frames(self) -> int:
        return len(self.wp.table_rad)

    @property
    def start_mm(self) -> np.ndarray:
        return self.wp.probe2table[0, :3, 3]

    @property
    def key(self) -> tuple:
        return (self.kind, round(self.table_deg, 6), round(self.tilt_deg, 6))

    @property
    def twin_key(self) -> tuple:
        """The key of the view that sees what this one sees: for a table turn, the same turn
        from the other side of the part (its poses are this one's turned half a circle about
        the table's axis, so over its full circle it meets the part as this one does: the same
        profiles, or with an odd number of them, profiles between them); a sweep's own key."""
        if self.kind != "turn":
            return self.key
        return (self.kind, round(self.table_deg, 6), round(-self.tilt_deg, 6))

    @property
    def utility(self) -> float:
        return self.gain / max(self.seconds, 1e-9)

    def waypoints(self) -> scanpath.Waypoints:
        return self.wp

    def path_entry(self) -> dict:
        """The view as a scan config's [[path]] entry (kinematics.path.path_entry)."""
        return scanpath.path_entry(self.wp, "sweep" if self.kind == "sweep" else "turntable")

    def describe(self) -> str:
        what = "sweep" if self.kind == "sweep" else "table turn"
        text = f"{what} at table {self.table_deg:.0f} deg, tilt {self.tilt_deg:.0f} deg, {self.frames} profiles"
        # Only a ranked candidate has a gain; one picked by hand (an agent's action) has none yet.
        return text + (f", promising about {self.gain} new surface cells" if self.seconds > 0 else "")


def robot_side(cell, table_deg: float) -> np.ndarray:
    """Horizontal unit vector (table frame, at that table angle) from the table's axis towards
    the robot's base."""
    base = cell.table.base2table(math.radians(table_deg))[:3, 3]
    side = np.array([base[0], base[1], 0.0])
    n = np.linalg.norm(side)
    return side / n if n > 1e-9 else np.array([1.0, 0.0, 0.0])


def candidates(cell, probe: Probe, lo, hi) -> list[Candidate]:
    """Views of the box [lo, hi] (table frame, mm), the probe at mid-range:

    - sweeps at TABLE_STEPS table angles × TILTS_DEG up to MAX_SWEEP_TILT_DEG: straight down
      at the box's top (moving across the robot's reach), or tilted from either side of the
      part as the robot sees it (moving towards the robot, so the arm stays on its side),
      SPACING_MM apart;
    - table turns: the probe still at each tilt (and side), 75° among them (aimed low: the
      sides, and what hangs over them), the laser plane holding the table's axis, the table
      turning a full circle in steps of TURN_SPACING_MM at the box's rim (the planner lays them
      out again at the part's radius once it knows it: :func:`resampled_turn`)."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    centre = 0.5 * (lo + hi)
    half = 0.5 * float(np.linalg.norm((hi - lo)[:2])) + 5.0
    standoff = 0.5 * sum(probe.z_range_mm)
    up = np.array([0.0, 0.0, 1.0])
    frames = max(2, int(math.ceil(2 * half / SPACING_MM)))
    frames_per_turn = turn_frames(half)
    out = []
    for k in range(TABLE_STEPS):
        table_deg = 360.0 * k / TABLE_STEPS
        table_rad = math.radians(table_deg)
        s = robot_side(cell, table_deg)
        beside = np.cross(up, s)
        for tilt in TILTS_DEG:
            t = math.radians(tilt)
            for side in ([None] if tilt == 0.0 else [beside, -beside]):
                beam = -math.cos(t) * up - (0.0 if side is None else math.sin(t)) * (s if side is None else side)
                aim = centre.copy()
                low = 0.7 if tilt < 40 else 0.5 if tilt < 60 else 0.2  # the steeper, the lower the aim
                bottom = max(lo[2], 0.0)  # a box reaching under the table top: the part stands on it
                aim[2] = hi[2] if tilt == 0.0 else bottom + (hi[2] - bottom) * low
                motion = beside if side is None else s
                signed = tilt if side is None or side @ beside > 0 else -tilt
                middle = aim - standoff * beam
                if tilt <= MAX_SWEEP_TILT_DEG:
                    wp = scanpath.sweep(frames, middle - half * motion, middle + half * motion, beam,
                                        table_rad=table_rad)
                    out.append(Candidate("sweep", table_deg, signed, wp))
                if k == 0:  # a full turn looks the same from every start angle
                    # Aimed off the axis towards the probe's side (the near half of the part).
                    off = np.zeros(3) if side is None else 0.5 * half * side
                    at = aim + off + (0.2 * half * s if side is None else 0.0)
                    turn = scanpath.turntable(frames_per_turn, at - standoff * beam, beam, up if side is not None else None,
                                              start_rad=table_rad, table=cell.table)
                    out.append(Candidate("turn", table_deg, signed, turn))
    return out


def turn_frames(radius_mm: float, spacing_mm: float | None = None) -> int:
    """Profiles for a full table turn that lays them ``spacing_mm`` (default TURN_SPACING_MM)
    apart at ``radius_mm`` from the table's axis (at least 8, at most MAX_TURN_FRAMES)."""
    spacing_mm = TURN_SPACING_MM if spacing_mm is None else spacing_mm
    return max(8, min(MAX_TURN_FRAMES, int(math.ceil(2 * math.pi * radius_mm / spacing_mm))))


def resampled_turn(c: Candidate, frames: int, table) -> Candidate:
    """Table turn ``c`` with ``frames`` profiles over its full circle instead: the probe where
    it stands in the world, the first profile at the same table angle."""
    if c.kind != "turn":
        raise ValueError(f"only a table turn can be resampled, not a {c.kind}")
    wp = c.waypoints()
    probe2base = table.table2base(wp.table_rad[0]) @ wp.probe2table[0]
    angles = wp.table_rad[0] + 2 * np.pi * np.arange(frames) / frames
    return replace(c, wp=scanpath.Waypoints(table.base2table(angles) @ probe2base, angles,
                                            np.full(frames, wp.segment[0])))


def new_cells(space: KnownSpace, probe: Probe, poses: np.ndarray) -> np.ndarray:
    """Indices (k, 3) of the distinct unknown cells the laser fans of ``poses`` (table frame)
    first meet within the probe's range: what those profiles would newly see."""
    origins, dirs = fan_rays(probe, poses, SAMPLE_RAYS)
    z0, z1 = probe.z_range_mm
    dist, state = space.first_hits(origins, dirs, z1 / math.cos(probe.fan_rad / 2))
    depth = dist * np.repeat(np.cos(np.linspace(-probe.fan_rad / 2, probe.fan_rad / 2, SAMPLE_RAYS))[None],
                             len(poses), axis=0).ravel()
    new = (state == UNKNOWN) & (depth >= z0) & (depth <= z1)
    if not new.any():
        return np.zeros((0, 3), dtype=np.int64)
    cells, inside = space.cell_of(origins[new] + (dist[new] + 0.25 * space.voxel)[:, None] * dirs[new])
    return np.unique(cells[inside], axis=0)


def gain(space: KnownSpace, probe: Probe, poses: np.ndarray, skip: np.ndarray | None = None) -> int:
    """How many cells the laser fans of ``poses`` would newly see (:func:`new_cells`), not
    counting those marked in ``skip`` (a boolean grid of the model's shape: cells earlier views
    were expected to see and did not; see adaptive.NextBestView.missed)."""
    cells = new_cells(space, probe, poses)
    if skip is not None and len(cells):
        cells = cells[~skip[cells[:, 0], cells[:, 1], cells[:, 2]]]
    return int(len(cells))


def sample_poses(c: Candidate) -> np.ndarray:
    """The probe poses (table frame) of the SAMPLE_FRAMES frames of ``c`` whose fans are cast."""
    pick = np.linspace(0, c.frames - 1, min(SAMPLE_FRAMES, c.frames)).round().astype(int)
    return c.waypoints().probe2table[pick]


def rank(space: KnownSpace, probe: Probe, cands: list[Candidate], table_deg_now: float,
         probe_now: np.ndarray | None, skip: np.ndarray | None = None) -> list[Candidate]:
    """The candidates with their gain and cost, best gain per second first (no gain: left out).
    ``probe_now``: where the probe is (table frame, mm, (3,); None: nowhere yet, no travel
    counted). ``skip``: cells not to count as gain (see :func:`gain`)."""
    if probe_now is not None:
        probe_now = np.asarray(probe_now, dtype=np.float64)
        if probe_now.shape != (3,):
            raise InputError(f"rank: probe_now is the probe's position (x, y, z) in the table frame, mm, or None; "
                             f"got an array of shape {probe_now.shape} (a 4x4 pose's position is pose[:3, 3])")
        if not np.isfinite(probe_now).all():
            raise InputError(f"rank: probe_now must be finite, got {probe_now.tolist()}")
    out = []
    for c in cands:
        poses = sample_poses(c)
        g = gain(space, probe, poses, skip)
        if g == 0:
            continue
        # The frames between the cast ones see as much again. That holds where neighbouring
        # frames see different cells; a table turn's laser plane holds the axis, so near it
        # successive frames meet the same cells, and the fewer frames are cast, the more a
        # turn is overcounted. With 6 cast frames (60° apart) a turn from straight above,
        # after the overview, outranked the sweeps that then found more of the step block
        # (it added 0.1 %, they 1.6 and 1.8 %); with 24 it does not.
        g = int(round(g * c.frames / len(poses)))
        out.append(replace(c, gain=g, seconds=seconds(c, table_deg_now, probe_now)))
    return sorted(out, key=lambda c: -c.utility)


def seconds(c: Candidate, table_deg_now: float, probe_now: np.ndarray | None) -> float:
    """How long candidate ``c`` takes from where the table and the probe are now: its profiles,
    the table's turn to its start (and a full turn for a table turn) and the probe's travel."""
    turn = abs((c.table_deg - table_deg_now + 180.0) % 360.0 - 180.0)
    travel = 0.0 if probe_now is None else float(np.linalg.norm(c.start_mm - probe_now))
    out = c.frames * FRAME_S + turn / TABLE_DEG_PER_S + travel / PROBE_MM_PER_S
    return out + (360.0 / TABLE_DEG_PER_S if c.kind == "turn" else 0.0)
