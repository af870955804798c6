"""Sharded scans on a local Dask cluster: wall time with 1 and with 2 workers, side by side.

Each scenario runs three times: in one process (no Dask), on a local cluster of
one worker, and on one of two workers (cores / workers render threads each), from
an empty shard folder each time. The farm times are wall-clock from starting the
cluster to the last shard written (worker start-up and bpy import included);
speed-up = time with 1 worker / time with 2. The clouds are checked to be
identical to the single process's.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace

import numpy as np


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--frames", type=int, default=120, help="frames of the 160x160 scenario (default 120)")
    parser.add_argument("--hires-frames", type=int, default=24, help="frames of the 1280x1024 scenario (default 24)")
    parser.add_argument("--readme", action="store_true", help="also put the table into README.md")
    parser.set_defaults(run=run)


def scenarios(args):
    from addon.core.probe import load_probe
    from addon.core.scanconfig import load_scan_config

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

    if args.frames < 8 or args.hires_frames < 8:
        raise InputError("--frames and --hires-frames must be at least 8 (four shards per worker)")
    rows = []
    for name, cfg in scenarios(args):
        t = time.perf_counter()
        single = run_scan(cfg, None, write_outputs=False)
        t_single = time.perf_counter() - t
        walls = {}
        for workers in (1, 2):
            with tempfile.TemporaryDirectory() as out:
                res = run_farm(cfg, out, workers=workers, log=lambda m: None)
            walls[workers] = res.report["farm"]["wall_s"]
            if not np.array_equal(res.cloud.points, single.cloud.points):
                raise RuntimeError(f"{name}: the {workers}-worker cloud differs from the single process's")
        n = len(cfg.waypoints)
        rows.append((name, n, t_single, walls[1], walls[2]))
        print(f"  {name}: one process {t_single:.1f} s, 1 worker {walls[1]:.1f} s, 2 workers {walls[2]:.1f} s",
              flush=True)
    md = to_markdown(rows)
    print()
    print(md)
    if args.readme:
        from headless.bench import readme

        readme.update("farm", md)
    return 0


def to_markdown(rows) -> str:
    lines = ["Measured with `python -m headless bench farm` (local cluster on this 2-core machine, Cycles on the "
             "CPU; wall time from cluster start to the last shard, worker start-up included; clouds identical "
             "to the single process's):", "",
             "| scenario | frames | one process | 1 worker | 2 workers | speed-up 1 → 2 |",
             "|---|---|---|---|---|---|"]
    for name, n, single, one, two in rows:
        lines.append(f"| {name} | {n} | {single:.1f} s | {one:.1f} s | {two:.1f} s | ×{one / two:.2f} |")
    return "\n".join(lines) + "\n"
