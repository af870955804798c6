"""Whole scans: profiles per second end to end, the error at that setting, and what each
leave-out saves, measured as a ratio against the same scan with it switched off, side by side.

A profile is one frame: both probe cameras rendered (or the one that can see),
the line detected, triangulated, fused and moved into the table frame. Rate =
frames / (render + detect + triangulate time); planning, scene building and
writing files are reported by the scan itself but not counted here.

Scenarios: the demo (sphere; a table turn and a sweep), the step block (two
sweeps), a short sweep along the step block's riser where the riser hides the
line from one camera (so skipping a blind camera has something to skip), and the
demo on the high-resolution probe (1280 rows x 1024 columns).
"""

from __future__ import annotations

import argparse
import statistics
from dataclasses import replace

import numpy as np


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--repeats", type=int, default=2, help="runs of each variant; the median counts (default 2)")
    parser.add_argument("--hires-frames", type=int, default=24, help="frames of the 1280x1024 scenario (default 24)")
    parser.add_argument("--quick", action="store_true", help="fewer frames everywhere (for a smoke test)")
    parser.add_argument("--readme", action="store_true", help="also put the table into README.md")
    parser.set_defaults(run=run)


def scenarios(args):
    from addon.core.config.rigs import load_probe
    from addon.core.config.scan import load_scan_config
    from addon.core.kinematics.path import sweep
    from addon.core.geometry.workpiece import builtin_workpiece

    step = 4 if args.quick else 1
    demo = load_scan_config("demo").with_overrides(frames=slice(None, None, step))
    block = load_scan_config("step_block").with_overrides(frames=slice(None, None, step))
    # The riser between the middle and lowest steps is at x = 12.5 mm; a line 1–3 mm from it and
    # along it is hidden from the camera on the riser's side. The block is made 200 mm wide so
    # the whole line (about 90 mm long there) stays on the tread.
    riser = load_scan_config("step_block")
    riser = replace(riser, name="step block, along a riser", workpiece=builtin_workpiece("step_block", width_mm=200.0),
                    waypoints=sweep(24 // step, [13.5, 0.0, 200.0], [15.5, 0.0, 200.0]))
    hires = replace(load_scan_config("demo"), probe=load_probe("hires"))
    hires = hires.with_overrides(frames=slice(0, None, max(1, 180 // max(args.hires_frames // step, 1))))
    return [("demo (sphere)", demo), ("step block", block), ("riser (one camera blind)", riser),
            ("demo, 1280x1024 sensor", hires)]


def measure(cfg, repeats):
    from addon.pipeline import run_scan

    rates, report = [], None
    for _ in range(repeats):
        report = run_scan(cfg, None, write_outputs=False).report
        rates.append(report["profiles_per_s"])
    return statistics.median(rates), report


def run(args: argparse.Namespace) -> int:
    rows = []
    for name, cfg in scenarios(args):
        lo = cfg.leave_out
        base_rate, rep = measure(cfg, args.repeats)
        ratios = {}
        for label, off in (("band", replace(lo, render_band=False)), ("robot", replace(lo, hide_robot=False)),
                           ("cameras", replace(lo, skip_blind_cameras=False))):
            rate, _ = measure(replace(cfg, leave_out=off), args.repeats)
            ratios[label] = base_rate / rate
        e = rep["error_um"]
        rows.append((name, rep, base_rate, ratios, e))
        print(f"  {name}: {base_rate:.1f} profiles/s", flush=True)
    print()
    print("Scans end to end (render + detect + triangulate), medians; ratio = time with the leave-out switched "
          "off / time with it on")
    hdr = (f"{'scenario':<28}{'sensor':>10}{'frames':>7}{'profiles/s':>11}{'RMS um':>8}{'p95 um':>8}"
           f"{'rows':>6}{'cams':>5}{'band':>7}{'robot':>7}{'camera skip':>12}")
    print(hdr + "\n" + "-" * len(hdr))
    for name, rep, rate, ratios, e in rows:
        W, H = rep["config"]["sensor_px"]
        print(f"{name:<28}{f'{W}x{H}':>10}{rep['frames']:>7}{rate:>11.1f}{e['rms_um']:>8.1f}{e['p95_um']:>8.1f}"
              f"{rep['mean_rows_rendered']:>6.0f}{len(rep['cameras_rendered']):>5}"
              f"{ratios['band']:>6.2f}x{ratios['robot']:>6.2f}x{ratios['cameras']:>11.2f}x")
    print()
    print("Goal: >= 100 profiles/s at 160x160 on this 2-core machine. 'rows': mean sensor rows rendered per frame; "
          "'cams': cameras rendered.")
    if args.readme:
        from headless.bench import readme

        readme.update("scan", to_markdown(rows, args))
    return 0


def to_markdown(rows, args) -> str:
    lines = [f"Measured with `python -m headless bench scan --repeats {args.repeats}`"
             + (" --quick" if args.quick else "") + " (Cycles on the CPU of this 2-core machine; profiles per "
             "second = frames / (render + detect + triangulate); ratio = time with that leave-out switched off ÷ "
             "time with it on, side by side in one run):", "",
             "| scenario | sensor | frames | profiles/s | RMS µm | p95 µm | rows rendered | cameras | band | robot "
             "| camera skip |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, rep, rate, ratios, e in rows:
        W, H = rep["config"]["sensor_px"]
        lines.append(f"| {name} | {W}×{H} | {rep['frames']} | {rate:.1f} | {e['rms_um']:.1f} | {e['p95_um']:.1f} | "
                     f"{rep['mean_rows_rendered']:.0f} of {H} | {len(rep['cameras_rendered'])} | "
                     f"×{ratios['band']:.2f} | ×{ratios['robot']:.2f} | ×{ratios['cameras']:.2f} |")
    return "\n".join(lines) + "\n"
