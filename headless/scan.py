"""``python -m headless scan CONFIG`` and ``python -m headless demo``: run a scan, print a summary.

Exit codes: 0 done; 2 the config or an option is wrong, or a file cannot be written
(one line on stderr, no files written); 3 the scan ran but its RMS error exceeds
``--max-rms-um`` (or no point lands on the part), or it covers less of the surface its path
can measure than ``--min-coverage``; 75 another scan holds the output folder, or a farm's
cluster went away (try again later); 130 stopped by Ctrl-C (143: SIGTERM), nothing written.

Before the first render: the config, the options, the output folder, the render's
size against memory and time, the temporary folder's room and the scheduler's
address are checked (headless.preflight); the output folder is claimed for the
run (a second scan into it is refused while this one runs); the three output files
appear together at the end or not at all.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

EXIT_QUALITY = 3
LARGE_MESH_FACES = 1_000_000  # a part this dense is said to take minutes beyond its frames
LONG_PLAN_FRAMES = 50_000  # a path this long is said to be planned first (minutes without a progress line)
PLAN_S_PER_FRAME = 0.0007  # the planning's pace, measured on a 2-core machine (demo cell, 20 000 frames: 14 s)


def add_arguments(parser: argparse.ArgumentParser, demo: bool = False) -> None:
    from headless.preflight import folder_argument, frames_argument

    if not demo:
        parser.add_argument("config", help="scan config: a name under rigs/scenes/ or a path to a .toml file")
    parser.add_argument("--out", type=folder_argument, help="output folder (default: out/<config name>, with -<engine> added where --engine changes it)")
    parser.add_argument("--frames", type=frames_argument, help="part of the path, as A:B (Python slice, e.g. 0:40 or ::2)")
    from addon.core.config.render import DEVICES, ENGINES
    from addon.core.optics.detect import METHODS as DETECT_METHODS

    parser.add_argument("--engine", choices=ENGINES,
                        help="render engine: cycles; eevee (renders the spot laser unless the config chooses the "
                             "slit); raycast (what Cycles renders under ideal conditions, by Embree ray casting, "
                             "without Blender)")
    parser.add_argument("--samples", type=int, help="samples per pixel")
    parser.add_argument("--device", type=str.upper, choices=DEVICES,
                        help="Cycles render device: CPU, GPU (the first backend found) or a backend by name")
    parser.add_argument("--resolution", help="sensor size WxH (columns x rows), the probe's optics kept")
    parser.add_argument("--detect", choices=DETECT_METHODS, help="line detection method")
    parser.add_argument("--max-rms-um", type=float, help="exit with code 3 when the part's RMS error is larger")
    parser.add_argument("--min-coverage", type=float, metavar="PERCENT",
                        help="exit with code 3 when the scan covers less of the surface its path can measure")
    parser.add_argument("--workers", type=int, help="scan in shards on a local Dask cluster of N worker processes")
    parser.add_argument("--scheduler", help="scan in shards on the Dask scheduler at tcp://HOST:PORT")
    parser.add_argument("--shard-frames", type=int, help="frames per shard (default: about 4 shards per worker)")
    parser.add_argument("--shard", type=int, metavar="K",
                        help="compute only shard K in this process (a farm manager's task; needs --shard-frames)")
    parser.add_argument("--merge", action="store_true",
                        help="compute nothing: merge the shards in --out when all are there (needs --shard-frames)")
    parser.add_argument("--force", action="store_true",
                        help="render even when the frame looks too big for this machine's memory or the scan "
                             "longer than 8 hours")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(run=run_demo if demo else run_scan_command)


def parse_resolution(text: str | None):
    if text is None:
        return None
    from addon.core.errors import InputError

    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise InputError(f"--resolution {text!r}: expected WxH, e.g. 320x320") from None
    from addon.core.optics.probe import MAX_PIXELS, MIN_PIXELS

    if not (MIN_PIXELS <= w <= MAX_PIXELS and MIN_PIXELS <= h <= MAX_PIXELS):
        raise InputError(f"--resolution {text!r}: both sizes must be in [{MIN_PIXELS}, {MAX_PIXELS}] pixels")
    return w, h


def _finite(value) -> bool:
    return value is not None and value == value and abs(value) != float("inf")


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}" if seconds >= 3600 else \
        f"{seconds // 60}:{seconds % 60:02d}"


def progress_and_lock(args, out):
    """For a command that writes into ``out``: its progress callback (the bar, and Ctrl-C
    taking effect between steps) and the folder's lock, released also when stopped."""
    from addon.core.files import OutputLock

    stops = getattr(args, "stops", None)
    bar = ProgressBar(args.quiet)

    def progress(stage, done, total):
        bar(stage, done, total)
        if stops is not None:
            stops.progress(stage, done, total)

    progress.bar = bar  # say(line) and finish() for a command that logs as it goes

    lock = OutputLock(out).acquire()
    if stops is not None:
        stops.cleanups.append(lock.release)
    return progress, lock


class ProgressBar:
    """Progress of long work on stderr: one bar redrawn in place on a terminal (done/total,
    rate, time left); where stderr is not a terminal (a log, CI), a plain line per 10 %.
    An adaptive scan's ``total`` is a budget (it may stop well before): its bar counts
    profiles against the budget and promises no time left. ``say(line)`` prints a line
    (stdout) without running it into the bar; ``finish()`` ends a bar left open."""

    def __init__(self, quiet: bool, stream=None):
        self.quiet = quiet
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty()
        self.start = time.perf_counter()
        self.shown = -1
        self.drawn = ""  # the bar on screen now (tty), "" once its line is ended
        self.stages: set[str] = set()
        self.last = self.start  # when progress was last reported

    def __call__(self, stage: str, done: int, total: int) -> None:
        if self.quiet:
            return
        if stage not in self.stages:  # a new stage (calibrate's laser images after its board images): its own count
            if self.stages:  # (its work began when the last stage last reported)
                self.start, self.shown = self.last, -1
            self.stages.add(stage)
        self.last = time.perf_counter()
        frac = min(done / max(total, 1), 1.0)
        elapsed = time.perf_counter() - self.start
        rate = done / max(elapsed, 1e-9)
        if stage == "adaptive":
            text = f"{stage}: {done} profiles of a budget of {total}, {rate:.1f} profiles/s"
        else:
            unit = "shards" if stage == "shards" else "frames"
            left = _clock((total - done) / rate) if 0 < done < total else ("-" if done == 0 else "0:00")
            text = f"{stage}: {done}/{total} {unit}, {rate:.1f} {unit}/s, {left} left"
        if self.tty:
            bar = "#" * int(30 * frac)
            self.drawn = f"\r[{bar:<30}] {text} "
            self.stream.write(self.drawn)
            if done >= total:
                self.stream.write("\n")
                self.drawn = ""
            self.stream.flush()
        elif int(frac * 10) > self.shown:
            self.shown = int(frac * 10)
            print(f"{text} ({frac * 100:.0f} %)", file=self.stream, flush=True)

    def say(self, line: str) -> None:
        """Print ``line`` on stdout; on a terminal the bar is cleared first and drawn again
        below it."""
        if self.drawn:
            self.stream.write("\r\033[K")
            self.stream.flush()
        print(line, flush=True)
        if self.drawn:
            self.stream.write(self.drawn)
            self.stream.flush()

    def note(self, line: str) -> None:
        """Print ``line`` on stderr with the progress (a farm's running log), the bar cleared
        first and drawn again below it on a terminal: stdout keeps the results alone."""
        if self.drawn:
            self.stream.write("\r\033[K")
        self.stream.write(line + "\n")
        if self.drawn:
            self.stream.write(self.drawn)
        self.stream.flush()

    def finish(self) -> None:
        """End the bar's line where the work stopped short of its total (a budget not spent)."""
        if self.drawn:
            self.stream.write("\n")
            self.stream.flush()
            self.drawn = ""


def run_scan_command(args: argparse.Namespace) -> int:
    from addon.core.config.scan import load_scan_config

    config = load_scan_config(args.config)
    return _run(args, config, args.out or default_out(config, args.engine))


def run_demo(args: argparse.Namespace) -> int:
    from addon.core.config.scan import load_scan_config

    config = load_scan_config("demo")
    return _run(args, config, args.out or default_out(config, args.engine))


def default_out(config, engine: str | None = None, kind: str = "") -> str:
    """The output folder where none is given: out/<config's file name>[-kind], with the engine
    added where --engine changed it (out/demo-raycast), so that a scan with another engine
    does not overwrite the config's own. Refused where it holds the results of another config
    file of the same name (a/scan.toml's, for b/scan.toml): those are not overwritten unasked."""
    name = Path(config.source).stem + (f"-{kind}" if kind else "")
    if engine is not None and engine != config.render.engine:
        name += f"-{engine}"
    out = Path("out") / name
    other = _results_of(out)
    if other is not None and config.source and other != str(Path(config.source).resolve()):
        from addon.core.errors import InputError

        raise InputError(f"the default output folder {out} holds the results of {other}; give --out for "
                         f"{config.source}'s (or move that folder away)")
    return str(out)


def _results_of(folder: Path) -> str | None:
    """The config file whose results ``folder`` holds (report.json's config.file, resolved);
    None where it holds none that say."""
    import json

    try:
        source = json.loads((folder / "report.json").read_text())["config"]["file"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return str(Path(source).resolve()) if isinstance(source, str) and source else None


def _run(args: argparse.Namespace, config, out: str) -> int:
    from addon.core.config.scan import parse_frames

    config = config.with_overrides(engine=args.engine, samples=args.samples,
                                   resolution=parse_resolution(args.resolution), detect=args.detect,
                                   frames=parse_frames(args.frames, "--frames"), device=args.device)
    if args.max_rms_um is not None and not 0 < args.max_rms_um < float("inf"):
        from addon.core.errors import InputError

        raise InputError(f"--max-rms-um must be a positive, finite number of micrometres, got {args.max_rms_um}")
    min_coverage = args.min_coverage
    if min_coverage is not None and not 0 < min_coverage <= 100:
        from addon.core.errors import InputError

        raise InputError(f"--min-coverage must be a percentage above 0 and at most 100, got {min_coverage}")
    if args.shard is not None and (args.max_rms_um is not None or min_coverage is not None):
        from addon.core.errors import InputError

        given = "--max-rms-um" if args.max_rms_um is not None else "--min-coverage"
        raise InputError(f"--shard K computes one shard and no figures, so {given} has nothing to check there; "
                         f"give it to the --merge task, which computes them")
    if args.workers is not None:
        from addon.core.errors import check_whole
        from headless.farm import MAX_WORKERS

        check_whole(args.workers, "--workers", 1, MAX_WORKERS)
    if args.shard is not None and (args.workers is not None or args.scheduler is not None or args.merge):
        from addon.core.errors import InputError

        given = next(o for o, v in (("--workers", args.workers), ("--scheduler", args.scheduler),
                                    ("--merge", args.merge or None)) if v is not None)
        raise InputError(f"--shard K runs one shard in this process, so {given} has nothing to do with it; "
                         f"leave {given} out, or run the whole job without --shard")
    if args.workers is not None and args.scheduler is not None:
        from addon.core.errors import InputError

        raise InputError("--workers N starts a local cluster of N workers and --scheduler uses a running one's: "
                         "give one of them (a running cluster's workers are its own)")
    if args.merge and (args.workers is not None or args.scheduler is not None):
        from addon.core.errors import InputError

        given = "--workers" if args.workers is not None else "--scheduler"
        raise InputError(f"--merge computes nothing (it merges the shard files the job's tasks wrote), so {given} "
                         f"has nothing to do with it; leave {given} out")
    if args.shard_frames is not None and not 1 <= args.shard_frames <= len(config.waypoints):
        from addon.core.errors import InputError

        raise InputError(f"--shard-frames must be 1 to {len(config.waypoints)} (the path's frames), "
                         f"got {args.shard_frames}")
    if (args.shard is not None or args.merge) and args.shard_frames is None:
        from addon.core.errors import InputError

        raise InputError("--shard and --merge need --shard-frames (the same for every task of the job)")
    from addon.core.scan.outputs import OUTPUT_FILES
    from headless import preflight

    farm = (args.workers is not None or args.scheduler is not None or args.shard_frames is not None
            or args.merge)
    local = 1
    if farm and args.scheduler is None and args.shard is None and not args.merge:
        from headless.farm import local_workers

        local = local_workers(len(config.waypoints), args.workers if args.workers is not None else 2,
                              args.shard_frames)
    # What renders here: a --shard task its shard, a --merge nothing, a scheduler's workers all
    # (elsewhere). (The whole path was counted: a farm job's task of 4 frames was refused as 10 h.)
    here = 0 if args.merge or args.scheduler is not None else \
        min(args.shard_frames, len(config.waypoints)) if args.shard is not None else None
    preflight.check_scan(config, out, names=OUTPUT_FILES.values(), farm=farm, scheduler=args.scheduler,
                         force=args.force, local_workers=local, frames=here)
    n = len(config.waypoints)
    size = " x ".join(f"{v:.4g}" for v in config.workpiece.mesh.extents) + " mm"  # a unit mistake shows here
    faces = len(config.workpiece.mesh.faces)
    if faces >= LARGE_MESH_FACES:  # a 4 M-face part: 2 min planning, 45 s metrics, 44 s writing, said nowhere
        size += (f", {faces / 1e6:.1f} M faces: its collision model, metrics and preview take minutes; a decimated "
                 f"mesh is faster")
    print(f"scan: {config.name} ({n} frame{'' if n == 1 else 's'}, {config.robot.name}, {config.probe.name}, "
          f"workpiece {config.workpiece.source}, {size})", flush=True)
    if n >= LONG_PLAN_FRAMES and args.shard is None:  # (a --merge plans the whole path too)
        # (a path of a million frames planned for over 5 min before the first progress line)
        print(f"scan: planning the path first: inverse kinematics, reach and collision checks for each of its {n} "
              f"frames (about {n * PLAN_S_PER_FRAME / 60:.0f} min on a 2-core machine)", flush=True)
    stops = getattr(args, "stops", None)
    if args.shard is not None:  # one task of a farm job: many write into the same --out at once
        return _run_shard(args, config, out)
    progress, lock = progress_and_lock(args, out)
    try:
        return _scan_and_summarise(args, config, out, farm, stops, progress)
    except KeyboardInterrupt as exc:
        from headless.lifecycle import Interrupted

        exc = exc if isinstance(exc, Interrupted) else Interrupted(2)
        finished, of = getattr(exc, "shards_finished", (0, 0))  # counted on disk once the cluster closed
        written = (f"no cloud or report written to {out}; {finished} of the {of} shards are finished in "
                   f"{Path(out) / 'shards'}, for the next run to keep" if finished else f"nothing written to {out}")
        print(f"{exc.describe()}: {written}", file=sys.stderr, flush=True)
        return exc.exit_code
    finally:
        lock.release()


def _run_shard(args: argparse.Namespace, config, out: str) -> int:
    from headless.farm import run_one_shard

    # (no lock: a farm job's tasks write into the same --out at once; a task monitor still
    # wants to see the shard move, which printed nothing for its whole run)
    bar, stops = ProgressBar(args.quiet), getattr(args, "stops", None)

    def progress(stage, done, total):
        bar(stage, done, total)
        if stops is not None:
            stops.progress(stage, done, total)

    try:
        info = run_one_shard(config, out, args.shard_frames, args.shard, progress=progress)
    finally:
        bar.finish()
    print(f"  {info['describe']} of {info['of']}: {info['points']} points in {info['seconds']:.1f} s -> "
          f"{info['path']}")
    return 0


def _scan_and_summarise(args: argparse.Namespace, config, out: str, farm: bool, stops, progress) -> int:
    """The scan (on a farm or here) with ``progress`` (progress_and_lock's), its summary and the quality gates."""
    t = time.perf_counter()
    if farm:
        from headless.farm import run_farm

        result = run_farm(config, out, workers=args.workers if args.workers is not None else 2,
                          scheduler=args.scheduler, shard_frames=args.shard_frames,
                          log=(lambda m: None) if args.quiet else progress.bar.note,
                          progress=progress, merge_only=args.merge,
                          measured=None if stops is None else stops.finish)
    else:
        from addon import Scanner

        scanner = Scanner(config=config)
        # Not run(): its report would come before a late stop is heard. Once the last frame is
        # measured (the bar says 100 %), a stop waits for the results: a stop while the cloud
        # was put together after it threw the whole scan away.
        for done, total in scanner.run_steps(progress):
            if stops is not None and done >= total:
                stops.finish()  # a stop asked for during the last frames: still nothing written
        if stops is not None and not stops.finishing:
            stops.finish()
        result = scanner.result(out)
    wall = time.perf_counter() - t
    print_summary(result, wall)
    failed = quality_failure(result.report, args.max_rms_um, args.min_coverage)
    if failed:
        print(f"error: {failed}", file=sys.stderr)
        return EXIT_QUALITY
    return 0


def quality_failure(report: dict, max_rms_um: float | None, min_coverage: float | None) -> str | None:
    """Why a scan fails the command's quality gates (``--max-rms-um``, ``--min-coverage`` in
    percent of the surface the path can measure), or None where it passes them all."""
    if max_rms_um is not None and not report["points_on_part"]:
        return f"no point landed on the part, so its RMS error cannot be held to --max-rms-um {max_rms_um:g}"
    if max_rms_um is not None and not report["error_um"]["rms_um"] <= max_rms_um:
        return f"RMS error {report['error_um']['rms_um']:.1f} um exceeds --max-rms-um {max_rms_um:g}"
    if min_coverage is not None:
        if not report["measurable_share"] > 0:
            return f"none of the part is measurable from this path, so --min-coverage {min_coverage:g} cannot be met"
        covered = 100.0 * report["coverage_measurable"]
        if not covered >= min_coverage:
            return (f"the scan covers {covered:.1f} % of the surface its path can measure, under --min-coverage "
                    f"{min_coverage:g}")
    return None


def clearance_where(nearest: dict, frames: int) -> str:
    """Where the report's nearest contact lies, in words: "at frame 12" (it is looked for at the
    path's waypoints), or, in a Scanner session, on a move between frames or after the last one
    (its frame is the one the next measurement takes, which the move does not reach)."""
    frame = nearest["frame"]
    if not nearest.get("on_move"):
        return f"at frame {frame}"
    return f"on a move before frame {frame}" if frame < frames else "on a move after the last frame"


def print_summary(result, wall: float) -> None:
    """The scan's summary on stdout: points, error, coverage, clearance, drops, time, speed, files."""
    r = result.report
    e = r["error_um"]
    if r["config"].get("calibration"):
        print(f"\n  calibration   triangulated with the calibrated probe in {r['config']['calibration']}", end="")
    print(f"\n  points        {r['points']} ({r['points_on_part']} on the part, {r['points_on_table']} on the table"
          f"{', ' + str(r['points_on_fixtures']) + ' on fixtures' if r.get('points_on_fixtures') else ''}), "
          f"{r['valid_fraction'] * 100:.1f} % of sensor columns with a line")
    if e["n"]:
        bias = f"bias {e['bias_um']:+.1f} um" if _finite(e["bias_um"]) else "bias n/a (an open mesh has no inside)"
        print(f"  error         RMS {e['rms_um']:.1f} um, mean {e['mean_um']:.1f} um, p95 {e['p95_um']:.1f} um, "
              f"max {e['max_um']:.1f} um, {bias} (part, against its exact shape)")
        within = r.get("within_2_sigma")
        print(f"  outliers      {r.get('outliers', 0)} points farther than 0.2 mm from the part"
              + ("" if within is None else f"; {within * 100:.1f} % within twice their stated sigma"))
    else:
        print("  error         none: no point on the part")
    measurable = (f"{r['coverage_measurable'] * 100:.1f} % of the surface the path can measure "
                  f"({r['measurable_share'] * 100:.1f} % of the part)" if r["measurable_share"] > 0
                  else "none of the part is measurable from this path (in range, within the incidence limit, seen)")
    print(f"  coverage      {measurable}, {r['coverage'] * 100:.1f} % of the whole part, "
          f"within {r['coverage_tolerance_mm']:g} mm of a point")
    c = (r.get("clearance") or {}).get("nearest")
    if r.get("clearance") is None and any(w.startswith("collision checks were off") for w in r.get("warnings", [])):
        print("  clearance     not checked ([safety] check = false)")
    if c:
        print(f"  clearance     {c['clearance_mm']:.1f} mm at least, {c['bodies'][0]} to {c['bodies'][1]} "
              f"{clearance_where(c, r['frames'])} (at least {r['clearance']['min_clearance_mm']:g} mm allowed)")
    ts = r["time_s"]
    dropped = ", ".join(f"{name.replace('_', ' ')} {count}" for name, count in sorted(r["points_dropped"].items())
                        if count)
    print(f"  kept          {r['points_fused']} points fused from both cameras; dropped after detection: "
          f"{dropped or 'none'}")
    stages = ", ".join(f"{name} {ts[name]:.2f}" for name in ("plan", "planner", "scene", "render", "detect",
                                                             "triangulate", "neighbours", "metrics", "write")
                       if name in ts)
    # A farm's shards ran side by side, or in earlier tasks (a merge): their stages add up over
    # the workers and can exceed the command's own time.
    summed = " (scene to triangulate summed over the shards' workers)" if "farm" in r else ""
    print(f"  time          {wall:.1f} s: {stages}{summed}")
    print(f"  speed         {r['profiles_per_s']:.1f} profiles/s (render + detect + triangulate) on "
          f"{r.get('render_device') or 'CPU'}; "
          f"cameras {r['cameras_rendered']}, {r['mean_rows_rendered']:.0f} of {r['config']['sensor_px'][1]} rows "
          f"rendered on average")
    if "farm" in r:
        f = r["farm"]
        rate = f"{f['profiles_per_s_wall']:.1f} profiles/s" if f["profiles_per_s_wall"] else "nothing to compute"
        print(f"  farm          {f['shards']} shards ({f['computed']} computed, {f['reused']} reused), "
              f"{f['wall_s']:.1f} s on the cluster: {rate}")
    for w in r["warnings"]:
        print(f"  warning       {w}")
    for name, path in result.files.items():
        print(f"  {name:<13} {path}")
