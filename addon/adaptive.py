"""Adaptive scanning: the reference next-best-view planner, driving a Scanner step by step.

It starts from what a real cell knows: the table, the robot, the probe and a bounding box of
the part (never the part's mesh; a config's [[path]] entries are ignored). It then repeats:
rank candidate sweeps by the new surface they would see per second of scanning, according
to what every laser ray so far has taught (core.scan.next_view over
core.geometry.known_space); ask the Scanner whether the robot can do the best one (solved
and collision-checked without moving: ``Scanner.plan_sweep``), else the next; scan it; add
its profiles to the model. It stops when no candidate promises ``min_gain`` new cells or
the profile budget is spent. The ground truth is used only afterwards, to score.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .core.errors import CollisionError, InputError, UnreachablePose
from .core.geometry.known_space import KnownSpace
from .core.scan import next_view

VOXEL_MM = 2.0
MARGIN_MM = 6.0   # the model's box around the part's
TRIES = 12        # candidates asked for reachability per decision, best first


@dataclass(frozen=True)
class AdaptiveStep:
    """One decision: the sweep chosen (its description), the profiles it took, the cells it
    taught the model, the planning time and the candidates refused as unreachable or colliding."""

    sweep: str
    table_deg: float
    tilt_deg: float
    profiles: int
    new_cells: int
    expected_cells: int
    planning_s: float
    refused: int

    def as_dict(self) -> dict:
        return dict(self.__dict__)


def part_box(config, grow: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """The bounding box the planner is told: the config's [adaptive] box, else the workpiece's
    box grown by ``grow`` of its size on each side (what a cell would roughly know)."""
    if config.adaptive.box is not None:
        return tuple(np.asarray(v, dtype=np.float64) for v in config.adaptive.box)
    lo, hi = (np.asarray(v, dtype=np.float64) for v in config.workpiece.mesh.bounds)
    pad = grow * (hi - lo)
    lo, hi = lo - pad, hi + pad
    lo[2] = max(lo[2], 0.0)  # the table top
    return lo, hi


def adaptive_scan(scanner, lo, hi, *, max_profiles: int = 600, min_gain: int = 30,
                  voxel_mm: float = VOXEL_MM, progress=None, log=None) -> list[AdaptiveStep]:
    """Scan the part inside the box [lo, hi] (table frame, mm) adaptively with ``scanner``;
    returns the decisions. ``progress(stage, done, total)`` after each sweep (profiles)."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    if lo.shape != (3,) or hi.shape != (3,) or not (np.isfinite(lo).all() and np.isfinite(hi).all() and (hi > lo).all()):
        raise InputError(f"the part's bounding box needs lo < hi, three finite numbers each, got {lo!r}, {hi!r}")
    if not (isinstance(max_profiles, int) and max_profiles > 0):
        raise InputError(f"max_profiles must be a positive whole number, got {max_profiles!r}")
    probe = scanner.config.probe
    space = KnownSpace(lo - MARGIN_MM, hi + MARGIN_MM, voxel_mm)
    pool = next_view.candidates(scanner.config.cell, probe, lo, hi)
    steps: list[AdaptiveStep] = []
    taken = 0
    impossible: set = set()  # candidates done, or that the robot cannot do (unreachable, colliding)
    while taken < max_profiles:
        t = time.perf_counter()
        probe_now = scanner.pose("table")[:3, 3]
        live = [c for c in pool if c.key not in impossible]
        ranked = [c for c in next_view.rank(space, probe, live, scanner.table_deg, probe_now) if c.gain >= min_gain]
        chosen, refused = None, 0
        for c in ranked[:TRIES]:
            if taken + c.frames > max_profiles:
                continue
            try:
                scanner.plan_sweep(c.from_mm, c.to_mm, c.frames, beam=c.beam, table_deg=c.table_deg)
            except (UnreachablePose, CollisionError) as exc:
                refused += 1
                impossible.add(c.key)
                if log:
                    log(f"  refused {c.describe()}: {str(exc)[:160]}")
                continue
            chosen = c
            break
        planning = time.perf_counter() - t
        if chosen is None:
            if log:
                log(f"adaptive: stopping after {len(steps)} sweeps: no reachable sweep promises {min_gain} new "
                    f"cells within the budget ({refused} refused)")
            break
        before = space.counts()["unknown"]
        profiles = scanner.sweep(chosen.from_mm, chosen.to_mm, chosen.frames, beam=chosen.beam,
                                 table_deg=chosen.table_deg)
        for p in profiles:
            if len(p.points):
                space.add_points(p.probe2table[:3, 3], p.points)
        impossible.add(chosen.key)  # the same sweep again would see the same (the scan is deterministic)
        taken += len(profiles)
        step = AdaptiveStep(chosen.describe(), chosen.table_deg, chosen.tilt_deg, len(profiles),
                            before - space.counts()["unknown"], chosen.gain, planning, refused)
        steps.append(step)
        if log:
            log(f"adaptive: sweep {len(steps)}: {step.sweep}; learnt {step.new_cells} cells "
                f"(planned in {planning:.2f} s, {refused} refused)")
        if len(steps) >= 2 and all(s.new_cells < min_gain for s in steps[-2:]):
            if log:
                log(f"adaptive: stopping after {len(steps)} sweeps: the last two taught fewer than {min_gain} cells")
            break
        if progress:
            progress("adaptive", taken, max_profiles)
    return steps
