"""Triangulation: the paper's Eq. 6 against the exact ray-plane intersection, speed, stability.

For every pixel of the sensor the two methods are compared on the same detected
position. Eq. 6's P_Z is exact, its P_Y is too long by √(1 + (p_y/f)²); the table
shows what that means in millimetres at the ends of the line, row by row.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from addon.core.optics.detect import LineDetection
from addon.core.optics.probe import Probe
from addon.core.config.rigs import load_probe
from addon.core.optics.triangulate import fuse_profiles, triangulate_profile
from headless.bench.timing import fmt_time, median_seconds


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--probes", nargs="+", default=["default", "hires"], metavar="PROBE",
                        help="bundled probe names or probe files (default: default hires)")
    parser.set_defaults(run=run)


def full_row(probe: Probe, v: float) -> LineDetection:
    W = probe.cols_px
    return LineDetection(np.arange(W), np.full(W, v), np.ones(W), np.ones(W), np.zeros(W, np.uint8), "grid",
                         (probe.rows_px, probe.cols_px))


def paper_vs_exact(probe: Probe) -> None:
    H = probe.rows_px
    rows = sorted({0.0, H * 0.1, H * 0.25, (H - 1) / 2, H * 0.75, H * 0.9, H - 1.0})
    print(f"{probe.name}: paper (Eq. 6) minus exact, camera 0, at the ends of the line")
    print(f"{'row v':>8}{'depth z (mm)':>14}{'line end |y| (mm)':>19}{'Δ|y| (mm)':>11}{'Δ|y|/|y|':>10}{'|Δz| (mm)':>11}")
    worst = (0.0, 0.0)
    for v in rows:
        line = full_row(probe, v)
        ex = triangulate_profile(probe, line, 0, "exact").points
        pa = triangulate_profile(probe, line, 0, "paper").points
        end = int(np.argmax(np.abs(ex[:, 1])))
        y = abs(ex[end, 1])
        dy = abs(pa[end, 1]) - y
        dz = float(np.max(np.abs(pa[:, 2] - ex[:, 2])))
        worst = max(worst, (dy, dy / y))
        print(f"{v:>8.1f}{ex[end, 2]:>14.2f}{y:>19.3f}{dy:>11.4f}{dy / y * 100:>9.3f}%{dz:>11.1e}")
    print(f"  largest Δ|y|: {worst[0]:.4f} mm ({worst[1] * 100:.2f} %); 1/cos γ − 1 = "
          f"{(1 / math.cos(probe.gamma_rad) - 1) * 100:.2f} %\n")


def round_trip(probe: Probe) -> float:
    y = np.linspace(-50, 50, 2000)
    P = np.column_stack([np.zeros_like(y), y, 150 + 0.25 * y])
    uv = probe.project(P, 0)
    ok = np.isfinite(uv).all(axis=1)
    line = LineDetection(uv[ok, 0], uv[ok, 1], np.ones(ok.sum()), np.ones(ok.sum()), np.zeros(ok.sum(), np.uint8),
                         "grid", (probe.rows_px, probe.cols_px))
    return float(np.abs(triangulate_profile(probe, line, 0).points - P[ok]).max())


def run(args: argparse.Namespace) -> int:
    probes = [load_probe(p) for p in args.probes]
    for probe in probes:
        paper_vs_exact(probe)
    print("Speed per profile (one camera, every column detected; fusion of both cameras)")
    print(f"{'probe':<48}{'columns':>8}{'exact':>11}{'paper':>11}{'fuse 2 cams':>13}{'round trip error':>18}")
    for probe in probes:
        line = full_row(probe, probe.rows_px / 2 + 3.3)
        t_exact = median_seconds(lambda: triangulate_profile(probe, line, 0, "exact"), 20)
        t_paper = median_seconds(lambda: triangulate_profile(probe, line, 0, "paper"), 20)
        p0 = triangulate_profile(probe, line, 0)
        p1 = triangulate_profile(probe, line, 1)
        t_fuse = median_seconds(lambda: fuse_profiles(p0, p1), 20)
        print(f"{probe.name:<48}{probe.cols_px:>8}{fmt_time(t_exact):>11}{fmt_time(t_paper):>11}"
              f"{fmt_time(t_fuse):>13}{round_trip(probe):>15.1e} mm")
    print()
    grazing = Probe("grazing test (φ − γ = 0.5°)", 60.0, 0.0, math.radians(10.5), math.radians(10.0), 200, 50)
    v = np.linspace(-0.5, 199.5, 2001)
    line = LineDetection(np.full(v.size, 24.5), v, np.ones(v.size), np.ones(v.size), np.zeros(v.size, np.uint8),
                         "grid", (200, 50))
    for method in ("exact", "paper"):
        prof = triangulate_profile(grazing, line, 0, method)
        print(f"Stability, {grazing.name}, {method}: {prof.masked['grazing']} of {v.size} rays masked as grazing "
              f"(< 2°), largest depth returned {prof.points[:, 2].max():.0f} mm, all finite: "
              f"{bool(np.isfinite(prof.points).all())}")
    return 0
