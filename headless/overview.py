"""``python -m headless overview``: render the overview picture of the demo cell."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", default="out/cell_overview.png", help="PNG to write (default out/cell_overview.png)")
    parser.add_argument("--robot", default="adept_viper_s650")
    parser.add_argument("--probe", default="default")
    parser.add_argument("--workpiece", default="sphere", help="plane, sphere, cylinder or step_block")
    parser.add_argument("--width", type=int, default=720)
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--samples", type=int, default=24)
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from addon.scene.overview import render_overview
    from addon.scene.session import new_scene
    from headless import demo_cell

    scene = new_scene()
    sc = demo_cell.build(scene, args.robot, args.probe, args.workpiece)
    frames = demo_cell.sweep(sc, 3, table_angle_rad=0.5)
    path = render_overview(sc, Path(args.out), args.width, args.height, args.samples, frame=frames.start + 1)
    print(f"wrote {path}")
    return 0
