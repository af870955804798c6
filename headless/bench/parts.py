"""Parts that are not analytic shapes: CAD-like parts with sharp edges, holes, pockets and thin
walls, built with trimesh booleans (manifold3d), scanned with the demo's path (a table turn
and a sweep, default probe) and measured against their own meshes.

Per part: points on the part, RMS / p95 / max error, points farther than 0.2 mm from the
surface (outliers), coverage of the surface the path can measure and of the whole part,
and the scan's time. This is the real-parts issue's baseline; scanned (organic) meshes are
not in it yet.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

OUTLIER_MM = 0.2


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--frames", default="::2", help="part of the demo path, as A:B:STEP (default ::2)")
    parser.add_argument("--only", default="", help="scan only the parts whose name contains this text")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from addon import Scanner
    from addon.core.config.scan import load_scan_config, parse_frames
    from addon.core.geometry.metrics import distances
    from addon.core.geometry.workpiece import Workpiece

    base = load_scan_config("demo").with_overrides(frames=parse_frames(args.frames, "--frames"))
    rows = []
    from headless.parts import all_parts

    for name, mesh in all_parts().items():
        if args.only.lower() not in name.lower():
            continue
        wp = Workpiece(name, mesh, mesh, f"bench:{name}", np.eye(4))
        cfg = replace(base, name=name, workpiece=wp)
        t = time.perf_counter()
        scanner = Scanner(config=cfg)
        scanner.run()
        result = scanner.result()
        wall = time.perf_counter() - t
        r, cloud = result.report, result.cloud
        d, _ = distances(cloud.points[result.on_part], mesh)
        e = r["error_um"]
        rows.append((name, len(mesh.faces), r["points_on_part"], e["rms_um"], e["p95_um"], e["max_um"],
                     int(np.sum(d > OUTLIER_MM)), r["coverage_measurable"], r["coverage"], wall))
        print(f"{name}: {r['points_on_part']} points, RMS {e['rms_um']:.1f} um", flush=True)
    print(f"\nReal-parts baseline (python -m headless bench parts --frames {args.frames}; demo path, default probe, "
          "Cycles on the CPU)\n")
    print("| part | faces | points on it | RMS µm | p95 µm | max µm | > 0.2 mm | coverage, measurable | "
          "coverage, whole | time |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, faces, n, rms, p95, mx, out, cm, cw, wall in rows:
        print(f"| {name} | {faces} | {n} | {rms:.1f} | {p95:.1f} | {mx:.0f} | {out} | {cm * 100:.1f} % | "
              f"{cw * 100:.1f} % | {wall:.1f} s |")
    return 0
