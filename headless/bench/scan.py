"""Whole scans: profiles per second end to end, the error at that setting, and what each
leave-out saves, measured as a ratio against the same scan with it switched off, side by side.

A profile is one frame: both probe cameras rendered (or the one that can see),
the line detected, triangulated, fused and moved into the table frame. Rate =
frames / (render + detect + triangulate time); planning, scene building and
writing files are reported by the scan itself but not counted here.

Each scenario is scanned by Cycles and by the raycast engine (Cycles' image under the
paper's ideal conditions, by Embree ray casting: ``addon/core/optics/raycast.py``), and the
two clouds are compared; one ``Scanner.measure()`` is timed with each.

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
from headless.bench import whole


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--repeats", type=whole(), default=2, help="runs of each variant; the median counts (default 2)")
    parser.add_argument("--hires-frames", type=whole(1, 180), default=24, help="frames of the 1280x1024 scenario: every (180 // N)-th of the demo's 180 (default 24: "
                             "every 7th, 26 frames)")
    parser.add_argument("--quick", action="store_true", help="fewer frames everywhere (for a smoke test)")
    parser.add_argument("--readme", action="store_true", help="also put the table into docs/scans.md")
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
    """Median profiles/s of ``repeats`` runs of the scan, and the last run's result."""
    from addon.pipeline import run_scan

    rates, result = [], None
    for _ in range(repeats):
        result = run_scan(cfg, None, write_outputs=False)
        rates.append(result.report["profiles_per_s"])
    return statistics.median(rates), result


def cloud_difference_um(a, b) -> float:
    """RMS distance (µm) from each point of cloud ``b`` to the nearest of cloud ``a``, both ways."""
    from scipy.spatial import cKDTree

    if not len(a.points) or not len(b.points):
        return float("nan")
    d1, _ = cKDTree(a.points).query(b.points)
    d2, _ = cKDTree(b.points).query(a.points)
    return 1e3 * float(np.sqrt(np.mean(np.concatenate([d1, d2]) ** 2)))


ENGINES = ("cycles", "raycast")
LEAVE_OUTS = {"band": "render_band", "robot": "hide_robot", "cameras": "skip_blind_cameras"}


def run(args: argparse.Namespace) -> int:
    rows = []
    for name, cfg in scenarios(args):
        reference = None
        for engine in ENGINES:
            c = cfg.with_overrides(engine=engine)
            base_rate, result = measure(c, args.repeats)
            ratios = {}
            for label, field in LEAVE_OUTS.items():
                if engine == "raycast" and field == "hide_robot":
                    continue  # the raycast engine never draws the robot: nothing to compare
                rate, _ = measure(replace(c, leave_out=replace(c.leave_out, **{field: False})), args.repeats)
                ratios[label] = base_rate / rate
            if reference is None:
                reference = (base_rate, result)
            speedup = base_rate / reference[0]
            delta = cloud_difference_um(reference[1].cloud, result.cloud)
            rows.append((name, engine, result.report, base_rate, ratios, speedup, delta))
            print(f"  {name}, {engine}: {base_rate:.1f} profiles/s", flush=True)
    measures = measure_calls(args)
    print()
    print("Scans end to end (render + detect + triangulate), medians; leave-out ratio = time with it switched "
          "off / time with it on; 'x Cycles' = profiles/s / Cycles' on the same scan; 'cloud diff' = RMS "
          "distance between the cloud and Cycles' (um)")
    hdr = (f"{'scenario':<28}{'engine':>9}{'sensor':>10}{'frames':>7}{'profiles/s':>11}{'x Cycles':>9}{'RMS um':>8}"
           f"{'p95 um':>8}{'cloud diff':>11}{'rows':>6}{'cams':>5}{'band':>7}{'robot':>7}{'camera skip':>12}")
    print(hdr + "\n" + "-" * len(hdr))
    for name, engine, rep, rate, ratios, speedup, delta in rows:
        W, H = rep["config"]["sensor_px"]
        e = rep["error_um"]
        print(f"{name:<28}{engine:>9}{f'{W}x{H}':>10}{rep['frames']:>7}{rate:>11.1f}{speedup:>8.2f}x{e['rms_um']:>8.1f}"
              f"{e['p95_um']:>8.1f}{delta:>11.3f}{rep['mean_rows_rendered']:>6.0f}{len(rep['cameras_rendered']):>5}"
              f"{_ratio(ratios, 'band'):>7}{_ratio(ratios, 'robot'):>7}{_ratio(ratios, 'cameras'):>12}")
    print()
    for engine, ms in measures.items():
        print(f"Scanner.measure() with {engine}: {ms:.1f} ms (median of {MEASURE_POSES} poses of the demo's path)")
    print(f"Goals: >= {GOAL_160} profiles/s at 160x160 on the demo and the step block, >= {GOAL_HIRES} at 1280x1024, "
          f"one measure() in <= {GOAL_MEASURE_MS} ms; the clouds within 1 um RMS of Cycles'.")
    for line in goals(rows, measures):
        print("  " + line)
    if args.readme:
        from headless.bench import readme

        readme.update("scan", to_markdown(rows, measures, args))
    return 0


GOAL_160, GOAL_HIRES, GOAL_MEASURE_MS = 150, 10, 15
MEASURE_POSES = 30


def _ratio(ratios: dict, key: str) -> str:
    return f"{ratios[key]:.2f}x" if key in ratios else "-"


def measure_calls(args) -> dict[str, float]:
    """Median time (ms) of one ``Scanner.measure()`` per engine, at poses along the demo's path
    (each after the scanner has measured once: its cell or ray-cast scene is built)."""
    import math
    import time

    from addon import Scanner
    from addon.core.scan.plan import plan_scan

    out = {}
    for engine in ENGINES:
        scanner = Scanner.from_config("demo", engine=engine)
        plan = plan_scan(scanner.config)
        picks = np.linspace(20, len(plan.q) - 20, MEASURE_POSES).astype(int)
        scanner.move_joints(plan.q[picks[0]])
        scanner.measure()
        times = []
        for k in picks:
            scanner.move_joints(plan.q[k])
            scanner.turn_table_to(math.degrees(plan.table_rad[k]))
            t = time.perf_counter()
            scanner.measure()
            times.append(time.perf_counter() - t)
        out[engine] = 1e3 * statistics.median(times)
    return out


def goals(rows, measures) -> list[str]:
    """One line per goal: met or not, with the figure."""
    out = []
    for name, engine, rep, rate, _, _, delta in rows:
        if engine != "raycast":
            continue
        W, H = rep["config"]["sensor_px"]
        goal = GOAL_HIRES if H >= 1024 else GOAL_160 if name in ("demo (sphere)", "step block") else None
        if goal is not None:
            out.append(f"{'met' if rate >= goal else 'MISSED'}: {name} {rate:.1f} profiles/s (goal {goal})")
        out.append(f"{'met' if delta <= 1.0 else 'MISSED'}: {name} cloud {delta:.3f} um RMS from Cycles' (goal 1)")
    ms = measures.get("raycast")
    if ms is not None:
        out.append(f"{'met' if ms <= GOAL_MEASURE_MS else 'MISSED'}: measure() {ms:.1f} ms (goal {GOAL_MEASURE_MS})")
    return out


def to_markdown(rows, measures, args) -> str:
    lines = [f"Measured with `python -m headless bench scan --repeats {args.repeats}`"
             + (" --quick" if args.quick else "") + " (the CPU of this 2-core machine; profiles per second = frames "
             "/ (render + detect + triangulate); × Cycles = profiles per second ÷ Cycles' on the same scan; cloud Δ = "
             "RMS distance between the cloud and Cycles' cloud; leave-out ratio = time with it switched off ÷ time "
             "with it on, side by side in one run; the raycast engine never draws the robot, so it has no robot "
             "ratio):", "",
             "| scenario | engine | sensor | frames | profiles/s | × Cycles | RMS µm | p95 µm | cloud Δ µm | rows rendered "
             "| cameras | band | robot | camera skip |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, engine, rep, rate, ratios, speedup, delta in rows:
        W, H = rep["config"]["sensor_px"]
        e = rep["error_um"]
        md = {k: f"×{v:.2f}" for k, v in ratios.items()}
        lines.append(f"| {name} | {engine} | {W}×{H} | {rep['frames']} | {rate:.1f} | ×{speedup:.2f} | {e['rms_um']:.1f} | "
                     f"{e['p95_um']:.1f} | {delta:.3f} | {rep['mean_rows_rendered']:.0f} of {H} | "
                     f"{len(rep['cameras_rendered'])} | {md.get('band', '—')} | {md.get('robot', '—')} | "
                     f"{md.get('cameras', '—')} |")
    lines.append("")
    lines.append("One `Scanner.measure()` (median of %d poses along the demo's path): %s." % (
        MEASURE_POSES, ", ".join(f"{engine} {ms:.1f} ms" for engine, ms in measures.items())))
    lines.append("")
    lines.append("Goals (issue 19): " + "; ".join(goals(rows, measures)) + ".")
    return "\n".join(lines) + "\n"
