"""``python -m headless adaptive CONFIG``: scan a part adaptively, with the reference next-best-view
planner (addon.adaptive), from its bounding box alone.

The config gives the cell (robot, probe, table), the part (rendered, and measured against
afterwards, but never shown to the planner) and an optional ``[adaptive]`` table (the box
the planner is told, the budget); its ``[[path]]`` entries are ignored. Writes what a scan
writes (cloud.ply, report.json with ``frames`` = profiles taken and ``adaptive``: the sweeps
chosen, preview.png). Exit codes as for ``scan``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from dataclasses import replace


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from addon.core.config.render import ENGINES
    from addon.core.config.scan import AdaptiveSettings
    from headless.preflight import folder_argument

    parser.add_argument("config", help="scan config: a name under rigs/scenes/ or a path to a .toml file")
    parser.add_argument("--out", type=folder_argument, help="output folder (default: out/<config name>-adaptive, with -<engine> added where --engine changes it)")
    parser.add_argument("--max-profiles", type=int,
                        help=f"profile budget (default: the config's, else {AdaptiveSettings.max_profiles})")
    parser.add_argument("--min-gain", type=int,
                        help=f"new cells a view must promise (default: the config's, else {AdaptiveSettings.min_gain})")
    parser.add_argument("--target-coverage", type=float, metavar="F",
                        help="stop once the planner's own coverage estimate reaches this share, over 0 and at most 1 "
                             "(default: the config's, else none)")
    parser.add_argument("--engine", choices=ENGINES,
                        help="render engine, as for scan (default: the config's); raycast needs no Blender")
    parser.add_argument("--force", action="store_true", help="as for scan: skip the memory and time limits")
    parser.add_argument("--quiet", action="store_true", help="no progress and no log of the sweeps")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from addon import Scanner
    from addon.adaptive import BudgetBelowView, check_target_coverage, part_box
    from addon.core.config.scan import MAX_MIN_GAIN, MAX_PROFILES, load_scan_config
    from addon.core.errors import InputError
    from addon.core.scan.outputs import OUTPUT_FILES
    from headless import preflight
    from headless.scan import default_out, print_summary, progress_and_lock

    given = load_scan_config(args.config, path_required=False)  # the planner ignores [[path]]
    config = given.with_overrides(engine=args.engine)
    settings = config.adaptive
    if args.max_profiles is not None:
        if not 1 <= args.max_profiles <= MAX_PROFILES:
            raise InputError(f"--max-profiles must be from 1 to {MAX_PROFILES}, got {args.max_profiles}")
        settings = replace(settings, max_profiles=args.max_profiles)
    if args.min_gain is not None:
        if not 1 <= args.min_gain <= MAX_MIN_GAIN:
            raise InputError(f"--min-gain must be from 1 to {MAX_MIN_GAIN:.0e}, got {args.min_gain}")
        settings = replace(settings, min_gain=args.min_gain)
    if args.target_coverage is not None:
        try:
            check_target_coverage(args.target_coverage)
        except InputError as exc:
            raise InputError(f"--target-coverage: {exc}") from None
        settings = replace(settings, target_coverage=args.target_coverage)
    out = args.out or default_out(given, args.engine, "adaptive")
    # (the budget's profiles, not the config's [[path]], which the planner ignores)
    preflight.check_scan(config, out, names=OUTPUT_FILES.values(), force=args.force, profiles=settings.max_profiles)
    lo, hi = part_box(config)
    print(f"adaptive: {config.name}: {config.robot.name}, {config.probe.name}; the planner is told the box "
          f"{lo.round(1).tolist()} .. {hi.round(1).tolist()} mm, budget {settings.max_profiles} profiles"
          + ("" if settings.target_coverage is None else f", target coverage {settings.target_coverage * 100:.0f} %"),
          flush=True)
    stops = getattr(args, "stops", None)
    progress, lock = progress_and_lock(args, out)
    try:
        t = time.perf_counter()
        scanner = Scanner(config=replace(config, adaptive=settings))
        try:
            steps = scanner.adaptive((lo, hi), progress=progress, log=None if args.quiet else progress.bar.say)
        except BudgetBelowView as exc:
            where = "--max-profiles" if args.max_profiles is not None else "--max-profiles, or [adaptive] max_profiles,"
            raise InputError(f"no view was scanned: the budget of {exc.budget} profiles is below the smallest view's "
                             f"{exc.smallest} (raise {where} to at least {exc.smallest}); nothing "
                             f"written") from None
        finally:
            progress.bar.finish()
        if stops is not None:
            stops.finish()  # as a scan's: a stop from here waits for the results to be written
        if not steps:
            raise InputError(f"no view was scanned: none the robot can do fits the budget of {settings.max_profiles} "
                             f"profiles and promises {settings.min_gain} new surface cells (raise --max-profiles, or check "
                             f"that the [adaptive] box {lo.round(1).tolist()} .. {hi.round(1).tolist()} mm is the "
                             f"part's, on the table within the robot's reach); nothing written")
        result = scanner.result(out)
        print_summary(result, time.perf_counter() - t)
        plan_s = [s.planning_s for s in steps]
        if plan_s:
            views = f"{len(steps)} view{'s' if len(steps) != 1 else ''}"
            print(f"  planner       {views}, {sum(s.profiles for s in steps)} profiles; planning "
                  f"{max(plan_s):.2f} s at most per decision (median {statistics.median(plan_s):.2f} s); "
                  f"its coverage estimate {steps[-1].coverage_estimate * 100:.1f} %")
        return 0
    except KeyboardInterrupt as exc:
        from headless.lifecycle import Interrupted

        progress.bar.finish()
        exc = exc if isinstance(exc, Interrupted) else Interrupted(2)
        print(f"{exc.describe()}: nothing written to {out}", file=sys.stderr, flush=True)
        return exc.exit_code
    finally:
        lock.release()
