"""``python -m headless overview``: render the overview picture of the demo cell."""

from __future__ import annotations

import argparse
from pathlib import Path

from headless.bench import whole
from headless.preflight import frames_argument


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", default="out/cell_overview.png", help="PNG to write (default out/cell_overview.png)")
    parser.add_argument("--robot", default="adept_viper_s650", help="robot rig under rigs/robots/ (default adept_viper_s650)")
    parser.add_argument("--probe", default="default", help="probe rig under rigs/probes/ (default: default)")
    parser.add_argument("--workpiece", default="sphere", help="plane, sphere, cylinder or step_block")
    parser.add_argument("--width", type=whole(16, 8192), default=720,
                        help="width of the cell's view in pixels, 16 to 8192 (default 720); the probe's camera "
                             "images are added to its right")
    parser.add_argument("--height", type=whole(16, 8192), default=480, help="picture height in pixels, 16 to 8192 (default 480)")
    parser.add_argument("--samples", type=whole(1, 4096), default=24, help="Cycles samples per pixel, 1 to 4096 (default 24)")
    parser.add_argument("--scan", metavar="CONFIG",
                        help="first run this scan through the Scanner panel's operator and show the imported "
                             "cloud, framed on the table; the scan's files go beside the picture, in a folder "
                             "named after it with -scan (default out/cell_overview-scan/CONFIG NAME/)")
    parser.add_argument("--frames", type=frames_argument, help="with --scan: part of the path, as A:B (default all)")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from addon.core.errors import InputError
    from addon.core.files import check_output_file
    from addon.scene.overview import render_overview
    from addon.scene.session import new_scene
    from headless import demo_cell

    check_output_file(args.out, "--out")  # before the render, not after
    if args.frames and not args.scan:
        raise InputError("--frames picks part of --scan's path: give --scan CONFIG too, or leave --frames out")
    if args.scan:  # the scan's config sets its cell (they were ignored without a word)
        given = [f"--{name}" for name, default in (("robot", "adept_viper_s650"), ("probe", "default"),
                                                   ("workpiece", "sphere")) if getattr(args, name) != default]
        if given:
            raise InputError(f"{' and '.join(given)} {'sets' if len(given) == 1 else 'set'} the cell drawn without "
                             f"--scan; with --scan the scan config's cell is drawn: leave "
                             f"{'it' if len(given) == 1 else 'them'} out, or give a config with that cell")
        from addon.core.config.scan import load_scan_config, parse_frames

        # the config and --frames checked before Blender starts (the operator's error was a traceback)
        load_scan_config(args.scan).with_overrides(frames=parse_frames(args.frames, "--frames"))
        from addon.core.files import check_output_folder

        # (the operator checks the config's own folder inside it, also before it renders)
        check_output_folder(scan_folder(args.out), (), "--scan's files: folder")
    scene = new_scene()
    if args.scan:
        return _with_scan(args, scene, render_overview)
    sc = demo_cell.build(scene, args.robot, args.probe, args.workpiece)
    frames = demo_cell.sweep(sc, 3, table_angle_rad=0.5)
    path = render_overview(sc, Path(args.out), args.width, args.height, args.samples, frame=frames.start + 1,
                           before_write=_stop_check(args))
    print(f"wrote {path}")
    return 0


def _stop_check(args):
    """What render_overview calls between its renders and writing the picture: a Ctrl-C or
    SIGTERM during the render (one long Cycles call, which only records it) stops the command
    there, with nothing written (it wrote the picture and exited 0)."""
    stops = getattr(args, "stops", None)
    if stops is None:
        return None

    def check():
        stops.done, stops.total, stops.unit = 0, 0, "pictures"
        stops.check()

    return check


def scan_folder(out: str) -> Path:
    """Where ``overview --scan`` keeps the scan's files: beside the picture ``out``, named after it."""
    return Path(out).parent / f"{Path(out).stem}-scan"


def _with_scan(args, scene, render_overview) -> int:
    """The Scanner panel's result: scan with its operator, then picture the cloud on the table."""
    import bpy

    import addon.ui as ui
    from addon.core.config.scan import load_scan_config
    from addon.scene.cell import SceneCell
    from addon.scene.blender_log import blender_output_captured

    ui.register()
    try:
        s = scene.scanner
        s.scan_config = "FILE"
        s.scan_file = str(load_scan_config(args.scan).source)
        told: list = []
        try:
            # Blender's own log goes with the operator's report to stdout (Cycles' "CUEW
            # initialization failed" where no CUDA is installed): the report is passed on alone.
            try:
                with blender_output_captured(told):
                    bpy.ops.scanner.scan(frames=args.frames or "", output_dir=str(scan_folder(args.out)))  # "": all
            finally:
                reported = [ln for ln in "".join(told).splitlines() if ln.startswith(("Info:", "Warning:"))]
                if reported:
                    print("\n".join(reported), flush=True)
        except RuntimeError as exc:  # the operator's own report: its last line says what went wrong
            from addon.core.errors import ScannerError

            stops = getattr(args, "stops", None)
            if stops is not None and stops.signum is not None:  # stopped: the operator reported the stop
                raise stops.interrupted() from None
            raise ScannerError(f"the Scanner panel's scan: {str(exc).strip().splitlines()[-1]}") from None
        cfg = load_scan_config(args.scan)
        sc = SceneCell.attach(scene, cfg.cell, cfg.probe, cfg.workpiece)
        cloud = bpy.data.objects["Scan cloud"]
        cloud.modifiers["Points"].node_group.nodes["Mesh to Points"].inputs["Radius"].default_value = 0.0009
        focus = [o for o in sc.root.all_objects if o.name == "Turntable"]
        # The probe's panes show the scan's last frame. The panel put the robot back where it
        # stood before the scan, which a raycast scan never moved from: its panes were blank.
        from addon.core.config.scan import parse_frames
        from addon.core.kinematics.path import solve_path

        scanned = cfg.with_overrides(frames=parse_frames(args.frames, "--frames"))
        sc.pose(solve_path(scanned.cell, scanned.waypoints, scanned.q_start).q[-1],
                float(scanned.waypoints.table_rad[-1]))
        path = render_overview(sc, Path(args.out), args.width, args.height, args.samples, focus=focus,
                               before_write=_stop_check(args))
    finally:
        ui.unregister()
    print(f"wrote {path}")
    return 0
