"""The realistic sensor, effect by effect: cloud error and time per profile against the ideal mode.

For each standard scene (the demo sphere on the turntable, the step block) the
same scan runs with the ideal sensor, with each realism effect alone, and with
all of them, side by side in one process. Error is against the exact shape:
RMS and p95 of the points on the part, and the share of sensor columns where no
line was accepted (rejected: no line, saturated, ambiguous, too wide).

Realistic settings used (addon.core.optics.sensor defaults unless said): 12-bit
sensor, 10 000 e⁻ full well, 5 e⁻ read noise, 1 % fixed-pattern gain, a chip
6.4 mm wide (40 µm pixels at 160 columns: a 13 mm lens), f/8 focused where the
blur is equal at both ends of the range, 650 nm laser, auto-exposure to 70 % of
full scale, 100 frames/s with a 1 ms exposure; glossy: roughness 0.15 with 2 light
bounces; ambient: world light 0.3 of the laser's mid-range peak; distortion
k1 = −0.05, k2 = 0.01 (0.6 % at the corners of this narrow view), and a strong
k1 = −0.5 (6 %), removed by calibration before triangulation or not.
"""

from __future__ import annotations

import argparse
import statistics
from dataclasses import replace
from headless.bench import whole

EFFECTS = {
    "pixel integration": dict(integrate_pixels=True),
    "exposure + saturation": dict(saturate=True, auto_exposure=True),
    "sensor noise": dict(saturate=True, noise=True, auto_exposure=True),
    "speckle": dict(speckle=True),
    "defocus": dict(defocus=True),
    "distortion (calibrated)": dict(distortion=(-0.05, 0.01, 0.0, 0.0)),
    "distortion (not removed)": dict(distortion=(-0.05, 0.01, 0.0, 0.0), undistort=False),
    "strong distortion (calibrated)": dict(distortion=(-0.5, 0.0, 0.0, 0.0)),
    "strong distortion (not removed)": dict(distortion=(-0.5, 0.0, 0.0, 0.0), undistort=False),
    "motion blur": dict(motion_blur=True),
}
ALL = dict(integrate_pixels=True, saturate=True, noise=True, auto_exposure=True, speckle=True, defocus=True,
           distortion=(-0.05, 0.01, 0.0, 0.0), motion_blur=True)
ALL_SCENE = dict(material="glossy", roughness=0.15, bounces=2, ambient=0.3)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--frames", type=whole(), default=30, help="frames per scan (default 30)")
    parser.add_argument("--repeats", type=whole(), default=1, help="runs per row; the median time counts")
    parser.add_argument("--scenes", default="demo,step_block", help="scan configs, comma-separated "
                                                                     "(default demo,step_block)")
    parser.add_argument("--only", choices=("scans", "noise"), help="run one part: the scans or the noise comparison")
    parser.add_argument("--noise-frames", type=whole(), default=20, help="noisy frames per level (default 20)")
    parser.add_argument("--readme", action="store_true", help="also put the tables into docs/realism.md")
    parser.set_defaults(run=run)


def variants():
    yield "ideal", {}, {}
    for name, kw in EFFECTS.items():
        yield name, kw, {}
    yield "glossy surface (2 bounces)", {}, dict(material="glossy", roughness=0.15, bounces=2)
    yield "dark surface", {}, dict(material="dark")
    yield "dark surface, auto-exposure", dict(saturate=True, noise=True, auto_exposure=True), dict(material="dark")
    yield "ambient light", {}, dict(ambient=0.3)
    yield "all of the above (glossy)", ALL, ALL_SCENE


def ideal(base):
    """``base`` with the ideal sensor of the paper: no sensor effect, a grey part, no room light
    and no light bounces (a config that has its own [sensor] table, a glossy part or room light,
    as cylinder_realistic has, is not its own ideal)."""
    from addon.core.optics.sensor import SensorModel

    cfg = replace(base.with_realism(SensorModel(), "grey", None, 0.0), roughness=0.2)
    return replace(cfg, detect=replace(cfg.detect, saturation=float("inf")), render=replace(cfg.render, bounces=0))


def configure(base, sensor_kw, scene_kw):
    # A white world of strength S lights a grey (albedo ρ) surface to radiance ρ·S; the
    # laser's peak is 0.5 at mid-range: S = fraction · 0.5 / ρ.
    ambient = scene_kw["ambient"] * 0.5 / 0.6 if "ambient" in scene_kw else None
    cfg = base.with_realism(replace(base.sensor, **sensor_kw), scene_kw.get("material"), scene_kw.get("roughness"),
                            ambient)
    if "bounces" in scene_kw:
        cfg = replace(cfg, render=replace(cfg.render, bounces=scene_kw["bounces"]))
    return cfg


def run(args: argparse.Namespace) -> int:
    from headless.bench import sensor_noise

    if args.frames < 1 or args.repeats < 1 or args.noise_frames < 1:
        from addon.core.errors import InputError

        raise InputError("--frames, --repeats and --noise-frames must be at least 1")
    from headless.bench import check_readme_whole

    check_readme_whole(args, scenes="demo,step_block", frames=30, repeats=1)  # (--only writes one section whole)
    sections = {}
    if args.only != "noise":
        sections["realism"] = scans(args)
    if args.only != "scans":
        rows = sensor_noise.compare(args.noise_frames)
        sensor_noise.print_table(rows)
        sections["realism-noise"] = sensor_noise.to_markdown(rows, args.noise_frames)
    if args.readme:
        from headless.bench import readme

        for name, body in sections.items():
            readme.update(name, body)
    return 0


def scans(args: argparse.Namespace) -> str:
    """Run the scans, print the table; return it as Markdown."""
    from addon.core.config.scan import load_scan_config
    from addon.core.errors import InputError
    from addon.pipeline import run_scan

    scenes = []
    names = [n.strip() for n in args.scenes.split(",") if n.strip()]
    if not names:  # an empty table, exit 0, before
        raise InputError(f"--scenes {args.scenes!r} names no scan config (none given); e.g. --scenes demo,step_block")
    for name in names:
        base = load_scan_config(name)
        step = max(1, len(base.waypoints) // args.frames)
        scenes.append((name, ideal(base).with_overrides(frames=slice(None, None, step))))  # each effect on its own
    rows = []
    for scene_name, base in scenes:
        for label, sensor_kw, scene_kw in variants():
            cfg = configure(base, sensor_kw, scene_kw)
            times, rep = [], None
            for _ in range(args.repeats):
                rep = run_scan(cfg, None, write_outputs=False).report
                times.append(1.0 / rep["profiles_per_s"])
            e = rep["error_um"]
            rows.append((scene_name, label, e["rms_um"], e["p95_um"], 1 - rep["valid_fraction"],
                         statistics.median(times), e["n"]))
            print(f"  {scene_name:<11}{label:<34}RMS {e['rms_um']:8.1f} um", flush=True)
    print()
    print("Realistic sensor: error on the part against the exact shape, rejected sensor columns, time per profile")
    hdr = (f"{'scene':<12}{'effect':<34}{'points':>8}{'RMS um':>9}{'p95 um':>9}{'rejected':>10}{'ms/profile':>12}"
           f"{'x ideal':>9}")
    print(hdr + "\n" + "-" * len(hdr))
    ideal_s = {}
    for scene_name, label, rms, p95, rej, t, n in rows:
        if label == "ideal":
            ideal_s[scene_name] = t
        print(f"{scene_name:<12}{label:<34}{n:>8}{rms:>9.1f}{p95:>9.1f}{rej * 100:>9.1f}%{t * 1e3:>12.1f}"
              f"{t / ideal_s[scene_name]:>8.1f}x")
    return to_markdown(rows, ideal_s, args)


def to_markdown(rows, ideal_s: dict, args) -> str:
    lines = [f"Measured with `python -m headless bench realism --frames {args.frames} --repeats {args.repeats}` "
             "(Cycles on the CPU of this 2-core machine, all rows side by side in one run; error on the part "
             "against its exact shape; rejected = sensor columns without an accepted line):", "",
             "| scene | effect | points on the part | RMS µm | p95 µm | rejected | ms/profile | × ideal |",
             "|---|---|---|---|---|---|---|---|"]
    last = None
    for scene_name, label, rms, p95, rej, t, n in rows:
        shown = scene_name if scene_name != last else ""
        last = scene_name
        bold = label.startswith("all of the above")
        name = f"**{label}**" if bold else label
        lines.append(f"| {shown} | {name} | {n} | {_figure(rms, n, bold)} | {_figure(p95, n, bold)} | {rej * 100:.1f} % | {t * 1e3:.1f} | "
                     f"{t / ideal_s[scene_name]:.1f} |")
    return "\n".join(lines) + "\n"


def _figure(x: float, points: int, bold: bool) -> str:
    if points == 0:
        return "–"  # no point on the part: nothing to measure
    return f"**{x:.1f}**" if bold else f"{x:.1f}"
