"""The reference adaptive planner against fixed paths given the same profile budget, part by part:
coverage against profiles, sweeps, the probe's path length, planning time per decision, RMS.

Parts: the demo's sphere, the step block, and the real parts of ``bench parts`` (CAD-like
booleans and real meshes). Methods, each with ``--budget`` profiles:

- **planner**: addon.adaptive (told only the part's box grown by 10 %);
- **turns**: full table turns at three probe heights (from above, 45° down at mid-height,
  70° down low at the sides), a third of the budget each: what an engineer sets up blind;
- **raster**: parallel sweeps straight down across the box at two table angles 90° apart;
- **sides** (only when ``--methods`` names it): the turns' two passes from the side (45° and
  70°) alone, 30 % of the budget each: the baseline's own best views within 60 % of its
  profiles, a yardstick for the ≤ 60 % goal (docs/adaptive.md, *Not yet*);
- **low** (only when ``--methods`` names it): other blind views within the same 60 % of the
  budget: a 45° turn and a 75° turn aimed at a fifth of the part's height (as the planner's
  steepest), 120/270 of it each, and a sweep straight down across the top with the rest;
- **yours** (with ``--planner FILE.py:NAME``): a planner of your own, run as the reference is
  (``NAME(scanner, lo, hi)`` told the same box, then ``choose(scanner, profiles left)`` and
  ``scan(scanner, view)`` until it chooses None or the budget is spent).

Coverage is of the whole part (the truth used only to score), after each sweep or pass.
"Reached with" is the share of the baseline's profiles the planner needed to reach the
baseline's final coverage (goal ≤ 60 %). Coverage of the measurable surface is the
report's, for the planner's own path.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from headless.bench import whole


GROWTH_PNG = Path(__file__).resolve().parents[1] / "gallery" / "adaptive_growth.png"
GROWTH_PANELS = 5   # at most; the views between are left out, the last one always in
METHODS = ("planner", "turns", "raster", "sides", "low", "yours")
DEFAULT_METHODS = ("planner", "turns", "raster")  # without --methods (and yours with --planner)
ADAPTIVE = ("planner", "yours")  # the methods that choose their views (the others are fixed paths)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--budget", type=whole(), default=450, help="profiles per method and part (default 450)")
    parser.add_argument("--only", default="", help="only the parts whose name holds this text (comma-separated; "
                                                   "--list names them)")
    parser.add_argument("--list", action="store_true", help="name the parts and stop")
    parser.add_argument("--planner", default="",
                        help="a planner of your own to compare: FILE.py:NAME or MODULE:NAME, where NAME(scanner, lo, "
                             "hi) gives an object with choose(scanner, profiles_left) -> view or None and "
                             "scan(scanner, view) (a subclass of addon.adaptive.NextBestView is one; see "
                             "docs/adaptive.md)")
    parser.add_argument("--methods", default=None,
                        help=f"the methods to run, comma-separated from {', '.join(METHODS)} (default: "
                             f"{','.join(DEFAULT_METHODS)}, and yours with --planner)")
    parser.add_argument("--engine", choices=("cycles", "raycast"), default="cycles",
                        help="render engine (default cycles; raycast: what Cycles renders under ideal conditions, "
                             "without Blender, for a quick comparison)")
    parser.add_argument("--readme", action="store_true", help="put the table and the plot into docs/adaptive.md")
    parser.add_argument("--growth", action="store_true",
                        help="draw the planner's scan of the first part growing, view by view, into "
                             "headless/gallery/adaptive_growth.png")
    parser.set_defaults(run=run)


def parts() -> dict:
    from addon.core.config.scan import load_scan_config
    from headless.parts import all_parts

    out = {"sphere (demo)": load_scan_config("demo").workpiece.mesh,
           "step block": load_scan_config("step_block").workpiece.mesh}
    out.update(all_parts())
    return out


def config_for(name: str, mesh, engine: str = "cycles"):
    """The bench's scan config for one part (``parts()``): the demo's cell, robot and probe
    with the part on the table (so "step block" is that mesh in the demo's cell, not
    rigs/scenes/step_block.toml)."""
    from addon.core.config.scan import load_scan_config
    from addon.core.geometry.workpiece import Workpiece

    base = load_scan_config("demo").with_overrides(engine=None if engine == "cycles" else engine)
    return replace(base, name=name, workpiece=Workpiece(name, mesh, mesh, f"bench:{name}", np.eye(4)))


def load_planner(spec: str):
    """The planner factory ``--planner`` names: FILE.py:NAME (a file of yours) or MODULE:NAME
    (importable from here). Raises InputError naming what is missing."""
    import importlib
    import importlib.util

    from addon.core.errors import InputError

    where, _, name = spec.rpartition(":")
    if not where or not name.isidentifier():
        raise InputError(f"--planner {spec!r}: expected FILE.py:NAME or MODULE:NAME (NAME: your planner's class "
                         f"or factory)")
    if where.endswith(".py"):
        path = Path(where)
        if not path.is_file():
            raise InputError(f"--planner {spec!r}: there is no file {where}")
        module_spec = importlib.util.spec_from_file_location(f"your_planner_{path.stem}", path)
        module = importlib.util.module_from_spec(module_spec)
        # Registered as imports are (dataclasses look their module up there), and with its own
        # folder's modules importable for the whole run (a helper file next to it, imported as
        # it loads or later in choose()); after the installed ones, which it cannot shadow.
        sys.modules[module_spec.name] = module
        folder = str(path.resolve().parent)
        if folder not in sys.path:
            sys.path.append(folder)
        try:
            module_spec.loader.exec_module(module)
        except Exception as exc:
            sys.modules.pop(module_spec.name, None)
            raise InputError(f"--planner {spec!r}: {where} failed to load: {_where_failed(exc, where)}") from None
    else:
        try:
            module = importlib.import_module(where)
        except Exception as exc:
            raise InputError(f"--planner {spec!r}: cannot import {where}: {type(exc).__name__}: {exc}") from None
    factory = getattr(module, name, None)
    if not callable(factory):
        raise InputError(f"--planner {spec!r}: {where} has no class or function {name}")
    return factory


def _where_failed(exc: BaseException, file: str | None = None) -> str:
    """An exception in one line, with the innermost line of ``file`` (or of any file) it passed."""
    import traceback

    if isinstance(exc, SyntaxError):  # its message names the file and the line
        return f"{type(exc).__name__}: {exc}"
    frames = traceback.extract_tb(exc.__traceback__)
    mine = [f for f in frames if file and Path(f.filename).resolve() == Path(file).resolve()] or frames[-1:]
    at = f" (at {mine[-1].filename}:{mine[-1].lineno})" if mine else ""
    return f"{type(exc).__name__}: {exc}{at}"


def _path_length(scanner) -> float:
    """The probe's path (mm, world frame) over every pose the scanner went through."""
    q = np.concatenate([p[0] for p in scanner._poses]) if scanner._poses else np.zeros((0, 6))
    if len(q) < 2:
        return 0.0
    P = scanner.config.cell.robot.fk(q)[:, :3, 3]
    return float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())


def run_planner(config, budget: int, factory=None) -> dict:
    """One adaptive planner on one part: ``factory(scanner, lo, hi)`` (default the reference,
    addon.adaptive.NextBestView) told the part's box, asked for views until it has none or the
    budget is spent. A planner of one's own (``--planner``) that fails or breaks the rules
    raises InputError naming what it did."""
    from addon import Scanner
    from addon.adaptive import NextBestView, part_box
    from addon.core.errors import InputError, ScannerError, is_whole

    own = factory is not None
    factory = factory or NextBestView
    who = f"your planner {getattr(factory, '__name__', factory)!r}"

    def yours(what: str, call):
        if not own:
            return call()
        try:
            return call()
        except ScannerError as exc:  # the Scanner refused what it was asked: its own one line
            raise InputError(f"{who}, {what}: {exc}") from None
        except Exception as exc:
            raise InputError(f"{who} failed in {what}: {_where_failed(exc)}") from None

    scanner = Scanner(config=config)
    lo, hi = part_box(config)

    def kept_rules(what: str, before: int) -> None:
        """Every profile counts, and the bench's config scores the scan: a planner that measured
        outside scan() (in its set-up or in choose()) or replaced the scanner's config is
        stopped (it scanned for free, or was scored against another truth)."""
        if not own:
            return
        if scanner.frames_taken != before:
            raise InputError(f"{who} measured {scanner.frames_taken - before} profiles in {what}: every profile "
                             f"counts against the budget, so measure only in scan(), the view choose() gave")
        if scanner.config is not config:
            raise InputError(f"{who} replaced the scanner's config in {what}: the bench scores every planner "
                             f"against its own config; keep your settings in your planner")

    t = time.perf_counter()
    planner = yours("its set-up", lambda: factory(scanner, lo, hi))  # the one-off set-up (model, candidates, ...)
    setup = time.perf_counter() - t
    kept_rules("its set-up", 0)
    smallest = getattr(planner, "smallest_view", None)
    if callable(smallest):  # (the reference's, and a subclass's): a budget that fits no view scans nothing
        smallest = yours("smallest_view()", smallest)
        if is_whole(smallest) and budget < smallest:
            raise InputError(f"--budget {budget} is below the smallest view's {smallest} profiles of "
                             f"{'your planner' if own else 'the planner'} on {config.workpiece.name}: nothing would "
                             f"be scanned (give a budget of at least {smallest})")
    curve, plan_s, taken, views = [], [], 0, []
    while taken < budget:
        t = time.perf_counter()
        before = scanner.frames_taken
        c = yours("choose()", lambda: planner.choose(scanner, budget - taken))
        plan_s.append(time.perf_counter() - t)
        kept_rules("choose()", before)
        if c is None:
            break
        frames = getattr(c, "frames", None)
        if own and not (is_whole(frames) and 0 < frames <= budget - taken):
            raise InputError(f"your planner chose {_describe(c)} with {frames!r} profiles while "
                             f"{budget - taken} were left in the budget: choose() must return a view that fits "
                             f"the profiles it is given, or None")
        yours("scan()", lambda: planner.scan(scanner, c))
        took = scanner.frames_taken - before  # what the scanner took, whatever scan() returns
        if own and not 0 < took <= budget - taken:
            raise InputError(f"{who}: its scan() of {_describe(c)} ({frames} profiles) measured {took}, with "
                             f"{budget - taken} left in the budget: scan() must measure the view it chose"
                             + (", which is more than the budget" if took else ""))
        kept_rules("scan()", scanner.frames_taken)
        taken += took
        curve.append((taken, scanner.result().report["coverage"]))
        views.append(_describe(c))
    result = scanner.result()
    r = result.report
    part = result.cloud.select(result.on_part)
    estimate = getattr(planner, "coverage_estimate", None)
    out = dict(curve=curve, sweeps=len(curve), profiles=taken, path_mm=_path_length(scanner), views=views,
               part_points=part.points, part_frames=part.frame,
               plan_max=max(plan_s) if plan_s else 0.0, plan_median=float(np.median(plan_s)) if plan_s else 0.0,
               setup=setup, rms=r["error_um"]["rms_um"], coverage=r["coverage"], measurable=r["coverage_measurable"])
    if callable(estimate):
        given = yours("coverage_estimate()", estimate)
        try:
            value = float(given)
        except (TypeError, ValueError):
            value = math.nan
        if own and not 0.0 <= value <= 1.0:
            raise InputError(f"{who}: its coverage_estimate() gave {given!r}: the bench shows it beside the true "
                             f"coverage, so it must be a share from 0 to 1 (or leave the method out)")
        out["estimate"] = value
    return out


def _describe(view) -> str:
    """A view for the growth picture's titles: kind and tilt where it has them."""
    kind, tilt = getattr(view, "kind", None), getattr(view, "tilt_deg", None)
    try:
        tilt = float(tilt)
    except (TypeError, ValueError):
        tilt = math.nan
    if kind is None or not math.isfinite(tilt):
        return type(view).__name__
    return f"{'turn' if kind == 'turn' else 'sweep'}, tilt {tilt:.0f} deg"


def run_fixed(config, passes) -> dict:
    """A fixed path given as passes [(waypoints, label)]; coverage after each."""
    from addon import Scanner
    from addon.core.kinematics.path import concatenate

    curve, done = [], []
    for wp in passes:
        done.append(wp)
        scanner = Scanner(config=replace(config, waypoints=concatenate(done)))
        scanner.run()
        curve.append((int(sum(len(w.table_rad) for w in done)), scanner.result().report["coverage"]))
    r = scanner.result().report
    return dict(curve=curve, sweeps=len(passes), profiles=curve[-1][0], path_mm=_path_length(scanner),
                plan_max=0.0, plan_median=0.0, rms=r["error_um"]["rms_um"], coverage=r["coverage"],
                measurable=r["coverage_measurable"])


TURN_HEIGHTS = ((45.0, 0.5), (70.0, 0.3))  # (tilt from vertical, aim's share of the part's height)


def turns(config, budget: int, from_above: bool = True, share: float = 1.0 / 3.0):
    """A full table turn from above and one at each of TURN_HEIGHTS, ``share`` of the budget
    each (``from_above`` False: the side turns alone)."""
    from addon.core.kinematics import path as scanpath

    from headless.bench.parts import STANDOFF_MM

    top = float(config.workpiece.mesh.bounds[1][2])
    n = max(1, int(budget * share + 1e-9))
    out = [scanpath.turntable(n, [12.0, 0.0, top + STANDOFF_MM], table=config.table, segment=0)] if from_above else []
    # Two more heights, not the mirror of one: a turn 45° from one side sees, over its full
    # circle, what the same turn from the other side sees (a first version spent its third
    # pass so and added nothing).
    return out + side_turns(config, n, TURN_HEIGHTS, first_segment=len(out))


def side_turns(config, frames: int, heights, first_segment: int = 0) -> list:
    """A full table turn of ``frames`` profiles for each (tilt from vertical, aim's share of
    the part's height) in ``heights``: the probe on the +y side, aimed half the part's corner
    radius out from the axis, the laser plane holding the axis."""
    from addon.core.kinematics import path as scanpath

    from headless.bench.parts import STANDOFF_MM

    lo, hi = config.workpiece.mesh.bounds
    radius = float(np.linalg.norm(np.maximum(np.abs(lo[:2]), np.abs(hi[:2]))))
    top = float(hi[2])
    out = []
    for k, (tilt_deg, height) in enumerate(heights):
        a = math.radians(tilt_deg)
        beam = np.array([0.0, -math.sin(a), -math.cos(a)])
        aim = np.array([0.0, 0.5 * radius, height * top])
        out.append(scanpath.turntable(frames, aim - STANDOFF_MM * beam, beam, (0.0, 0.0, 1.0), table=config.table,
                                      segment=first_segment + k))
    return out


SIDES_SHARE = 0.3  # of the budget, for each of the sides method's two turns: 60 % together
LOW_TURNS = ((45.0, 0.5), (75.0, 0.2))  # the low method's turns: (tilt from vertical, aim's share of the height)


def low_views(config, budget: int):
    """The ``low`` yardstick: 60 % of ``budget``, 4/9 of it for each of the LOW_TURNS and the
    rest for a sweep straight down across the part's top (the line across the part's x)."""
    from addon.core.kinematics import path as scanpath

    from headless.bench.parts import STANDOFF_MM

    lo, hi = config.workpiece.mesh.bounds
    total = int(0.6 * budget + 1e-9)
    n_turn = max(1, total * 4 // 9)
    out = side_turns(config, n_turn, LOW_TURNS)
    top = float(hi[2])
    half = max(abs(float(lo[0])), abs(float(hi[0]))) + 2.0
    z = top + STANDOFF_MM
    out.append(scanpath.sweep(max(2, total - 2 * n_turn), [-half, 0.0, z], [half, 0.0, z], segment=len(out)))
    return out


def raster(config, budget: int):
    from addon.core.kinematics import path as scanpath

    from headless.bench.parts import STANDOFF_MM

    lo, hi = config.workpiece.mesh.bounds
    half = 0.5 * float(np.linalg.norm((hi - lo)[:2])) + 5.0
    z = float(hi[2]) + STANDOFF_MM
    lines = 4
    n = max(2, budget // (2 * lines))
    out = []
    for k, table_deg in enumerate((0.0, 90.0)):
        for j, y in enumerate(np.linspace(-0.5 * half, 0.5 * half, lines)):
            out.append(scanpath.sweep(n, [-half, y, z], [half, y, z], table_rad=math.radians(table_deg),
                                      segment=k * lines + j))
    return out


def reached_with(planner_curve, target: float) -> float | None:
    """Profiles the planner needed to reach ``target`` coverage (None: never)."""
    for profiles, cov in planner_curve:
        if cov >= target - 1e-9:
            return profiles
    return None


def table(rows: list[dict]) -> str:
    """The markdown table; with a planner of your own, a column of the profiles it needed to
    reach each other method's final coverage beside the reference planner's."""
    theirs = any(r["method"] == "yours" for r in rows)
    head = ("| part | method | profiles | sweeps / passes | coverage, whole | coverage, measurable | "
            "planner's own estimate | probe path | planning per decision (max / median; the set-up before the "
            "first) | RMS µm | planner reaches this with |" + (" yours reaches this with |" if theirs else ""))
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        plan = (f"{r['plan_max']:.2f} / {r['plan_median']:.2f} s (set-up {r['setup']:.2f} s)"
                if r["method"] in ADAPTIVE else "")
        estimate = f"{r['estimate'] * 100:.1f} %" if "estimate" in r else ""
        reach = " | ".join(_reach_text(r.get(key), r["coverage"])
                           for key in (("reach", "reach_yours") if theirs else ("reach",)))
        lines.append(f"| {r['part']} | {r['method']} | {r['profiles']} | {r['sweeps']} | {r['coverage'] * 100:.1f} % | "
                     f"{r['measurable'] * 100:.1f} % | {estimate} | {r['path_mm'] / 1000:.2f} m | {plan} | "
                     f"{r['rms']:.1f} | {reach} |")
    return "\n".join(lines)


def _reach_text(reach, target: float) -> str:
    """The profiles a planner needed to reach ``target``, and their share; "never" with the
    two coverages to as many decimals (two at least) as tell them apart, which the table's one
    decimal may show equal (87.1 % and "never" for 87.08 % against 87.11 %)."""
    if reach is None:
        return ""
    if reach[0]:
        return f"{reach[0]} profiles ({reach[1] * 100:.0f} %)"
    digits = next((d for d in range(2, 7) if f"{reach[2] * 100:.{d}f}" != f"{target * 100:.{d}f}"), 6)
    return f"never ({reach[2] * 100:.{digits}f} % at most, against {target * 100:.{digits}f} %)"


def growth_picture(mesh, planner: dict, path) -> None:
    """The planner's cloud of one part growing, a panel per view (at most GROWTH_PANELS)."""
    import cv2

    from addon.core.scan.preview import growth_strip

    ends = np.array([p for p, _ in planner["curve"]])
    view = np.searchsorted(ends, planner["part_frames"], side="right")  # frame -> the view that took it
    shown = sorted(set(np.linspace(0, len(ends) - 1, min(GROWTH_PANELS, len(ends))).round().astype(int)))
    # Views left out of the strip join the next panel shown.
    panel_of_view = np.searchsorted(shown, np.arange(len(ends)))
    titles = [f"{ends[k]} profiles: {planner['views'][k]}, {planner['curve'][k][1] * 100:.0f} % of the part"
              for k in shown]
    picture = growth_strip(mesh, planner["part_points"], panel_of_view[view], titles)
    cv2.imwrite(str(path), picture)


def plot(results: dict, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(results)
    fig, axes = plt.subplots(1, n, figsize=(2.8 * n, 2.8), squeeze=False, sharey=True)
    for ax, (part, methods) in zip(axes[0], results.items()):
        for method, r in methods.items():
            xs, ys = zip(*([(0, 0.0)] + r["curve"]))
            ax.plot(xs, np.array(ys) * 100, marker="o", ms=3, label=method)
        ax.set_title(part, fontsize=7)
        ax.set_xlabel("profiles", fontsize=7)
        ax.tick_params(labelsize=6)
    axes[0][0].set_ylabel("coverage of the part, %", fontsize=7)
    axes[0][0].legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def chosen_methods(text: str | None, planner: str) -> list[str]:
    """The methods ``--methods`` names (default: all, yours only with ``--planner``)."""
    from addon.core.errors import InputError

    if text is None:
        return [m for m in METHODS if m in DEFAULT_METHODS or (m == "yours" and planner)]
    names = [w.strip().lower() for w in text.split(",") if w.strip()]
    if not names:
        raise InputError(f"--methods {text!r} names no method; name one or more of {', '.join(METHODS)}, "
                         "comma-separated (or leave --methods out for the default)")
    unknown = [n for n in names if n not in METHODS]
    if unknown:
        raise InputError(f"--methods: {unknown[0]!r} is not one of {', '.join(METHODS)}")
    if "yours" in names and not planner:
        raise InputError("--methods yours needs --planner FILE.py:NAME (your planner)")
    if planner and "yours" not in names:
        names.append("yours")
    return [m for m in METHODS if m in names]


def run(args: argparse.Namespace) -> int:
    from addon.core.errors import InputError

    catalogue = parts()
    if args.list:
        for name, mesh in catalogue.items():
            print(f"{name}: {len(mesh.faces)} faces, {np.ptp(mesh.bounds, axis=0).round(1).tolist()} mm")
        return 0
    methods_run = chosen_methods(args.methods, args.planner)
    if args.readme and (methods_run != list(DEFAULT_METHODS) or args.engine != "cycles" or args.only):
        raise InputError("--readme writes the README's table: every part, the three methods, Cycles "
                         "(leave out --only, --methods, --planner and --engine)")
    factory = load_planner(args.planner) if args.planner else None
    wanted = [w.strip().lower() for w in args.only.split(",") if w.strip()]
    picked = {n: m for n, m in catalogue.items() if not wanted or any(w in n.lower() for w in wanted)}
    if not picked:
        raise InputError(f"--only {args.only!r}: no part's name holds it; the parts: {', '.join(catalogue)}")
    rows, results = [], {}
    for name, mesh in picked.items():
        config = config_for(name, mesh, args.engine)
        runs = {"planner": lambda: run_planner(config, args.budget),
                "turns": lambda: run_fixed(config, turns(config, args.budget)),
                "raster": lambda: run_fixed(config, raster(config, args.budget)),
                "sides": lambda: run_fixed(config, turns(config, args.budget, from_above=False, share=SIDES_SHARE)),
                "low": lambda: run_fixed(config, low_views(config, args.budget)),
                "yours": lambda: run_planner(config, args.budget, factory)}
        methods = {m: runs[m]() for m in methods_run}
        results[name] = methods
        if args.growth and len(results) == 1:
            grown = next((methods[m] for m in ADAPTIVE if m in methods and methods[m]["curve"]), None)
            if grown is not None:
                growth_picture(mesh, grown, GROWTH_PNG)
                print(f"{name}: the scan growing, view by view: {GROWTH_PNG}", flush=True)
        for method, r in methods.items():
            row = dict(part=name, method=method, **{k: v for k, v in r.items() if k != "curve"})
            for planner, key in (("planner", "reach"), ("yours", "reach_yours")):
                if planner in methods and method != planner:
                    curve = methods[planner]["curve"]
                    got = reached_with(curve, r["coverage"])
                    row[key] = (got, got / r["profiles"] if got else None, max((c for _, c in curve), default=0.0))
            rows.append(row)
        print(f"{name}: " + "; ".join(f"{m} {r['coverage'] * 100:.1f} % in {r['profiles']} profiles"
                                      for m, r in methods.items()), flush=True)
    named = args.methods is not None and methods_run != list(DEFAULT_METHODS)
    command = f"python -m headless bench adaptive --budget {args.budget}" + (
        f" --methods {','.join(methods_run)}" if named else "") + (
        f" --planner {args.planner}" if args.planner else "") + (
        " --engine raycast" if args.engine == "raycast" else "")
    body = (f"Adaptive scanning against fixed paths (`{command}`, 2-core CPU, "
            f"{'Cycles' if args.engine == 'cycles' else 'the raycast engine'}): coverage of the whole part (against "
            f"its mesh, after the scan), of the surface the method's own path can measure, the planner's own "
            f"coverage estimate from its model (what `--target-coverage` stops at), the probe's path length and the "
            f"planner's time per decision; the last column: the profiles the planner needed to reach that "
            f"method's final coverage, and their share of that method's.\n\n" + table(rows))
    print("\n" + body)
    if args.readme:
        from headless.bench import readme

        readme.update_with_picture("adaptive", body, lambda png: plot(results, png),
                                   "Coverage against profiles, per part and method")
    return 0
