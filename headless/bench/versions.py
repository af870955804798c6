"""The demo scan under several Blender releases, side by side in one run.

Each interpreter given (a Python with bpy of some release and the project's
packages) runs ``python -m headless demo`` in turn, round after round, so that
the machine's load falls on all of them alike; the table gives each release's
median profiles/s and render time and the ratio to the first. The clouds are
compared too: point counts and RMS must agree where the releases render alike.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from headless.bench import whole
from headless.preflight import frames_argument

REPO = Path(__file__).resolve().parents[2]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("pythons", nargs="*", metavar="PYTHON",
                        help="interpreters to compare (default: this one); each needs bpy and the project's packages")
    parser.add_argument("--rounds", type=whole(), default=5, help="demo runs per interpreter; medians count (default 5)")
    parser.add_argument("--frames", type=frames_argument, help="part of the demo path, as A:B:STEP (default: all 180)")
    parser.set_defaults(run=run)


def _one(python: str, out: Path, frames: str | None) -> dict:
    cmd = [python, "-m", "headless", "demo", "--quiet", "--out", str(out)] + (["--frames", frames] if frames else [])
    res = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
    if res.returncode != 0:
        raise SystemExit(f"error: the demo failed under {python}: {res.stderr.strip().splitlines()[-1:]}")
    return json.loads((out / "report.json").read_text())


def run(args: argparse.Namespace) -> int:
    from addon.core.config.scan import load_scan_config, parse_frames

    pythons = args.pythons or [sys.executable]
    load_scan_config("demo").with_overrides(frames=parse_frames(args.frames, "--frames"))  # refused here, in one line
    names = []
    for py in pythons:
        res = subprocess.run([py, "-c", "import bpy, sys; print(bpy.app.version_string, '|', sys.version.split()[0])"],
                             capture_output=True, text=True)
        if res.returncode != 0:
            raise SystemExit(f"error: {py} cannot import bpy")
        names.append(res.stdout.strip().splitlines()[-1])
    runs: dict[int, list[dict]] = {i: [] for i in range(len(pythons))}
    with tempfile.TemporaryDirectory(prefix="scanner-versions-") as tmp:
        for r in range(args.rounds):
            for i, py in enumerate(pythons):
                runs[i].append(_one(py, Path(tmp) / f"{i}-{r}", args.frames))
                print(f"round {r + 1}/{args.rounds}: {names[i]}: {runs[i][-1]['profiles_per_s']:.1f} profiles/s",
                      file=sys.stderr, flush=True)
    print(f"Demo scan, medians of {args.rounds} rounds, interleaved (python -m headless bench versions)\n")
    print("| Blender | CPython | profiles/s | render s | ratio | points | RMS on the part |")
    print("|---|---|---|---|---|---|---|")
    base = None
    for i in range(len(pythons)):
        pps = statistics.median(rep["profiles_per_s"] for rep in runs[i])
        render = statistics.median(rep["time_s"]["render"] for rep in runs[i])
        base = base or pps
        blender, python = (s.strip() for s in names[i].split("|"))
        last = runs[i][-1]
        print(f"| {blender} | {python} | {pps:.1f} | {render:.2f} | {pps / base:.2f} | {last['points']} | "
              f"{last['error_um']['rms_um']:.1f} µm |")
    return 0
