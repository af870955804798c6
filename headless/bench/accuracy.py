"""Error against run time: one setting changed at a time, on scenes with exact ground truth.

Scenes: the tilted plate (two sweeps), the demo sphere on the turntable (a table
turn and a sweep) and the step block (two sweeps), each on evenly spread frames
of its path. From each scene's own settings (1 sample at the pixel centre,
160 x 160 sensor, gauss read unsmoothed, exact triangulation, 1.2 mm line, the
profile filter on, Cycles with the gobo laser, ideal sensor) one setting at a time
changes: samples per pixel (box filter of one pixel), pixel filter, sensor
resolution, detector, triangulation, laser line width, the profile filter, laser
model and engine, and the realistic sensor. For each: the median time per profile
over the repeats (render + detect + triangulate, one process, side by side) and
the cloud's error on the part against the exact shape.

Outputs (``--out``, default out/accuracy): accuracy.csv, accuracy.md and
accuracy.png (error against time per scene, the Pareto front drawn, the baseline
ringed). ``--readme`` puts the table and plot into docs/accuracy.md.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
import statistics
from dataclasses import dataclass, replace
from pathlib import Path
from headless.bench import whole

SCENES = {"plane": "tilted_plane", "sphere": "demo", "step block": "step_block"}
OUTPUT_FILES = ("accuracy.csv", "accuracy.md", "accuracy.png")
BUDGETS_MS = (20.0, 50.0, 200.0, 1000.0)


@dataclass
class Row:
    scene: str
    factor: str
    setting: str
    ms: float
    rms: float
    p95: float
    max: float
    bias: float
    coverage: float
    points: int
    frames: int
    baseline: bool = False
    pareto: bool = False
    note: str = ""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--frames", type=whole(), default=20, help="frames per scene, at least: every k-th frame of its path, k its frames // N (default 20)")
    parser.add_argument("--repeats", type=whole(), default=3, help="runs per setting; the median time counts (default 3)")
    parser.add_argument("--scenes", default=",".join(SCENES), help=f"comma-separated, of: {', '.join(SCENES)}")
    parser.add_argument("--factors", default="", help="comma-separated factor names to run (default all)")
    parser.add_argument("--eevee-frames", type=whole(), default=4, help="frames for the Eevee rows, at least, spread as --frames's (default 4; slow on a CPU)")
    parser.add_argument("--out", default="out/accuracy", help="folder for accuracy.csv, .md and .png")
    parser.add_argument("--readme", action="store_true", help="also put the table and plot into docs/accuracy.md")
    parser.set_defaults(run=run)


def _filter_label() -> str:
    from addon.core.config.scan import DEFAULT_FILTER as f

    return f"on ({f.max_incidence_deg:g} deg, {f.edge_px} px, σ ≤ {f.max_sigma_mm * 1e3:g} µm)"


def factors():
    """{factor: [(setting, changes)]}; ``changes`` are applied by :func:`variant`."""
    from headless.bench.realism import ALL

    return {
        "samples (box 1 px)": [(f"{n} spp", dict(samples=n, pixel_filter="BOX", filter_width_px=1.0))
                               for n in (1, 2, 4, 16, 64)],
        "pixel filter": [("point, 1 spp", dict()),
                         ("Gaussian 1.5 px, 16 spp", dict(samples=16, pixel_filter="GAUSSIAN", filter_width_px=1.5)),
                         ("Blackman-Harris 1.5 px, 16 spp",
                          dict(samples=16, pixel_filter="BLACKMAN_HARRIS", filter_width_px=1.5))],
        "resolution": [(f"{h} px", dict(rows=h)) for h in (160, 320, 640, 1280)],
        "detector": [("threshold (paper)", dict(detect="threshold")), ("cog", dict(detect="cog")),
                     ("gauss", dict()), ("gauss, smoothed 0.8 px", dict(smoothing=0.8)),
                     ("steger", dict(detect="steger"))],
        "triangulation": [("paper (Eq. 6)", dict(triangulate="paper")), ("exact", dict())],
        "line width": [(f"{w:g} mm", dict(line_mm=w)) for w in (0.6, 1.2, 2.4, 4.8)],
        "profile filter": [("off", dict(profile_filter=False)), (_filter_label(), dict())],
        "laser / engine": [("Cycles, gobo", dict()), ("raycast (Embree), gobo", dict(engine="raycast")),
                           ("Cycles, slit", dict(laser="slit")),
                           ("Eevee, spot", dict(engine="eevee")),
                           ("Eevee, slit", dict(engine="eevee", laser="slit"))],
        "sensor": [("ideal", dict()), ("realistic (all effects)", dict(sensor=ALL))],
    }


def variant(base, changes: dict):
    """The scene's config with one setting changed."""
    from addon.core.optics.profile_filter import ProfileFilter
    from addon.core.optics.sensor import SensorModel

    cfg = base
    render = cfg.render
    # in one replace: 16 samples on the scene's point-sampling box would be refused on the way
    render = replace(render, **{k: changes[k] for k in ("samples", "pixel_filter", "filter_width_px", "laser")
                                if k in changes})
    cfg = replace(cfg, render=render)
    if "engine" in changes:
        cfg = cfg.with_overrides(engine=changes["engine"])
    if "rows" in changes:
        h = changes["rows"]
        cfg = replace(cfg, probe=cfg.probe.with_resolution(h, round(cfg.probe.cols_px * h / cfg.probe.rows_px)))
    if "detect" in changes:
        cfg = cfg.with_overrides(detect=changes["detect"])
    if "smoothing" in changes:
        cfg = replace(cfg, detect=replace(cfg.detect, smoothing_px=changes["smoothing"]))
    if "triangulate" in changes:
        cfg = replace(cfg, triangulate_method=changes["triangulate"])
    if "line_mm" in changes:
        cfg = replace(cfg, probe=replace(cfg.probe, line_width_mm=changes["line_mm"]))
    if changes.get("profile_filter") is False:
        cfg = replace(cfg, profile_filter=ProfileFilter())
    if "sensor" in changes:
        cfg = cfg.with_realism(SensorModel(**changes["sensor"]))
    return cfg


def setting_key(cfg) -> str:
    """What decides a measurement: equal keys are the same setting reached by two factors."""
    return repr((cfg.render, cfg.probe.rows_px, cfg.probe.cols_px, cfg.probe.line_width_mm, cfg.detect_method,
                 cfg.detect_params, cfg.triangulate_method, cfg.profile_filter, cfg.sensor, len(cfg.waypoints)))


def measure(cfg, repeats: int) -> tuple[float, dict]:
    from addon.pipeline import run_scan

    times, report = [], None
    for _ in range(repeats):
        report = run_scan(cfg, None, write_outputs=False).report
        times.append(1e3 / report["profiles_per_s"])
    return statistics.median(times), report


def run(args: argparse.Namespace) -> int:
    from addon.core.errors import InputError
    from addon.core.config.scan import load_scan_config

    if args.frames < 2 or args.repeats < 1 or args.eevee_frames < 1:
        raise InputError("--frames must be at least 2, --repeats and --eevee-frames at least 1")
    from headless.bench import check_readme_whole

    check_readme_whole(args, scenes=",".join(SCENES), factors="")
    from addon.core.files import check_output_folder

    # before the measurements, not after them (a file given as --out threw every one away)
    check_output_folder(args.out, names=OUTPUT_FILES, what="--out")
    scenes = [s.strip() for s in args.scenes.split(",") if s.strip()]
    unknown = [s for s in scenes if s not in SCENES]
    if unknown or not scenes:
        raise InputError(f"--scenes: unknown {', '.join(unknown) or '(none given)'}; allowed: {', '.join(SCENES)}")
    table = factors()
    wanted = [f.strip() for f in args.factors.split(",") if f.strip()] or list(table)
    bad = [f for f in wanted if f not in table]
    if bad:
        raise InputError(f"--factors: unknown {', '.join(bad)}; allowed: {', '.join(table)}")

    # Every distinct setting once per round, the rounds one after another: a slow spell of
    # this shared machine then lands on every setting alike, and the median sees through it.
    jobs: list[tuple] = []       # (scene, factor, setting, changes, key, cfg, note), in table order
    distinct: dict = {}          # key -> cfg, one per distinct measurement
    base_keys = set()
    for scene in scenes:
        base = load_scan_config(SCENES[scene])
        step = max(1, len(base.waypoints) // args.frames)
        base = base.with_overrides(frames=slice(None, None, step))
        base_keys.add((scene, setting_key(base)))
        for factor in wanted:
            for setting, changes in table[factor]:
                cfg = variant(base, changes)
                note = ""
                if changes.get("engine") == "eevee":
                    eevee_step = max(1, len(cfg.waypoints) // args.eevee_frames)
                    cfg = cfg.with_overrides(frames=slice(None, None, eevee_step))
                    note = f"{len(cfg.waypoints)} frames"
                key = (scene, setting_key(cfg))
                distinct.setdefault(key, cfg)
                jobs.append((scene, factor, setting, changes, key, note))
    times: dict = {key: [] for key in distinct}
    reports: dict = {}
    for rnd in range(args.repeats):
        for k, (key, cfg) in enumerate(distinct.items()):
            ms, rep = measure(cfg, 1)
            times[key].append(ms)
            reports.setdefault(key, rep)  # the error does not change between rounds (seeded, deterministic)
            e = rep["error_um"]
            print(f"  round {rnd + 1}/{args.repeats}  {k + 1:>3}/{len(distinct)}  {key[0]:<11}{ms:8.1f} ms  "
                  f"RMS {e['rms_um']:9.1f} um", flush=True)
    rows: list[Row] = []
    for scene, factor, setting, changes, key, note in jobs:
        rep = reports[key]
        e = rep["error_um"]
        if not math.isfinite(e["rms_um"]):
            note = "; ".join(filter(None, [note, _none_kept(rep)]))
        rows.append(Row(scene, factor, setting, statistics.median(times[key]), e["rms_um"], e["p95_um"],
                        e["max_um"], e["bias_um"], rep["coverage"], e["n"], rep["frames"],
                        baseline=key in base_keys, note=note))
    mark_pareto(rows)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    from addon.core.files import write_bytes_atomic

    write_bytes_atomic(out / "accuracy.csv", to_csv(rows).encode())
    md = to_markdown(rows, args)  # beside accuracy.png in the output folder
    write_bytes_atomic(out / "accuracy.md", md.encode())
    plot(rows, out / "accuracy.png")
    print()
    print(md)
    print(f"wrote {out / 'accuracy.csv'}, {out / 'accuracy.md'}, {out / 'accuracy.png'}")
    if args.readme:
        from headless.bench import readme

        readme.update("accuracy", to_markdown(rows, args, readme.picture_link("accuracy", "accuracy.png")),
                      {"accuracy.png": out / "accuracy.png"})
    return 0


def mark_pareto(rows: list[Row]) -> None:
    """A setting is on the front when no other is both faster and more accurate (RMS)."""
    for scene in {r.scene for r in rows}:
        mine = [r for r in rows if r.scene == scene and math.isfinite(r.rms)]
        for r in mine:
            r.pareto = not any(o.ms <= r.ms and o.rms <= r.rms and (o.ms < r.ms or o.rms < r.rms) for o in mine)


def best_within(rows: list[Row], scene: str, budget_ms: float) -> Row | None:
    inside = [r for r in rows if r.scene == scene and r.ms <= budget_ms and math.isfinite(r.rms)]
    return min(inside, key=lambda r: r.rms) if inside else None


def to_csv(rows: list[Row]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["scene", "factor", "setting", "ms_per_profile", "rms_um", "p95_um", "max_um", "bias_um", "coverage",
                "points", "frames", "baseline", "pareto", "note"])
    for r in rows:
        w.writerow([r.scene, r.factor, r.setting, f"{r.ms:.3f}", f"{r.rms:.3f}", f"{r.p95:.3f}", f"{r.max:.3f}",
                    f"{r.bias:.3f}", f"{r.coverage:.4f}", r.points, r.frames, int(r.baseline), int(r.pareto), r.note])
    return buf.getvalue()


def _none_kept(report: dict) -> str:
    """Why a setting kept no point on the part: the reason most of its detected points were
    dropped for (columns without a line aside)."""
    dropped = {k: v for k, v in report.get("points_dropped", {}).items() if k != "no_detection" and v}
    if not dropped:
        return "no line detected"
    reason = max(dropped, key=dropped.get)
    return f"no point kept; most dropped as {reason.replace('_', ' ')}"


def _num(x: float, digits: int = 1) -> str:
    return "n/a" if not math.isfinite(x) else f"{x:.{digits}f}"


def to_markdown(rows: list[Row], args, picture: str = "accuracy.png") -> str:
    """The section's text; ``picture``: the link to the plot from the page it goes into."""
    scenes = list(dict.fromkeys(r.scene for r in rows))
    lines = [
        f"Measured with `python -m headless bench accuracy --frames {args.frames} --repeats {args.repeats}` "
        "(Cycles on the CPU of this 2-core machine; ms per profile = render + detect + triangulate, median of "
        "the repeats; error on the part against its exact shape). **Bold**: the scene's own settings; "
        "★: on the Pareto front (nothing else is both faster and more accurate).",
        "",
        f"![Error against time per profile, one panel per scene]({picture})",
        "",
        "Best setting within a time budget (lowest RMS among the settings measured):",
        "",
        "| scene | " + " | ".join(f"≤ {b:g} ms" for b in BUDGETS_MS) + " |",
        "|---|" + "---|" * len(BUDGETS_MS),
    ]
    for scene in scenes:
        cells = []
        for b in BUDGETS_MS:
            r = best_within(rows, scene, b)
            cells.append("none" if r is None else f"{r.factor}: {r.setting} ({_num(r.rms)} µm, {_num(r.ms)} ms)")
        lines.append(f"| {scene} | " + " | ".join(cells) + " |")
    lines += ["", "| factor | setting | " + " | ".join(f"{s}: ms, RMS / p95 / max µm" for s in scenes) + " |",
              "|---|---|" + "---|" * len(scenes)]
    keys = list(dict.fromkeys((r.factor, r.setting) for r in rows))
    for factor, setting in keys:
        cells = []
        is_base = False
        for scene in scenes:
            r = next((x for x in rows if x.scene == scene and x.factor == factor and x.setting == setting), None)
            if r is None:
                cells.append("")
                continue
            is_base = is_base or r.baseline
            star = " ★" if r.pareto else ""
            note = f" ({r.note})" if r.note else ""
            if not math.isfinite(r.rms):
                cells.append(f"{_num(r.ms)} ms{note}")
                continue
            cells.append(f"{_num(r.ms)} ms, {_num(r.rms)} / {_num(r.p95)} / {_num(r.max, 0)}{star}{note}")
        label = f"**{setting}**" if is_base else setting
        lines.append(f"| {factor} | {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def plot(rows: list[Row], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(dict.fromkeys(r.scene for r in rows))
    factor_names = list(dict.fromkeys(r.factor for r in rows))
    markers = "osD^v<>Ph*X"
    colours = plt.get_cmap("tab10")
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    fig, axes = plt.subplots(1, len(scenes), figsize=(4.6 * len(scenes) + 2.2, 4.4), squeeze=False)
    for ax, scene in zip(axes[0], scenes):
        mine = [r for r in rows if r.scene == scene and math.isfinite(r.rms)]
        for k, factor in enumerate(factor_names):
            pts = [r for r in mine if r.factor == factor and not r.baseline]
            if pts:
                ax.scatter([r.ms for r in pts], [max(r.rms, 1e-3) for r in pts], marker=markers[k % len(markers)],
                           color=colours(k % 10), s=36, label=factor, zorder=3)
        base = next((r for r in mine if r.baseline), None)
        if base is not None:
            ax.scatter([base.ms], [base.rms], s=160, facecolors="none", edgecolors="black", linewidths=1.5,
                       label="scene's own settings", zorder=4)
        front = sorted({(r.ms, r.rms) for r in mine if r.pareto})
        if front:
            xs, ys = zip(*front)
            ax.step(xs, ys, where="post", color="black", linewidth=1, alpha=0.6, zorder=2, label="Pareto front")
        named = set()
        for r in mine:
            if r.pareto and not r.baseline and (r.ms, r.rms) not in named:
                named.add((r.ms, r.rms))
                ax.annotate(r.setting, (r.ms, r.rms), textcoords="offset points", xytext=(4, 4), fontsize=7)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(scene)
        ax.set_xlabel("time per profile (ms)")
        ax.set_ylabel("RMS error on the part (µm)")
        ax.grid(True, which="both", alpha=0.3)
        for axis in (ax.xaxis, ax.yaxis):  # 1-2-5 ticks, written as plain numbers
            axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
            axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
            axis.set_minor_formatter(NullFormatter())
    handles, labels = [], []
    for ax in axes[0]:  # every factor that appears in any panel, once
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(handles, labels, loc="center right", fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0, 1 - 2.0 / fig.get_figwidth(), 1))
    tmp = path.with_suffix(".part.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    tmp.replace(path)
