"""Sharded scans on a local Dask cluster: wall time with 1 and with 2 workers, side by side.

Each scenario runs four ways, from an empty shard folder each time, in rounds: in one process (no
Dask, Cycles on every core), and on local clusters of one worker with one render
thread, two workers with one render thread each, and one worker with as many
render threads as the machine has cores. The farm's scaling is the speed-up from
one worker to two at one thread each (what adding a node does); the last column
compares two single-threaded workers with one worker using both cores (processes
against threads on one machine). Farm times are wall-clock from starting the
cluster to the last shard written: worker start-up (spawning, importing bpy,
building the cell) included. Every cloud is checked to be identical to the
single process's.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from dataclasses import replace

import numpy as np
from headless.bench import whole
from addon.core.machine import usable_cpus


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--frames", type=whole(8, 180), default=120,
                        help="at least this many frames of the 160x160 scenario: every k-th of the demo's "
                             "path, k = its frames // FRAMES (default 120: all 180)")
    parser.add_argument("--hires-frames", type=whole(8, 180), default=60,
                        help="at least this many frames of the 1280x1024 scenario, taken likewise "
                             "(default 60: every third, 60)")
    parser.add_argument("--repeats", type=whole(), default=2,
                        help="runs of each layout, in rounds; the median counts (default 2)")
    parser.add_argument("--readme", action="store_true", help="also put the table into docs/farm.md")
    parser.set_defaults(run=run)


def scenarios(args):
    from addon.core.config.rigs import load_probe
    from addon.core.config.scan import load_scan_config

    demo = load_scan_config("demo")
    step = max(1, len(demo.waypoints) // args.frames)
    hires = replace(demo, probe=load_probe("hires"))
    hstep = max(1, len(demo.waypoints) // args.hires_frames)
    return [("demo, 160x160", demo.with_overrides(frames=slice(None, None, step))),
            ("demo, 1280x1024", hires.with_overrides(frames=slice(None, None, hstep)))]


def run(args: argparse.Namespace) -> int:
    from addon.core.errors import InputError
    from addon.pipeline import run_scan
    from headless.farm import run_farm

    if args.frames < 8 or args.hires_frames < 8 or args.repeats < 1:
        raise InputError("--frames and --hires-frames must be at least 8 (four shards per worker), --repeats at least 1")
    cores = usable_cpus()
    layouts = [None, (1, 1), (2, 1), (1, cores)]  # one process, then (workers, render threads each)
    rows = []
    for name, cfg in scenarios(args):
        # bpy imported and Cycles warmed up before the one-process run is timed (workers pay their own start-up)
        run_scan(cfg.with_overrides(frames=slice(0, 2)), None, write_outputs=False)
        walls = {layout: [] for layout in layouts}
        single = None
        for rnd in range(args.repeats):  # every layout once per round: a slow spell hits all alike
            for layout in layouts:
                if layout is None:
                    t = time.perf_counter()
                    single = run_scan(cfg, None, write_outputs=False)
                    walls[None].append(time.perf_counter() - t)
                    label = "one process"
                else:
                    workers, threads = layout
                    with tempfile.TemporaryDirectory() as out:
                        res = run_farm(cfg, out, workers=workers, render_threads=threads, log=lambda m: None)
                    walls[layout].append(res.report["farm"]["wall_s"])
                    if not np.array_equal(res.cloud.points, single.cloud.points):
                        raise RuntimeError(f"{name}: the {workers}-worker cloud differs from the single process's")
                    label = f"{workers} worker(s) x {threads} render thread(s)"
                print(f"  round {rnd + 1}/{args.repeats}  {name}: {label}: {walls[layout][-1]:.1f} s", flush=True)
        med = {layout: statistics.median(v) for layout, v in walls.items()}
        rows.append((name, len(cfg.waypoints), med[None], med[1, 1], med[2, 1], med[1, cores]))
    md = to_markdown(rows, cores, args.repeats)
    print()
    print(md)
    if args.readme:
        from headless.bench import readme

        readme.update("farm", md)
    return 0


def to_markdown(rows, cores: int, repeats: int) -> str:
    lines = [f"Measured with `python -m headless bench farm --repeats {repeats}` (local clusters on this {cores}-core "
             "machine, Cycles on the CPU; medians of the repeats; farm times are wall-clock from starting the "
             "cluster to the last shard, worker start-up included; every cloud identical to the single "
             "process's):", "",
             f"| scenario | frames | one process, {cores} threads | 1 worker × 1 thread | 2 workers × 1 thread "
             f"| speed-up 1 → 2 workers | 1 worker × {cores} threads | 2 workers against 1 worker × {cores} |",
             "|---|---|---|---|---|---|---|---|"]
    for name, n, single, one, two, one_all in rows:
        lines.append(f"| {name} | {n} | {single:.1f} s | {one:.1f} s | {two:.1f} s | ×{one / two:.2f} "
                     f"| {one_all:.1f} s | ×{one_all / two:.2f} |")
    return "\n".join(lines) + "\n"
