"""Rendering N frames in one animation call against N separate render calls, side by side.

The demo cell (robot, probe, workpiece on the turntable) sweeps the probe across
the workpiece; both probe cameras render through multiview. Times are per frame,
medians of repeats, in one process.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

from headless.bench.timing import fmt_time
from headless.bench import whole


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--frames", type=whole(), default=24, help="frames in the path (default 24)")
    parser.add_argument("--probe", default="default", help="probe name or file (default: default)")
    parser.add_argument("--repeats", type=whole(), default=3, help="repeats of each way (default 3)")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    import statistics

    from addon.core.config.render import RenderOptions
    from addon.scene.session import new_scene
    from headless import demo_cell

    scene = new_scene()
    sc = demo_cell.build(scene, probe=args.probe)
    frames = demo_cell.sweep(sc, args.frames)
    first, last = frames.start, frames.stop - 1
    settings = RenderOptions()

    def one_call(cameras=(0, 1)):
        sc.render(first, last, settings, cameras)

    def separate(persistent=True):
        for f in frames:
            sc.render(f, f, replace(settings, persistent_data=persistent))

    ways = [("one animation call, both cameras", one_call), ("one call per frame, both cameras", separate),
            ("one call per frame, no persistent data", lambda: separate(False)),
            ("one animation call, camera 0 only", lambda: one_call((0,)))]
    one_call()  # warm-up: first render builds kernels and caches
    results = {}
    for label, fn in ways:
        times = []
        for _ in range(args.repeats):
            t = time.perf_counter()
            fn()
            times.append((time.perf_counter() - t) / len(frames))
        results[label] = statistics.median(times)
    W, H = sc.probe.cols_px, sc.probe.rows_px
    print(f"Render benchmark: {len(frames)} frames of a sweep over the workpiece, {W}x{H} px per camera, "
          f"Cycles {settings.device}, {settings.samples} sample(s), median of {args.repeats}\n")
    base = results[ways[0][0]]
    for label, _ in ways:
        t = results[label]
        print(f"  {label:<40}{fmt_time(t):>11} per frame   {1 / t:7.1f} frames/s   x{t / base:.2f}")
    return 0
