"""What a calibration costs: the bench scenes scanned with the true probe and with probes
calibrated from 5, 10, 20 and 40 board poses, on the ideal and on the realistic sensor.

Each calibration renders its board and laser images in the demo cell (``addon.calibrate``),
solves, and is then used to triangulate scans that render with the true probe: the tilted
plate and the demo sphere (every third and every sixth frame of their paths). Printed per
row: the reprojection error (RMS over both cameras' corners), the error the calibration puts
on points of the laser plane over the whole view (its error field: from geometry alone),
the scans' RMS error against the exact shapes, and the calibration's run time. Then, for the
20-pose calibration, which parameter moves the points most: the true probe with one group
of calibrated parameters swapped in at a time.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from headless.bench import check_readme_whole, whole

VIEWS = (5, 10, 20, 40)
SCENES = (("tilted_plane", slice(None, None, 3), "plate"), ("demo", slice(None, None, 6), "sphere"))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    # (at least 4: a calibration needs them, as the calibrate command says)
    parser.add_argument("--views", type=whole(4, 1000), nargs="+", default=list(VIEWS), help="board poses per calibration")
    parser.add_argument("--ideal-only", action="store_true", help="leave out the realistic sensor's rows")
    parser.add_argument("--readme", action="store_true", help="put the tables and the plot into docs/calibration.md")
    parser.set_defaults(run=run)


def _scan_rms(cfg, probe, frames) -> float:
    from addon import Scanner

    scanner = Scanner(config=replace(cfg, probe=probe).with_overrides(frames=frames))
    return float(scanner.run().error_um.rms_um)


def _groups(truth, fit, realistic: bool):
    """{group: probe} the true probe with one group of the calibration's parameters swapped in."""
    import numpy as np

    from addon.core.optics.calibrated import CameraModel, ProbeCalibration

    cal = fit.probe.calibration
    exact = ProbeCalibration.of(truth)

    def probe_with(K=False, dist=False, pose=False, plane=False):
        cams = tuple(CameraModel(c.K if K else e.K, c.distortion if dist else np.zeros(5),
                                 c.cam2probe if pose else e.cam2probe) for c, e in zip(cal.cameras, exact.cameras))
        n, d = (cal.plane_normal, cal.plane_offset_mm) if plane else (exact.plane_normal, exact.plane_offset_mm)
        return replace(truth, calibration=ProbeCalibration(cams, n, d))

    out = {"focal lengths and principal points": probe_with(K=True),
           "camera poses (hand-eye)": probe_with(pose=True),
           "laser plane": probe_with(plane=True)}
    if realistic:
        out["lens distortion (k1)"] = probe_with(dist=True)
    out["all of them"] = fit.probe
    return out


def run(args: argparse.Namespace) -> int:
    from addon.calibrate import calibrate
    from addon.core.calibration import triangulation_error
    from addon.core.config.scan import load_scan_config
    from addon.core.errors import CalibrationError

    check_readme_whole(args, views=list(VIEWS), ideal_only=False)
    base = {name: load_scan_config(name) for name, _, _ in SCENES}
    realistic_sensor = load_scan_config("cylinder_realistic").sensor
    sensors = [("ideal", None)] + ([] if args.ideal_only else [("realistic", realistic_sensor)])
    rows, sens, pictures = [], [], {}
    folder = Path(tempfile.mkdtemp(prefix="bench-calibration-"))
    for label, sensor in sensors:
        cfgs = {k: (c if sensor is None else replace(c, sensor=sensor)) for k, c in base.items()}
        truth = cfgs["demo"].probe
        true_dist = tuple(cfgs["demo"].sensor.distortion)
        row = {"sensor": label, "views": "true probe", "reproj": "", "field": "", "seconds": ""}
        for name, frames, short in SCENES:
            row[short] = _scan_rms(cfgs[name], truth, frames)
        rows.append(row)
        print(f"{label:9s} true probe: " + ", ".join(f"{s} {row[s]:.1f} um" for _, _, s in SCENES), flush=True)
        for n in args.views:
            keep = folder / "views" if n == 20 and sensor is None else None  # its picture goes into the docs
            t = time.perf_counter()
            try:
                cal = calibrate(cfgs["demo"], keep, views=n)
            except CalibrationError as exc:  # a result too: this many poses do not make a calibration
                why = str(exc).split(";")[0]
                rows.append({"sensor": label, "views": f"{n}: refused ({why})", "reproj": "", "field": "",
                             "seconds": f"{time.perf_counter() - t:.0f}", **{sh: None for _, _, sh in SCENES}})
                print(f"{label:9s} {n:3d} views: refused: {exc}", flush=True)
                continue
            seconds = time.perf_counter() - t
            s = cal.summary
            field = s["triangulation_error"]["all"]
            reproj = (s["camera0"]["reprojection_error_px"] + s["camera1"]["reprojection_error_px"]) / 2
            row = {"sensor": label, "views": f"{s['views']} of {n}", "reproj": f"{reproj:.3f}",
                   "field": f"{field['rms_mm'] * 1e3:.0f} / {field['max_mm'] * 1e3:.0f}", "seconds": f"{seconds:.0f}",
                   "field_rms": field["rms_mm"] * 1e3, "n": n}
            for name, frames, short in SCENES:
                row[short] = _scan_rms(cfgs[name], cal.fit.probe, frames)
            rows.append(row)
            print(f"{label:9s} {n:3d} views: reprojection {reproj:.3f} px, field {row['field']} um, "
                  + ", ".join(f"{sh} {row[sh]:.1f} um" for _, _, sh in SCENES) + f" ({seconds:.0f} s)", flush=True)
            if n == 20:
                for group, probe in _groups(truth, cal.fit, sensor is not None).items():
                    e = triangulation_error(truth, probe, true_dist)["all"]
                    sens.append((label, group, e["rms_mm"] * 1e3, e["max_mm"] * 1e3))
                if keep is not None:
                    pictures["calibration_views.png"] = keep / "calibration.png"
    body = _tables(rows, sens)
    print()
    print(body)
    if args.readme:
        from headless.bench import readme

        png = folder / "calibration_cost.png"
        _plot(rows, png)
        pictures["calibration_cost.png"] = png
        readme.update("calibration", body, pictures)
    return 0


def _tables(rows, sens) -> str:
    names = [s for _, _, s in SCENES]
    out = ["Scans with the true probe and with calibrated probes (python -m headless bench calibration; demo cell, "
           "default probe 160 × 160; the calibrations render their boards in the cell, the scans render with the "
           "true probe and triangulate with the calibration):", "",
           "| sensor | calibration | reprojection (px) | error field RMS / max (µm) | "
           + " | ".join(f"{n} RMS (µm)" for n in names) + " | calibration (s) |",
           "|---|---|---|---|" + "---|" * len(names) + "---|"]
    for r in rows:
        out.append(f"| {r['sensor']} | {r['views']} | {r['reproj'] or '–'} | {r['field'] or '–'} | "
                   + " | ".join("–" if r[n] is None else f"{r[n]:.1f}" for n in names) + f" | {r['seconds'] or '–'} |")
    if not sens:  # (that table is made from the 20-pose calibrations: none among --views)
        return "\n".join(out)
    out += ["", "Which parameter moves the points most (20 board poses; the true probe with one group of "
            "calibrated parameters swapped in; error field over the view, µm):", "",
            "| sensor | parameters from the calibration | RMS | max |", "|---|---|---|---|"]
    for label, group, rms, mx in sens:
        out.append(f"| {label} | {group} | {rms:.0f} | {mx:.0f} |")
    return "\n".join(out)


def _plot(rows, png) -> None:
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.6), dpi=110)
    for label, style in (("ideal", "o-"), ("realistic", "s--")):
        pts = [(r["n"], r["field_rms"]) for r in rows if r["sensor"] == label and "n" in r]
        if pts:
            ax.plot(*zip(*pts), style, label=f"{label} sensor")
    ax.set_xscale("log")
    ax.set_xticks([5, 10, 20, 40], ["5", "10", "20", "40"])
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.set_xlabel("board poses")
    ax.set_ylabel("error field RMS (µm)")
    ax.set_title("What calibration costs: error on the laser plane over the view")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(png)
    plt.close(fig)
