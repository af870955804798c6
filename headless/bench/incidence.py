"""Where on a part the error sits by the laser's angle of incidence, beside the line-width floor.

A scan config is scanned as configured; the part's points are binned by the angle between
the surface's normal (at the nearest point of the part's mesh) and the direction to the
laser. Per band: the points' bias (mean signed error, negative inside the part) and RMS
against the part's exact shape, and the same for the floor (``line_floor.line_width_floor``:
where a perfect detector of this probe would put each point, from the beam's width cast on
the exact mesh, with no rendering), and how far the measured points lie from the floor's.
Where the two agree, what the band shows is the line's own width on the part, not the
pipeline.
"""

from __future__ import annotations

import argparse
import time

BAND_DEG = 10.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from addon.core.config.render import ENGINES

    parser.add_argument("--config", default="demo", help="scan config: a bundled name or a .toml file (default demo)")
    parser.add_argument("--engine", choices=ENGINES, default=None,
                        help="render engine (default: the config's)")
    parser.add_argument("--readme", action="store_true", help="write the table into README.md")
    parser.set_defaults(run=run)


def incidence_bands(config_name: str, engine: str | None = None) -> tuple[list[dict], dict]:
    """(one row per band of incidence, the scan's figures) for the scan ``config_name``."""
    import igl
    import numpy as np

    from addon import Scanner
    from addon.core.config.scan import load_scan_config
    from addon.core.geometry.line_floor import line_width_floor
    from addon.core.errors import InputError
    from addon.core.geometry.metrics import distances, has_inside
    from addon.core.scan.plan import cell_surfaces

    cfg = load_scan_config(config_name)
    if engine is not None:
        cfg = cfg.with_overrides(engine=engine)
    truth = cfg.workpiece.truth
    if not (hasattr(truth, "signed_distance") or has_inside(truth)):  # before the scan, not after it
        raise InputError(f"{cfg.workpiece.source} is not a closed mesh: a signed error (inside or outside the "
                         f"part) needs one")
    t = time.perf_counter()
    scanner = Scanner(config=cfg)
    scanner.run()
    result = scanner.result()
    wall = time.perf_counter() - t
    part = result.cloud.select(result.on_part)
    truth, mesh = cfg.workpiece.truth, cfg.workpiece.mesh
    q = np.concatenate([p[0] for p in scanner._poses])
    table_rad = np.concatenate([p[1] for p in scanner._poses])
    probe2table = cfg.cell.probe2table(q, table_rad)
    if not len(part):
        raise InputError(f"no point of {cfg.name!r} lies on its part, so there is no error to band by incidence: "
                         f"give a config whose path measures the part")
    _, signed = distances(part.points, truth)
    floor = line_width_floor(cfg.probe, probe2table, part.points, part.frame, part.camera, cell_surfaces(cfg))
    has_floor = np.isfinite(floor).all(axis=1)
    floor_signed = np.full(len(part), np.nan)
    if has_floor.any():
        floor_signed[has_floor] = distances(floor[has_floor], truth)[1]
    # The incidence: the normal of the mesh's face nearest each point against the way to the laser.
    V, F = np.ascontiguousarray(mesh.vertices, float), np.ascontiguousarray(mesh.faces, np.int64)
    _, face, _ = igl.point_mesh_squared_distance(np.ascontiguousarray(part.points, float), V, F)
    normal = mesh.face_normals[np.asarray(face, int)]
    to_laser = probe2table[part.frame.astype(int), :3, 3] - part.points
    to_laser /= np.linalg.norm(to_laser, axis=1, keepdims=True)
    incidence = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", normal, to_laser), -1.0, 1.0)))
    rows = []
    for lo in np.arange(0.0, 90.0, BAND_DEG):
        band = (incidence >= lo) & (incidence < lo + BAND_DEG)
        if not band.any():
            continue
        e = signed[band] * 1e3
        f = floor_signed[band] * 1e3
        ok = np.isfinite(f)
        rows.append(dict(lo=float(lo), hi=float(lo + BAND_DEG), points=int(band.sum()), fused=float(np.mean(
            part.camera[band] == 3)), bias=float(e.mean()), rms=float(np.sqrt(np.mean(e ** 2))),
            floor_bias=float(f[ok].mean()) if ok.any() else float("nan"),
            floor_rms=float(np.sqrt(np.mean(f[ok] ** 2))) if ok.any() else float("nan"),
            apart=float(np.sqrt(np.mean((e[ok] - f[ok]) ** 2))) if ok.any() else float("nan")))
    e = signed * 1e3
    return rows, dict(name=cfg.name, engine=cfg.render.engine, points=len(part), rms=float(np.sqrt(np.mean(e ** 2))),
                      steepest=float(incidence.max()) if len(part) else float("nan"), time=wall)


def table(rows: list[dict]) -> str:
    lines = ["| incidence | points | fused | bias µm | RMS µm | floor bias µm | floor RMS µm | measured − floor, RMS µm |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['lo']:.0f}–{r['hi']:.0f}° | {r['points']} | {r['fused'] * 100:.0f} % | {r['bias']:+.1f} | "
                     f"{r['rms']:.1f} | {r['floor_bias']:+.1f} | {r['floor_rms']:.1f} | {r['apart']:.1f} |")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    rows, scan = incidence_bands(args.config, args.engine)
    command = f"python -m headless bench incidence --config {args.config}" + (
        f" --engine {args.engine}" if args.engine else "")
    body = (f"The part's error by the laser's angle of incidence ({command}: {scan['name']}, {scan['engine']}, "
            f"{scan['points']} points on the part, RMS {scan['rms']:.1f} µm, in {scan['time']:.1f} s). Bias: the mean "
            f"signed error, negative inside the part; fused: points both cameras measured; floor: where a perfect "
            f"detector of this probe puts the same points, from the beam's width cast on the exact mesh "
            f"(addon/core/geometry/line_floor.py, no rendering).\n\n" + table(rows))
    print(body)
    if args.readme:
        from headless.bench import readme

        readme.update("incidence", body)
    return 0
