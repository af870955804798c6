"""Point-to-mesh distances for the error metrics: libigl's AABB tree against trimesh's proximity.

A closed mesh of 81 920 faces (an ellipsoid, icosphere-based) and 25 000 points
scattered around its surface, as a scan of a real part gives; times are medians of
rounds, trimesh on a subset (it is far slower) and quoted per point as well.
"""

from __future__ import annotations

import argparse
import statistics
import time
from headless.bench import whole


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--points", type=whole(), default=25000, help="points (default 25000)")
    parser.add_argument("--rounds", type=whole(), default=3, help="rounds; medians count (default 3)")
    parser.add_argument("--trimesh-points", type=whole(), default=500, help="points given to trimesh (default 500)")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    import numpy as np
    import trimesh

    from addon.core.geometry.metrics import mesh_distances

    sphere = trimesh.creation.icosphere(subdivisions=6, radius=30.0)
    mesh = trimesh.Trimesh(sphere.vertices * [1.0, 1.3, 0.8], sphere.faces)  # closed, 81 920 faces
    rng = np.random.default_rng(0)
    surface, _ = trimesh.sample.sample_surface(mesh, args.points, seed=1)
    sets = {
        "near the surface (a scan of the part)": surface + rng.normal(scale=0.05, size=surface.shape),
        "5-50 mm away (table points, outliers)": surface * (1 + rng.uniform(0.15, 1.5, size=(len(surface), 1))),
    }
    print(f"Point-to-mesh distances, {args.points} points against {len(mesh.faces)} faces (closed), medians of "
          f"{args.rounds} rounds (python -m headless bench metrics)\n")
    print("| points | libigl AABB, signed (the metrics' method) | per point | trimesh proximity, unsigned "
          f"(first {args.trimesh_points} points) | per point | × libigl | largest difference |")
    print("|---|---|---|---|---|---|---|")
    for label, P in sets.items():
        igl_times, tri_times = [], []
        for _ in range(args.rounds):
            t = time.perf_counter()
            d, s = mesh_distances(P, mesh)
            igl_times.append(time.perf_counter() - t)
            sub = P[: args.trimesh_points]
            t = time.perf_counter()
            _, dt, _ = trimesh.proximity.closest_point(mesh, sub)
            tri_times.append(time.perf_counter() - t)
        ti, tt = statistics.median(igl_times), statistics.median(tri_times) / len(sub)
        agree = float(np.abs(d[: len(sub)] - dt).max())
        print(f"| {label} | {ti:.2f} s | {ti / len(P) * 1e6:.0f} µs | {tt * len(P):.1f} s (estimated) | "
              f"{tt * 1e6:.0f} µs | {tt * len(P) / ti:.0f} | {agree * 1e6:.3f} nm |")
    return 0
