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


def _parts():
    """{name: closed trimesh} in mm, standing on z = 0 around the table's axis."""
    import numpy as np
    import trimesh
    from trimesh.creation import box, cylinder

    def on_table(mesh):
        mesh.apply_translation([-mesh.bounds[:, 0].mean(), -mesh.bounds[:, 1].mean(), -mesh.bounds[0, 2]])
        return mesh

    def at(mesh, xyz):
        mesh.apply_translation(xyz)
        return mesh

    parts = {}
    # A block with a through hole and a rectangular pocket: sharp edges, a cavity.
    block = box(extents=[60.0, 40.0, 30.0])
    block = block.difference(cylinder(radius=7.0, height=50.0, sections=96))
    block = block.difference(at(box(extents=[16.0, 24.0, 14.0]), [-19.0, 0.0, 9.0]))
    parts["block with hole and pocket"] = on_table(block)
    # An L-bracket with a concave fillet in its inner corner.
    base = at(box(extents=[60.0, 40.0, 10.0]), [0.0, 0.0, 5.0])
    wall = at(box(extents=[10.0, 40.0, 50.0]), [-25.0, 0.0, 25.0])
    fillet_block = at(box(extents=[8.0, 40.0, 8.0]), [-16.0, 0.0, 14.0])
    fillet_cut = cylinder(radius=8.0, height=44.0, sections=96)
    fillet_cut.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    fillet_cut.apply_translation([-12.0, 0.0, 18.0])
    bracket = base.union(wall).union(fillet_block.difference(fillet_cut))
    parts["L-bracket with fillet"] = on_table(bracket)
    # A thin-walled tube: 1.5 mm walls, open both ends.
    tube = cylinder(radius=22.0, height=45.0, sections=128).difference(cylinder(radius=20.5, height=50.0,
                                                                                sections=128))
    parts["thin-walled tube"] = on_table(tube)
    # A stepped shaft with a groove, standing on its end.
    shaft = cylinder(radius=18.0, height=25.0, sections=128)
    shaft = shaft.union(at(cylinder(radius=11.0, height=30.0, sections=128), [0.0, 0.0, 25.0]))
    shaft = shaft.difference(at(cylinder(radius=25.0, height=4.0, sections=128).difference(
        cylinder(radius=15.0, height=6.0, sections=128)), [0.0, 0.0, 8.0]))
    parts["stepped shaft with groove"] = on_table(shaft)
    for name, mesh in parts.items():
        if not mesh.is_watertight:
            raise SystemExit(f"error: the part {name!r} did not come out closed")
    return parts


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--frames", default="::2", help="part of the demo path, as A:B:STEP (default ::2)")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from addon import Scanner
    from addon.core.config.scan import load_scan_config, parse_frames
    from addon.core.geometry.metrics import distances
    from addon.core.geometry.workpiece import Workpiece

    base = load_scan_config("demo").with_overrides(frames=parse_frames(args.frames, "--frames"))
    rows = []
    for name, mesh in _parts().items():
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
