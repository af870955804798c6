"""One ``Scanner.measure()`` against one frame of a batch scan, side by side in one process.

The batch frame is the demo scan's time per profile (render + detect + triangulate,
as in the scan summary) on the same cell; the step-by-step figure is the wall time of
``measure()`` at poses of the same table turn, the pose's IK done before. Medians of
rounds; the ratio is what the issue's goal (at most twice a batch frame) is judged by.
"""

from __future__ import annotations

import argparse
import statistics
import time
from headless.bench import whole


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config", default="demo", help="scan config (default demo)")
    parser.add_argument("--engine", choices=("cycles", "raycast"), default="cycles",
                        help="render engine (default cycles; raycast: Embree, without Blender)")
    parser.add_argument("--measures", type=whole(), default=30, help="measure() calls per round (default 30)")
    parser.add_argument("--rounds", type=whole(), default=3, help="rounds; medians count (default 3)")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from addon import Scanner

    batch, single = [], []
    for _ in range(args.rounds):
        s = Scanner.from_config(args.config, engine=args.engine)
        report = s.run()
        t = report.time_s
        batch.append((t["render"] + t["detect"] + t["triangulate"]) / report.frames)
        s.measure()  # the first call after a path renders a new frame range: not timed
        times = []
        for _k in range(args.measures):
            s.turn_table(360.0 / args.measures)
            t0 = time.perf_counter()
            s.measure()
            times.append(time.perf_counter() - t0)
        single.append(statistics.median(times))
    b, m = statistics.median(batch), statistics.median(single)
    print(f"Scanner.measure() against a batch frame ({args.config}, {args.engine}, medians of {args.rounds} rounds; "
          "python -m headless bench measure)\n")
    print("| what | ms | × batch frame |")
    print("|---|---|---|")
    print(f"| one frame inside a batch scan (render + detect + triangulate) | {b * 1e3:.1f} | 1.00 |")
    print(f"| one Scanner.measure() (wall time, everything) | {m * 1e3:.1f} | {m / b:.2f} |")
    return 0
