"""Collision checks along long paths: how fast the cell's path check runs, and what it saves.

A 10 000-frame path on the demo cell (a table turn and a sweep over the 82 k-face sphere,
5 000 frames each) is checked as a scan's plan checks it: every waypoint and the motion
between them, sampled so that nothing moves more than 1 mm. Printed: frames per second,
samples, the body pairs decided per second, and how many exact (FCL) distances it took;
beside it, on the first 100 frames, the same check with an exact distance for every
pair and sample, for the ratio the bounds buy.
"""

from __future__ import annotations

import argparse
import statistics
import time
from headless.bench import whole


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--frames", type=whole(2), default=10_000, help="frames in the path (default 10000: half a "
                                                                          "table turn, half a sweep)")
    parser.add_argument("--repeats", type=whole(), default=3, help="timed repeats; the median is printed")
    parser.add_argument("--readme", action="store_true", help="put the figures into docs/safety.md")
    parser.set_defaults(run=run)


def _path(cfg, frames: int):
    from addon.core.kinematics import path as scanpath

    half = frames // 2
    return scanpath.concatenate([
        scanpath.turntable(half, [12.0, 0.0, 210.0], table=cfg.table, segment=0),
        scanpath.sweep(frames - half, [-40.0, 0.0, 210.0], [40.0, 0.0, 210.0], segment=1),
    ])


def _brute(model, q, table_rad) -> tuple[float, int]:
    """Seconds for an exact distance of every pair at every sample, and the pairs done."""
    qs, ts, _ = model.samples(q, table_rad)
    from addon.core.safety.bodies import carrier_poses

    carriers = carrier_poses(model.robot, model.table, qs, ts)
    t = time.perf_counter()
    for s in range(len(qs)):
        for i, j, _ in model.pairs:
            model._exact(i, j, carriers, s, False)
    return time.perf_counter() - t, len(qs) * len(model.pairs)


def run(args: argparse.Namespace) -> int:
    from addon.core.config.scan import load_scan_config
    from addon.core.kinematics.path import solve_path
    from addon.core.safety import CollisionModel

    cfg = load_scan_config("demo")
    wp = _path(cfg, args.frames)
    sol = solve_path(cfg.cell, wp, cfg.q_start)
    if not sol.ok.all():
        raise SystemExit("error: the benchmark path is not reachable")
    t = time.perf_counter()
    model = CollisionModel(cfg.cell.robot, cfg.probe, cfg.table, cfg.workpiece.mesh)
    build = time.perf_counter() - t
    times = []
    for _ in range(max(1, args.repeats)):
        t = time.perf_counter()
        found = model.check(sol.q, wp.table_rad, wp.segment)
        times.append(time.perf_counter() - t)
    wall = statistics.median(times)
    pairs = found.samples * len(model.pairs)
    n_brute = min(100, args.frames)
    brute_s, brute_pairs = _brute(model, sol.q[:n_brute], wp.table_rad[:n_brute])
    near = found.report()["nearest"]
    lines = [
        f"Collision check of a {args.frames}-frame path (python -m headless bench collision; demo cell, "
        f"the 82 k-face sphere; median of {len(times)}):",
        "",
        "| what | figure |",
        "|---|---|",
        f"| model built (BVH of the part, hulls, pairs) | {build:.2f} s |",
        f"| path checked | {wall:.2f} s: {args.frames / wall:,.0f} frames/s |",
        f"| poses checked (waypoints and motion, ≤ 1 mm apart) | {found.samples:,} |",
        f"| body pairs decided | {pairs:,}: {pairs / wall:,.0f} pairs/s ({len(model.pairs)} pairs per pose) |",
        f"| convex-hull distances / exact distances | {found.bound_queries:,} / {found.exact_queries:,} |",
        f"| smallest clearance | {near['clearance_mm']:.1f} mm, {near['bodies'][0]} to {near['bodies'][1]} |",
        f"| every pair exactly, first {n_brute} frames | {brute_s:.2f} s for {brute_pairs:,} pairs: "
        f"{brute_pairs / brute_s:,.0f} pairs/s; the bounds are "
        f"{(brute_s / brute_pairs) / (wall / pairs):,.0f} × faster per pair |",
    ]
    body = "\n".join(lines)
    print(body)
    if args.readme:
        from headless.bench import readme

        readme.update("collision", body)
    return 0
