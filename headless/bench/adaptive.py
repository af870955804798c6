"""The reference adaptive planner against fixed paths given the same profile budget, part by part:
coverage against profiles, sweeps, the probe's path length, planning time per decision, RMS.

Parts: the demo's sphere, the step block, and the real parts of ``bench parts`` (CAD-like
booleans and real meshes). Methods, each with ``--budget`` profiles:

- **planner**: addon.adaptive (told only the part's box grown by 10 %);
- **turns**: full table turns at three probe heights (from above, 45° down at mid-height,
  70° down low at the sides), a third of the budget each: what an engineer sets up blind;
- **raster**: parallel sweeps straight down across the box at two table angles 90° apart.

Coverage is of the whole part (the truth used only to score), after each sweep or pass.
"Reached with" is the share of the baseline's profiles the planner needed to reach the
baseline's final coverage (goal ≤ 60 %). Coverage of the measurable surface is the
report's, for the planner's own path.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from headless.bench import whole


GROWTH_PNG = Path(__file__).resolve().parents[1] / "gallery" / "adaptive_growth.png"
GROWTH_PANELS = 5   # at most; the views between are left out, the last one always in


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--budget", type=whole(), default=450, help="profiles per method and part (default 450)")
    parser.add_argument("--only", default="", help="only the parts whose name holds this text (comma-separated)")
    parser.add_argument("--readme", action="store_true", help="put the table and the plot into docs/adaptive.md")
    parser.add_argument("--growth", action="store_true",
                        help="draw the planner's scan of the first part growing, view by view, into "
                             "headless/gallery/adaptive_growth.png")
    parser.set_defaults(run=run)


def parts() -> dict:
    from addon.core.config.scan import load_scan_config
    from headless.parts import all_parts

    out = {"sphere (demo)": load_scan_config("demo").workpiece.mesh,
           "step block": load_scan_config("step_block").workpiece.mesh}
    out.update(all_parts())
    return out


def config_for(name: str, mesh):
    from addon.core.config.scan import load_scan_config
    from addon.core.geometry.workpiece import Workpiece

    base = load_scan_config("demo")
    return replace(base, name=name, workpiece=Workpiece(name, mesh, mesh, f"bench:{name}", np.eye(4)))


def _path_length(scanner) -> float:
    """The probe's path (mm, world frame) over every pose the scanner went through."""
    q = np.concatenate([p[0] for p in scanner._poses]) if scanner._poses else np.zeros((0, 6))
    if len(q) < 2:
        return 0.0
    P = scanner.config.cell.robot.fk(q)[:, :3, 3]
    return float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())


def run_planner(config, budget: int) -> dict:
    from addon import Scanner
    from addon.adaptive import NextBestView, part_box

    scanner = Scanner(config=config)
    lo, hi = part_box(config)
    t = time.perf_counter()
    planner = NextBestView(scanner, lo, hi)  # the one-off set-up (model, candidates, collision model)
    setup = time.perf_counter() - t
    curve, plan_s, taken, views = [], [], 0, []
    while taken < budget:
        t = time.perf_counter()
        c = planner.choose(scanner, budget - taken)
        plan_s.append(time.perf_counter() - t)
        if c is None:
            break
        profiles, _ = planner.scan(scanner, c)
        taken += len(profiles)
        curve.append((taken, scanner.result().report["coverage"]))
        views.append(f"{'turn' if c.kind == 'turn' else 'sweep'}, tilt {c.tilt_deg:.0f} deg")
    result = scanner.result()
    r = result.report
    part = result.cloud.select(result.on_part)
    return dict(curve=curve, sweeps=len(curve), profiles=taken, path_mm=_path_length(scanner), views=views,
                part_points=part.points, part_frames=part.frame,
                plan_max=max(plan_s) if plan_s else 0.0, plan_median=float(np.median(plan_s)) if plan_s else 0.0,
                setup=setup, rms=r["error_um"]["rms_um"], coverage=r["coverage"], measurable=r["coverage_measurable"],
                estimate=planner.coverage_estimate())


def run_fixed(config, passes) -> dict:
    """A fixed path given as passes [(waypoints, label)]; coverage after each."""
    from addon import Scanner
    from addon.core.kinematics.path import concatenate

    curve, done = [], []
    for wp in passes:
        done.append(wp)
        scanner = Scanner(config=replace(config, waypoints=concatenate(done)))
        scanner.run()
        curve.append((int(sum(len(w.table_rad) for w in done)), scanner.result().report["coverage"]))
    r = scanner.result().report
    return dict(curve=curve, sweeps=len(passes), profiles=curve[-1][0], path_mm=_path_length(scanner),
                plan_max=0.0, plan_median=0.0, rms=r["error_um"]["rms_um"], coverage=r["coverage"],
                measurable=r["coverage_measurable"])


TURN_HEIGHTS = ((45.0, 0.5), (70.0, 0.3))  # (tilt from vertical, aim's share of the part's height)


def turns(config, budget: int):
    from addon.core.kinematics import path as scanpath

    from headless.bench.parts import STANDOFF_MM

    lo, hi = config.workpiece.mesh.bounds
    radius = float(np.linalg.norm(np.maximum(np.abs(lo[:2]), np.abs(hi[:2]))))
    top = float(hi[2])
    n = max(1, budget // 3)
    out = [scanpath.turntable(n, [12.0, 0.0, top + STANDOFF_MM], table=config.table, segment=0)]
    # Two more heights, not the mirror of one: a turn 45° from one side sees, over its full
    # circle, what the same turn from the other side sees (a first version spent its third
    # pass so and added nothing).
    for k, (tilt_deg, height) in enumerate(TURN_HEIGHTS):
        a = math.radians(tilt_deg)
        beam = np.array([0.0, -math.sin(a), -math.cos(a)])
        aim = np.array([0.0, 0.5 * radius, height * top])
        out.append(scanpath.turntable(n, aim - STANDOFF_MM * beam, beam, (0.0, 0.0, 1.0), table=config.table,
                                      segment=k + 1))
    return out


def raster(config, budget: int):
    from addon.core.kinematics import path as scanpath

    from headless.bench.parts import STANDOFF_MM

    lo, hi = config.workpiece.mesh.bounds
    half = 0.5 * float(np.linalg.norm((hi - lo)[:2])) + 5.0
    z = float(hi[2]) + STANDOFF_MM
    lines = 4
    n = max(2, budget // (2 * lines))
    out = []
    for k, table_deg in enumerate((0.0, 90.0)):
        for j, y in enumerate(np.linspace(-0.5 * half, 0.5 * half, lines)):
            out.append(scanpath.sweep(n, [-half, y, z], [half, y, z], table_rad=math.radians(table_deg),
                                      segment=k * lines + j))
    return out


def reached_with(planner_curve, target: float) -> float | None:
    """Profiles the planner needed to reach ``target`` coverage (None: never)."""
    for profiles, cov in planner_curve:
        if cov >= target - 1e-9:
            return profiles
    return None


def table(rows: list[dict]) -> str:
    lines = ["| part | method | profiles | sweeps / passes | coverage, whole | coverage, measurable | "
             "planner's own estimate | probe path | planning per decision (max / median; the set-up before the "
             "first) | RMS µm | planner reaches this with |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        reach = r.get("reach")
        reach = "" if reach is None else (f"{reach[0]} profiles ({reach[1] * 100:.0f} %)" if reach[0] else "never")
        plan = (f"{r['plan_max']:.2f} / {r['plan_median']:.2f} s (set-up {r['setup']:.2f} s)"
                if r["method"] == "planner" else "")
        estimate = f"{r['estimate'] * 100:.1f} %" if "estimate" in r else ""
        lines.append(f"| {r['part']} | {r['method']} | {r['profiles']} | {r['sweeps']} | {r['coverage'] * 100:.1f} % | "
                     f"{r['measurable'] * 100:.1f} % | {estimate} | {r['path_mm'] / 1000:.2f} m | {plan} | "
                     f"{r['rms']:.1f} | {reach} |")
    return "\n".join(lines)


def growth_picture(mesh, planner: dict, path) -> None:
    """The planner's cloud of one part growing, a panel per view (at most GROWTH_PANELS)."""
    import cv2

    from addon.core.scan.preview import growth_strip

    ends = np.array([p for p, _ in planner["curve"]])
    view = np.searchsorted(ends, planner["part_frames"], side="right")  # frame -> the view that took it
    shown = sorted(set(np.linspace(0, len(ends) - 1, min(GROWTH_PANELS, len(ends))).round().astype(int)))
    # Views left out of the strip join the next panel shown.
    panel_of_view = np.searchsorted(shown, np.arange(len(ends)))
    titles = [f"{ends[k]} profiles: {planner['views'][k]}, {planner['curve'][k][1] * 100:.0f} % of the part"
              for k in shown]
    picture = growth_strip(mesh, planner["part_points"], panel_of_view[view], titles)
    cv2.imwrite(str(path), picture)


def plot(results: dict, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(results)
    fig, axes = plt.subplots(1, n, figsize=(2.8 * n, 2.8), squeeze=False, sharey=True)
    for ax, (part, methods) in zip(axes[0], results.items()):
        for method, r in methods.items():
            xs, ys = zip(*([(0, 0.0)] + r["curve"]))
            ax.plot(xs, np.array(ys) * 100, marker="o", ms=3, label=method)
        ax.set_title(part, fontsize=7)
        ax.set_xlabel("profiles", fontsize=7)
        ax.tick_params(labelsize=6)
    axes[0][0].set_ylabel("coverage of the part, %", fontsize=7)
    axes[0][0].legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(args: argparse.Namespace) -> int:
    rows, results = [], {}
    for name, mesh in parts().items():
        if args.only and not any(w.strip().lower() in name.lower() for w in args.only.split(",")):
            continue
        config = config_for(name, mesh)
        methods = {"planner": run_planner(config, args.budget),
                   "turns": run_fixed(config, turns(config, args.budget)),
                   "raster": run_fixed(config, raster(config, args.budget))}
        results[name] = methods
        if args.growth and len(results) == 1 and methods["planner"]["curve"]:
            growth_picture(mesh, methods["planner"], GROWTH_PNG)
            print(f"{name}: the planner's scan growing, view by view: {GROWTH_PNG}", flush=True)
        for method, r in methods.items():
            row = dict(part=name, method=method, **{k: v for k, v in r.items() if k != "curve"})
            if method != "planner":
                got = reached_with(methods["planner"]["curve"], r["coverage"])
                row["reach"] = (got, got / r["profiles"] if got else None)
            rows.append(row)
        print(f"{name}: " + "; ".join(f"{m} {r['coverage'] * 100:.1f} % in {r['profiles']} profiles"
                                      for m, r in methods.items()), flush=True)
    if not rows:
        raise SystemExit(f"error: no part's name holds {args.only!r}")
    body = (f"Adaptive scanning against fixed paths (`python -m headless bench adaptive --budget {args.budget}`, "
            f"2-core CPU, Cycles): coverage of the whole part (against its mesh, after the scan), of the "
            f"surface the method's own path can measure, the planner's own coverage estimate from its model "
            f"(what `--target-coverage` stops at), the probe's path length and the planner's time per "
            f"decision; the last column: the profiles the planner needed to reach that baseline's final "
            f"coverage, and their share of the baseline's.\n\n" + table(rows))
    print("\n" + body)
    if args.readme:
        from headless.bench import readme

        readme.update_with_picture("adaptive", body, lambda png: plot(results, png),
                                   "Coverage against profiles, per part and method")
    return 0
