"""Command line of the simulator: ``python -m headless <command>``.

Commands:
  demo                 the demo scan (rigs/scenes/demo.toml): the README's first command
  scan CONFIG          a scan described by a config file (rigs/scenes/*.toml)
  adaptive CONFIG      scan the config's part adaptively from its bounding box (next-best-view planner)
  calibrate CONFIG     calibrate the config's probe from rendered ChArUco boards and laser lines (probe.toml)
  gym-baselines        the Gymnasium environment's baselines (reference planner, random, random allowed): coverage
  kinematics           tool poses of the bundled robots and IK solves
  bench kinematics     FK/IK speed, IK success and accuracy, false successes
  bench detect         laser-line detection accuracy and speed on synthetic images
  bench triangulate    paper's Eq. 6 against the exact intersection, speed, stability
  bench render         N frames in one render call against N separate calls
  bench scan           profiles/s end to end, error, and what each leave-out saves
  bench realism        the realistic sensor effect by effect against the ideal mode
  bench accuracy       error against run time, one setting at a time, with the Pareto front
  bench stability      stiff and extreme cases, each with its expected and measured outcome
  bench farm           sharded scans on a local Dask cluster: 1 against 2 workers
  bench versions       the demo under several Blender releases (their interpreters), side by side
  bench measure        one Scanner.measure() against one frame of a batch scan
  bench metrics        point-to-mesh distances: libigl's AABB tree against trimesh
  bench parts          real parts (CAD-like and scanned meshes) against their meshes, beside the line-width floor
  bench collision      collision checks along a 10 000-frame path: frames/s, pairs/s
  bench ik-bridge      IK from a controller over TCP/IP against the local solver: agreement, latency
  bench adaptive       the adaptive planner against fixed paths on the same budget, part by part
  bench calibration    scans with probes calibrated from 5 to 40 board poses against the true probe
  bench incidence      the part's error by angle of incidence, beside the line-width floor
  ik-server            serve this project's IK over TCP/IP with the controller protocol
  robot-meshes         install the bundled robots' link meshes where a package ships them (optional)
  overview             a picture of the cell and the two probe camera images
  realism-figure       one probe frame seen by the ideal and by the realistic sensor
  build-extension      the Blender extension zips (wheels downloaded, Blender's tool builds)

Errors the user can fix (bad rig file, bad value) print one line and exit 2; an output
folder another scan holds, or a farm's cluster that went away, one line and exit 75 (try
again later); Ctrl-C exits 130
(SIGTERM 143); scan's exit codes are listed in headless/scan.py.
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import sys
from pathlib import Path

from addon.core.errors import ScannerError, TemporaryFailure

EXIT_USER_ERROR = 2
EXIT_BUSY = 75  # sysexits' EX_TEMPFAIL: the output folder is another scan's, or the cluster went; try again later


class OneLineParser(argparse.ArgumentParser):
    """argparse with its errors on one line (what was wrong and where the help is), exit 2."""

    def error(self, message: str):
        self.exit(EXIT_USER_ERROR, f"error: {message} (see: {self.prog} --help)\n")

    def parse_args(self, args=None, namespace=None):
        """As argparse's, but an unknown option points to the help of the command it was given
        to (``python -m headless scan --help``), not to the top level's. A slice counted from the
        path's end (``--frames -5:``) is taken as --frames' value, not as an option of its own."""
        args = sys.argv[1:] if args is None else list(args)
        for i in range(len(args) - 2, -1, -1):
            if args[i] == "--frames" and re.fullmatch(r"-\d[\d:-]*", args[i + 1]):
                args[i:i + 2] = [f"--frames={args[i + 1]}"]
        known, extras = self.parse_known_args(args, namespace)
        if extras:
            where = " ".join(v for v in (self.prog, getattr(known, "command", None), getattr(known, "bench", None))
                             if v)
            self.exit(EXIT_USER_ERROR, f"error: unrecognized arguments: {' '.join(extras)} (see: {where} --help)\n")
        return known


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="python -m headless", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    from headless import scan

    scan.add_arguments(sub.add_parser("demo", help="run the demo scan (rigs/scenes/demo.toml)"), demo=True)
    from addon.core.config.toml import available_rigs

    scan.add_arguments(sub.add_parser("scan", help="run the scan a config file describes (bundled: "
                                      + ", ".join(available_rigs("scenes")) + ")"))
    from headless import adaptive

    adaptive.add_arguments(sub.add_parser("adaptive", help=_summary(adaptive.__doc__)))
    from headless import calibrate

    calibrate.add_arguments(sub.add_parser("calibrate", help=_summary(calibrate.__doc__)))
    from headless import scan_env

    scan_env.add_arguments(sub.add_parser("gym-baselines", help="run the Gymnasium environment's baselines "
                                          "(the reference planner, random actions, random actions the mask "
                                          "allows) and print their coverage curves"))
    sub.add_parser("kinematics", help="tool poses of the bundled robots and one IK solve each").set_defaults(
        run=_run_kinematics)

    bench = sub.add_parser("bench", help="benchmarks that print figures and ratios")
    bench_sub = bench.add_subparsers(dest="bench", required=True, metavar="NAME")
    from headless import build_extension, overview, realism_figure
    from headless.bench import accuracy as bench_accuracy
    from headless.bench import detect as bench_detect
    from headless.bench import farm as bench_farm
    from headless.bench import kinematics as bench_kinematics
    from headless.bench import realism as bench_realism
    from headless.bench import render as bench_render
    from headless.bench import scan as bench_scan
    from headless.bench import stability as bench_stability
    from headless.bench import triangulate as bench_triangulate
    from headless.bench import measure as bench_measure
    from headless.bench import metrics as bench_metrics
    from headless.bench import parts as bench_parts
    from headless.bench import collision as bench_collision
    from headless.bench import ik_bridge as bench_ik_bridge
    from headless.bench import adaptive as bench_adaptive
    from headless.bench import calibration as bench_calibration
    from headless.bench import incidence as bench_incidence
    from headless.bench import versions as bench_versions

    overview.add_arguments(sub.add_parser("overview", help=_summary(overview.__doc__)))
    from headless import ik_server

    ik_server.add_arguments(sub.add_parser("ik-server", help=_summary(ik_server.__doc__)))
    from headless import robot_meshes

    robot_meshes.add_arguments(sub.add_parser("robot-meshes", help=_summary(robot_meshes.__doc__)))
    realism_figure.add_arguments(sub.add_parser("realism-figure", help=_summary(realism_figure.__doc__)))
    build_extension.add_arguments(sub.add_parser("build-extension", help=_summary(build_extension.__doc__)))
    for name, module in (("kinematics", bench_kinematics), ("detect", bench_detect),
                         ("triangulate", bench_triangulate), ("render", bench_render), ("scan", bench_scan),
                         ("realism", bench_realism), ("accuracy", bench_accuracy),
                         ("stability", bench_stability), ("farm", bench_farm), ("versions", bench_versions),
                         ("measure", bench_measure), ("metrics", bench_metrics),
                         ("parts", bench_parts), ("collision", bench_collision),
                         ("ik-bridge", bench_ik_bridge), ("adaptive", bench_adaptive),
                         ("calibration", bench_calibration), ("incidence", bench_incidence)):
        module.add_arguments(bench_sub.add_parser(name, help=_summary(module.__doc__)))
    return parser


def _summary(doc: str) -> str:
    """A module docstring's first sentence, without a leading "``command``:" label."""
    text = " ".join(doc.strip().split("\n\n")[0].split())
    if text.startswith("``") and "``:" in text:
        text = text.split("``:", 1)[1].strip()
    # A sentence ends at ". " before a capital letter, not after an abbreviation ("Eq. 6").
    ends = [m.start() for m in re.finditer(r"\.\s+(?=[A-Z])", text)
            if not re.search(r"\b(Eq|e\.g|i\.e|Fig)$", text[:m.start()])]
    sentence = (text[:ends[0]] if ends else text).rstrip(".")
    return sentence[0].upper() + sentence[1:] if sentence else sentence


def _run_kinematics(args: argparse.Namespace) -> int:
    from headless import kinematics_demo

    return kinematics_demo.run()


def main(argv: list[str] | None = None, *, exiting: bool = False) -> int:
    """Run a command in its own temporary folder with Ctrl-C taken as a request to stop
    (headless.lifecycle); a user's error or a file that cannot be written is one line.
    ``exiting``: the process exits with the returned code right after (``python -m
    headless``), so after a stop the signals stay with the stop until it is gone; otherwise
    they are given back whatever happened."""
    from headless.lifecycle import PrivateTemp, StopRequests

    # Started with stdout or stderr closed (`>&-`, a daemon), Python has None there: what would
    # go to it goes nowhere, instead of an AttributeError's traceback after the results were
    # written (and exit 1).
    if sys.stdout is None:
        sys.stdout = open(os.devnull, "w")
    if sys.stderr is None:
        sys.stderr = open(os.devnull, "w")
    # A terminal or a log that cannot show a character (a path in another script under an
    # ASCII locale) gets it escaped, not a UnicodeEncodeError in the middle of a scan.
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.reconfigure(errors="backslashreplace")
        except (AttributeError, ValueError, OSError):  # a replaced stream (pytest's capture) keeps its own
            pass

    # The signals are taken before the heavy imports (see StopRequests.record_only).
    stops = StopRequests(exiting=exiting)
    stops.record_only = True
    stops.install()
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        from addon import pipeline
    except BaseException:
        stops.signum = None  # a stop asked for while the command was refused: nothing to stop
        stops.restore()
        raise
    temp = PrivateTemp()
    stops.temp = temp
    args.stops = stops
    pipeline.set_default_progress(args.stops.progress)  # scans started without one (the benchmarks')
    code = None
    try:
        code = _exit_code(args, stops)
        return code
    finally:
        # The command is over: from here a signal ends the process with its code (see
        # StopRequests.leaving); a second Ctrl-C after a stop still ends it cleanly (exit 130).
        sys.stderr.flush()
        args.stops.restore(code)
        temp.close()
        pipeline.set_default_progress(None)


def _exit_code(args: argparse.Namespace, stops) -> int:
    """Run the command; its exit code, with a user's error, a stop or a closed pipe said in one line."""
    from headless.lifecycle import SIGNAL_NAMES, Interrupted

    try:
        try:
            stops.record_only = False
            stops.check()  # Ctrl-C while the command started
            code = args.run(args)
            if stops.signum is not None and code == 0:  # asked for once nothing was left to stop
                print(f"({SIGNAL_NAMES.get(stops.signum, 'the stop')} came after the last frame: the command "
                      f"finished and wrote its results)", file=sys.stderr, flush=True)
            sys.stdout.flush()  # a closed pipe shows here, inside the handlers, not at the interpreter's exit
            return code
        except BaseException:
            # The failure is being told below: a signal from now on is only noted (the command
            # ends with the failure's code), never raised into the handler printing it.
            stops.record_only = True
            raise
    except TemporaryFailure as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BUSY
    except ScannerError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_USER_ERROR
    except Interrupted as exc:
        # A benchmark writes its figures and files once all is measured: none yet.
        if getattr(args, "bench", None) and exc.total and exc.done >= exc.total and exc.unit == "frames":
            # (its last scan was done: "after 160 of 160 frames of the scan under way" named none)
            print(f"interrupted ({SIGNAL_NAMES.get(exc.signum, 'a signal')}) between two of the benchmark's scans: "
                  f"nothing written", file=sys.stderr)
            return exc.exit_code
        where = " of the scan under way: nothing written" if getattr(args, "bench", None) else ""
        print(exc.describe() + where, file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("interrupted (Ctrl-C)", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # Whoever read the output (``| head``) has gone: that is no failure of the scan, and
        # files already written (all of a set or none) stay. Exit as a process killed by
        # SIGPIPE would, and let nothing else try the closed pipe on the way out.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
        try:
            print("stopped: the program reading the output closed it (broken pipe)", file=sys.stderr, flush=True)
        except OSError:  # stderr went into the same closed pipe (2>&1)
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stderr.fileno())
        return 128 + signal.SIGPIPE
    except OSError as exc:  # a disk full, a folder that vanished, a permission taken away mid-run
        where = f"{exc.filename}: " if exc.filename else ""
        # The results are written all together or not at all; a farm's finished shards stay
        # (for the next run to reuse), so say so where there are some.
        print(f"error: {where}{exc.strerror or exc} (no results written{_shards_kept(args)})", file=sys.stderr)
        return EXIT_USER_ERROR


def _shards_kept(args) -> str:
    """"; N shard files kept in OUT/shards ..." where a farm's shard files are there, else ""
    (files only: which of them a later run can reuse, it checks then)."""
    out = getattr(args, "out", None)
    if not out:
        return ""
    try:
        n = sum(1 for p in (Path(out) / "shards").glob("shard_*.npz") if p.is_file())
    except OSError:
        return ""
    return (f"; {n} shard file{'s' if n != 1 else ''} kept in {Path(out) / 'shards'}, which the next run reuses "
            f"where valid") if n else ""
