"""Real parts (headless.parts: CAD-like boolean parts and real meshes, a scanned bunny among
them), each scanned with a path made for it from its bounding box and measured against its
own mesh.

Per part: points on the part, RMS / p95 / max error, points farther than 0.2 mm from the
surface (outliers), the floor the line's own width sets on that part (the RMS a perfect
detector of this probe would get on the same points: addon.core.geometry.line_floor), the
share of points within twice their stated σ, coverage of the surface the path can measure
(and its ceiling: what points within the σ limit of the part, by the floor, would cover)
and of the whole part, and the scan's time.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

# The path each part gets (a table turn from above, two at 45° from the side, a sweep) has one
# home, the core's, where the panel's "cell built here" scan takes it too.
from addon.core.kinematics.path import AROUND_PART_STANDOFF_MM as STANDOFF_MM
from addon.core.kinematics.path import around_part as part_path

from addon.core.geometry.metrics import OUTLIER_MM  # the real-parts goal: nothing farther from the part
from headless.bench import whole


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--frames", type=whole(2), default=60, help="frames per table turn (default 60; the sweep has half)")
    parser.add_argument("--only", default="", help="scan only the parts whose name contains this text (several: comma-separated)")
    parser.add_argument("--probe", default="default", help="probe rig (default: default; hires: the 1280-row probe)")
    parser.add_argument("--readme", action="store_true", help="put the table and the picture into the README (the default probe) or docs/accuracy.md (another)")
    parser.set_defaults(run=run)


def measure_part(name: str, mesh, frames: int = 60, probe: str = "default") -> dict:
    """Scan one part with its part path and measure it: the report's figures, the floor the
    line's width sets (see addon.core.geometry.line_floor), and how well each point's σ
    predicts its error."""
    import numpy as np

    from addon import Scanner
    from addon.core.config.scan import load_scan_config
    from addon.core.geometry.line_floor import coverage_ceiling, line_width_floor
    from addon.core.geometry.metrics import distances
    from addon.core.geometry.workpiece import Workpiece
    from addon.core.config.rigs import load_probe
    from addon.core.scan.plan import cell_surfaces

    base = load_scan_config("demo")
    wp = Workpiece(name, mesh, mesh, f"bench:{name}", np.eye(4))
    cfg = replace(base, name=name, workpiece=wp, probe=load_probe(probe), waypoints=part_path(mesh, base.table, frames))
    t = time.perf_counter()
    scanner = Scanner(config=cfg)
    scanner.run()
    result = scanner.result()
    wall = time.perf_counter() - t
    r = result.report
    part = result.cloud.select(result.on_part)
    d, _ = distances(part.points, mesh)
    probe2table = cfg.cell.probe2table(*_joints_and_table(scanner))
    surfaces = cell_surfaces(cfg)  # the part and the table, for the floor and the ceiling
    floor_pts = line_width_floor(cfg.probe, probe2table, part.points, part.frame, part.camera, surfaces)
    has_floor = np.isfinite(floor_pts).all(axis=1)
    floor = np.zeros(len(part))
    if has_floor.any():
        floor[has_floor] = distances(floor_pts[has_floor], mesh)[0]
    ceiling = coverage_ceiling(cfg.probe, probe2table, surfaces, mesh, cfg.profile_filter.max_incidence_deg,
                               cfg.profile_filter.max_sigma_mm, cfg.coverage_tolerance_mm)
    e = r["error_um"]
    return dict(name=name, faces=len(mesh.faces), points=len(part), rms=e["rms_um"], p95=e["p95_um"], max=e["max_um"],
                outliers=int(np.sum(d > OUTLIER_MM)),
                # Outliers the floor does not explain: a perfect detector's point lies on the part.
                unexplained=int(np.sum((d > OUTLIER_MM) & ~(floor > 0.5 * OUTLIER_MM))), floor=float(np.sqrt(np.mean(floor[has_floor] ** 2)) * 1e3)
                if has_floor.any() else float("nan"),
                within_2sigma=float(np.mean(d <= 2.0 * part.quality)) if len(part) else float("nan"),
                coverage_measurable=r["coverage_measurable"], coverage_ceiling=ceiling, coverage=r["coverage"], time=wall,
                dropped=r["points_dropped"], points_xyz=part.points, error_mm=d, floor_mm=floor,
                sigma_mm=part.quality.astype(float), camera=part.camera, frame=part.frame)


def _joints_and_table(scanner):
    import numpy as np

    q = np.concatenate([p[0] for p in scanner._poses])
    table = np.concatenate([p[1] for p in scanner._poses])
    return q, table


def goal_met(row: dict) -> bool:
    """The real-parts goals: nothing beyond 0.2 mm that the line's width does not put there too
    (the floor model's point for it lies more than 0.1 mm off the part), RMS ≤ 15 µm or within
    20 % of the floor, and 90 % of the measurable surface covered."""
    return (row["unexplained"] == 0 and (row["rms"] <= 15.0 or row["rms"] <= 1.2 * row["floor"])
            and row["coverage_measurable"] >= 0.9)


def table(rows: list[dict]) -> str:
    lines = ["| part | faces | points | RMS µm | floor µm | p95 µm | max µm | > 0.2 mm (floor not) | within 2σ | "
             "coverage, measurable | ceiling | coverage, whole | time | goals |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for w in rows:
        lines.append(f"| {w['name']} | {w['faces']} | {w['points']} | {w['rms']:.1f} | {w['floor']:.1f} | "
                     f"{w['p95']:.1f} | {w['max']:.0f} | {w['outliers']} ({w['unexplained']}) | "
                     f"{w['within_2sigma'] * 100:.0f} % | "
                     f"{w['coverage_measurable'] * 100:.1f} % | {w['coverage_ceiling'] * 100:.1f} % | "
                     f"{w['coverage'] * 100:.1f} % | {w['time']:.1f} s | "
                     f"{'met' if goal_met(w) else 'not met'} |")
    return "\n".join(lines)


def picture(rows: list[dict], path) -> None:
    """One panel per part: its points seen from above and the side, coloured by error."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig, axes = plt.subplots(2, len(rows), figsize=(2.6 * len(rows), 5.4), squeeze=False)
    for k, w in enumerate(rows):
        p, err = w["points_xyz"], w["error_mm"] * 1e3
        order = np.argsort(err)
        for j, (a, b, label) in enumerate(((0, 1, "top"), (0, 2, "side"))):
            ax = axes[j, k]
            sc = ax.scatter(p[order, a], p[order, b], c=err[order], s=1.0, cmap="viridis", vmin=0, vmax=50)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            if j == 0:
                ax.set_title(w["name"], fontsize=7)
            ax.set_ylabel(label, fontsize=7)
    fig.colorbar(sc, ax=axes.ravel().tolist(), shrink=0.7, label="distance to the part, µm")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(args: argparse.Namespace) -> int:
    from headless.parts import all_parts

    from addon.core.errors import InputError
    from headless.bench import check_readme_whole

    check_readme_whole(args, only="")
    section = "parts" if args.probe == "default" else f"parts-{args.probe}"
    if args.readme:  # the page before the scans (a probe given by its file has no section: refused at the end)
        from headless.bench import readme

        try:
            readme.page_with(section)
        except Exception as exc:
            raise InputError(f"--readme --probe {args.probe}: {exc} (the docs have one for the default and the hires "
                             f"probe, given by name)") from None
    catalogue = all_parts()
    wanted = [w.strip().lower() for w in args.only.split(",") if w.strip()]
    if args.only and not wanted:  # "," named none: not every part without a word
        raise InputError(f"--only {args.only!r} names no part; the parts: {', '.join(catalogue)}")
    picked = {n: m for n, m in catalogue.items() if not wanted or any(w in n.lower() for w in wanted)}
    if not picked:
        raise InputError(f"--only {args.only!r}: no part's name holds it; the parts: {', '.join(catalogue)}")
    rows = []
    stops = getattr(args, "stops", None)
    for name, mesh in picked.items():
        row = measure_part(name, mesh, args.frames, args.probe)
        if stops is not None:  # a stop during a part's floor and ceiling (no frames render there): none of the figures
            stops.check()
        rows.append(row)
        print(f"{name}: {row['points']} points, RMS {row['rms']:.1f} um (floor {row['floor']:.1f}), "
              f"{row['outliers']} beyond 0.2 mm, {row['coverage_measurable'] * 100:.1f} % of the measurable surface, "
              f"dropped {row['dropped']}", flush=True)
    command = f"python -m headless bench parts --frames {args.frames}" + (
        f" --probe {args.probe}" if args.probe != "default" else "")
    body = (f"Real parts ({command}; each part's own path: a table turn from above, two at 45° from the side, "
            f"a sweep; {args.probe} probe, Cycles on the CPU). Floor: the RMS a perfect detector of this "
            f"probe gets on the same points (the line's width alone); > 0.2 mm: points farther than that "
            f"from the part, in brackets those whose floor (a perfect detector's point) lies within 0.1 mm "
            f"of the part; within 2σ: points within twice their stated σ; ceiling: the coverage of the measurable surface by every point whose "
            f"floor lies within 50 µm (the σ limit) of the part, what the line's width leaves coverable "
            f"(addon.core.geometry.line_floor.coverage_ceiling).\n\n" + table(rows))
    print("\n" + body)
    if args.readme:
        from headless.bench import readme

        readme.update_with_picture(section, body, lambda png: picture(rows, png), "Where the error sits on each part")
    return 0
