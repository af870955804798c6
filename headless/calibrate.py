"""``python -m headless calibrate CONFIG``: calibrate the config's probe as a lab calibrates a real
one, and write the calibrated probe file.

A ChArUco board lies on the table in place of the part; the robot shows it to the probe
from ``--views`` poses (the laser off, the room lit), then the laser draws its line on the
plate's plain side at the same poses. Camera intrinsics (with lens distortion where the
config's sensor has it), both cameras' poses (hand-eye) and the laser plane are solved
from the rendered images. Writes DIR/probe.toml (a scan config takes it as
``[probe] calibration = "DIR/probe.toml"``), DIR/calibration.json (reprojection errors,
standard deviations, every parameter's deviation from the truth, the error it puts on
the points) and DIR/calibration.png. Exit codes as for ``scan``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from headless.preflight import folder_argument

    parser.add_argument("config", help="scan config: a name under rigs/scenes/ or a path to a .toml file")
    parser.add_argument("--out", type=folder_argument, help="output folder (default: out/<config name>-calibration)")
    parser.add_argument("--views", type=int, default=None,
                        help="board poses the robot shows the probe (default 20; not with --poses)")
    parser.add_argument("--poses", metavar="FILE",
                        help="the board views to take, a TOML file of [[view]] tables with xyz_mm and yzz_deg (probe "
                             "poses in the table frame; the board lies face up at the table's centre) instead of "
                             "--views proposed ones")
    parser.add_argument("--distortion", choices=("auto", "yes", "no"), default="auto",
                        help="fit lens distortion (auto: where the config's sensor has it)")
    parser.add_argument("--quiet", action="store_true", help="no progress")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from addon.calibrate import FILES, calibrate
    from addon.core.config.scan import load_scan_config
    from addon.core.errors import ConfigError, InputError
    from addon.core.files import check_output_folder
    from headless.scan import progress_and_lock

    config = load_scan_config(args.config, path_required=False)  # (the board views are its own)
    if args.views is not None and args.poses:
        raise InputError(f"--views {args.views} and --poses {args.poses} both choose the board views; give one")
    args.views = 20 if args.views is None else args.views
    if not 4 <= args.views <= 1000:
        raise InputError(f"--views must be in [4, 1000] (a calibration needs at least 4 board poses), "
                         f"got {args.views}")
    out = args.out or str(Path("out") / f"{Path(config.source).stem}-calibration")
    check_output_folder(out, FILES)
    distortion = None if args.distortion == "auto" else args.distortion == "yes"
    poses = None
    if args.poses:
        from addon.core.calibration import load_views

        from addon.core.calibration.solve import MIN_VIEWS

        poses = load_views(args.poses)
        if len(poses) < MIN_VIEWS:
            raise ConfigError(f"{args.poses}: {len(poses)} board view{'s' * (len(poses) != 1)} ([[view]] tables); "
                              f"a calibration needs at least {MIN_VIEWS}")
    count = args.views if poses is None else len(poses)
    print(f"calibrate: {config.name}: {config.robot.name}, {config.probe.name}; {count} board views"
          + (f" from {args.poses}" if poses is not None else " (proposed)")
          # (the ray caster draws a laser line, not a printed board under room light)
          + ("; rendered with Cycles (the config's raycast engine draws no board)"
             if config.render.engine == "raycast" else ""), flush=True)
    bar_progress, lock = progress_and_lock(args, out)

    def progress(stage, done, total):
        # The plan is no work to wait for but a count of board views: one line, not a bar of frames.
        if stage == "plan":
            if not args.quiet:
                bar_progress.bar.say(f"plan: {done} of {total} board views reachable")
            return
        bar_progress(stage, done, total)
        if stage == "laser images" and done == total and getattr(args, "stops", None) is not None:
            # Every image is rendered: a stop asked for until now ends the command with nothing
            # written; one from now on waits for the files (it was announced as a stop and ignored).
            args.stops.finish()

    try:
        t = time.perf_counter()
        run_ = calibrate(config, out, views=args.views, distortion=distortion, poses=poses, progress=progress)
        s = run_.summary
        print(f"calibrated in {time.perf_counter() - t:.1f} s from {s['views']} views "
              f"({len(s['views_left_out'])} left out: unreachable or colliding)")
        for c in (0, 1):
            cam, dev = s[f"camera{c}"], s[f"camera{c}"]["deviation"]
            print(f"  camera {c}   reprojection {cam['reprojection_error_px']:.3f} px over {cam['corners']} corners; "
                  f"f {dev['fx_px']:+.2f}/{dev['fy_px']:+.2f} px, c {dev['cx_px']:+.2f}/{dev['cy_px']:+.2f} px, "
                  f"position {dev['position_mm'] * 1e3:.0f} um, rotation {dev['rotation_deg'] * 60:.1f} arcmin "
                  f"from the truth" + (f"; k1 {cam['distortion'][0]:+.4f}" if s["distortion_fitted"] else ""))
        laser = s["laser"]
        print(f"  laser plane  fit {laser['fit_rms_mm'] * 1e3:.1f} um RMS over {laser['points']} points; "
              f"tilt {laser['deviation']['tilt_deg'] * 60:.1f} arcmin, offset {laser['deviation']['offset_mm'] * 1e3:+.0f}"
              f" um from the truth")
        err = s["triangulation_error"]["all"]
        print(f"  points       the calibration moves points on the laser plane by {err['rms_mm'] * 1e3:.0f} um RMS "
              f"({err['max_mm'] * 1e3:.0f} um at most) over the field of view")
        for name, path in run_.files.items():
            print(f"  wrote        {path}")
        return 0
    except KeyboardInterrupt as exc:
        from headless.lifecycle import Interrupted

        exc = exc if isinstance(exc, Interrupted) else Interrupted(2)
        print(f"{exc.describe()}: nothing written to {out}", file=sys.stderr, flush=True)
        return exc.exit_code
    finally:
        lock.release()
