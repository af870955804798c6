"""The command line: demo, a small benchmark, and one-line errors for bad input."""

import argparse
import json
import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
# Commands that render need bpy; without it (a machine set up without Blender) they skip.
needs_bpy = pytest.mark.skipif(importlib.util.find_spec("bpy") is None,
                               reason="renders with bpy (installed by the README's set-up)")


def run_cli(*args, env=None):
    return subprocess.run([sys.executable, "-m", "headless", *args], cwd=REPO, capture_output=True, text=True,
                          env=None if env is None else {**os.environ, **env})


def bpy_own_ocio_config() -> str:
    """Blender's own colour configuration, for the OCIO variable an artist's machine may set
    (Blender then logs "color_management | Using OCIO=..." at start-up, to stdout)."""
    import bpy

    return str(Path(bpy.utils.resource_path("LOCAL")) / "datafiles" / "colormanagement" / "config.ocio")


def test_kinematics_prints_poses_and_solves_ik_for_every_robot():
    out = run_cli("kinematics")
    assert out.returncode == 0, out.stderr
    for name in ("Adept Viper s650", "Unimation PUMA 560", "Universal Robots UR5"):
        assert out.stdout.count(name) == 4  # three poses and one IK row
    assert out.stdout.count(" yes ") == 3 and " NO " not in out.stdout
    # The PUMA's zero pose as published for Corke's model (plus the 671.83 mm base height).
    assert "452.10    -150.05    1103.63" in out.stdout


@needs_bpy
def test_the_incidence_bench_bins_every_part_point_and_gives_the_floor_beside_it():
    out = run_cli("bench", "incidence", "--config", "tilted_plane", "--engine", "raycast")
    assert out.returncode == 0, out.stderr
    on_part = int(re.search(r"(\d+) points on the part", out.stdout).group(1))
    rows = [line.split("|")[1:-1] for line in out.stdout.splitlines() if re.match(r"\| \d+–\d+° \|", line)]
    assert rows and sum(int(r[1]) for r in rows) == on_part  # the bands share out every point on the part
    # A flat plate has no curvature for the line's width to act on: the floor stays within a few µm.
    assert all(abs(float(r[5])) < 3 and float(r[6]) < 3 for r in rows), rows


def test_small_kinematics_bench_reports_zero_false_successes():
    out = run_cli("bench", "kinematics", "--robots", "puma560", "--n", "60", "--near", "20",
                  "--unreachable", "20", "--fk-batch", "2000")
    assert out.returncode == 0, out.stderr
    rows = [line for line in out.stdout.splitlines() if line.startswith("Unimation PUMA 560")]
    assert len(rows) == 2 + 4 + 2  # speed, quality (random + near per method), unreachable
    unreachable_rows = rows[-2:]
    for row in unreachable_rows:
        assert row.split()[5] == "0", row  # false successes


def test_bad_rig_file_gives_one_line_error(tmp_path):
    bad = tmp_path / "broken.toml"
    bad.write_text("name = 'x'\n[[link]]\na_mm = 'long'\n")
    out = run_cli("bench", "kinematics", "--robots", str(bad), "--n", "10")
    assert out.returncode == 2
    assert "Traceback" not in out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and str(bad) in lines[0]


@pytest.mark.parametrize("command", [("scan", "demo"), ("bench", "parts"), ("adaptive", "demo")])
def test_an_unknown_option_points_to_the_commands_own_help(command):
    out = run_cli(*command, "--bogus")
    where = " ".join(c for c in command if c != "demo")
    assert out.returncode == 2 and out.stderr == (f"error: unrecognized arguments: --bogus "
                                                  f"(see: python -m headless {where} --help)\n")


@pytest.mark.parametrize("args, words", [
    (("calibration", "--views", "5", "--readme"), "--views runs part of it"),
    (("calibration", "--ideal-only", "--readme"), "--ideal-only runs part of it"),
    (("stability", "--only", "kinematics", "--readme"), "--only runs part of it"),
    (("parts", "--only", "nut", "--readme"), "--only runs part of it"),
    (("accuracy", "--scenes", "plate", "--readme"), "--scenes runs part of it"),
    (("realism", "--scenes", "demo", "--readme"), "--scenes runs part of it"),
    (("parts", "--only", "zzzz"), "no part's name holds it; the parts: "),
    (("calibration", "--views", "5", "1001"), "expected a whole number from 4 to 1000"),
    (("detect", "--cols", "3000"), "expected a whole number from 16 to 1600"),  # (the line left the image)
])
def test_a_bench_refuses_a_partial_docs_table_and_a_bad_selection_before_any_work(args, words):
    # (Each ran part of its table and then replaced the docs' whole table with it; --views
    # 1001 was refused after the work for the others.)
    out = run_cli("bench", *args)
    assert out.returncode == 2 and "Traceback" not in out.stderr and out.stdout == "", out.stderr[-500:]
    assert len(out.stderr.strip().splitlines()) == 1 and words in out.stderr, out.stderr


def test_unknown_robot_name_lists_alternatives():
    out = run_cli("bench", "kinematics", "--robots", "abb_irb120", "--n", "10")
    assert out.returncode == 2
    assert "adept_viper_s650" in out.stderr and "Traceback" not in out.stderr


def test_triangulate_bench_reports_the_paper_difference():
    out = run_cli("bench", "triangulate", "--probes", "default")
    assert out.returncode == 0, out.stderr
    assert "largest Δ|y|" in out.stdout and "all finite: True" in out.stdout
    pct = float(out.stdout.split("largest Δ|y|:")[1].split("(")[1].split("%")[0])
    assert 2.5 < pct < 2.9  # about 1/cos γ − 1 at the sensor's outer rows


def test_detect_bench_runs_small():
    out = run_cli("bench", "detect", "--images", "1", "--cols", "60", "--runs", "1")
    assert out.returncode == 0, out.stderr
    for method in ("threshold", "cog", "gauss", "steger"):
        assert f"{method}: line σ" in out.stdout
    assert "1280x1024" in out.stdout and "(median of 1 run)" in out.stdout


@needs_bpy
def test_overview_picture_is_written(tmp_path):
    import cv2

    out = run_cli("overview", "--out", str(tmp_path / "cell.png"), "--width", "360", "--height", "240",
                  "--samples", "4", "--workpiece", "step_block")
    assert out.returncode == 0, out.stderr[-2000:]
    img = cv2.imread(str(tmp_path / "cell.png"))
    assert img.shape == (240, 360 + 120, 3)  # the cell, and the two probe images stacked beside it
    right = img[:, 360:].astype(int)
    assert (right[..., 2] - right[..., 1]).max() > 100  # the red laser line shows in the probe images


@needs_bpy
def test_overview_scans_the_whole_path_without_frames(tmp_path):
    """Without --frames the operator was given None (its default since --frames is checked as
    it is read) and failed with a traceback: the whole path is scanned (a short raycast one)."""
    demo = (Path(REPO) / "rigs" / "scenes" / "demo.toml").read_text()
    short = demo.replace('engine = "cycles"', 'engine = "raycast"').replace("frames = 120", "frames = 4") \
        .replace("frames = 60", "frames = 2")
    (tmp_path / "short.toml").write_text(short)
    out = run_cli("overview", "--scan", str(tmp_path / "short.toml"), "--out", str(tmp_path / "cell.png"),
                  "--width", "120", "--height", "80", "--samples", "1")
    assert out.returncode == 0 and "Traceback" not in out.stderr, out.stderr[-2000:]
    report = json.loads(next((tmp_path / "cell-scan").rglob("report.json")).read_text())
    assert report["frames"] == 6


@needs_bpy
def test_overview_with_a_scan_keeps_the_scans_files_beside_the_picture(tmp_path):
    # (they went to a temporary folder, deleted at exit, that the operator's message named)
    (tmp_path / "taken-scan").write_text("x")
    out = run_cli("overview", "--scan", "demo", "--out", str(tmp_path / "taken.png"))
    assert out.returncode == 2 and "taken-scan is a file" in out.stderr and not (tmp_path / "taken.png").exists()
    out = run_cli("overview", "--scan", "demo", "--frames", "0:3", "--out", str(tmp_path / "cell.png"),
                  "--width", "64", "--height", "48", "--samples", "1", env={"OCIO": bpy_own_ocio_config()})
    assert out.returncode == 0, out.stderr[-2000:]
    kept = sorted(p.name for p in (tmp_path / "cell-scan").glob("*/*"))
    assert kept == ["cloud.ply", "preview.png", "report.json"] and (tmp_path / "cell.png").is_file()
    assert str(tmp_path / "cell-scan") in out.stdout
    # stdout: the operator's report and the picture's path, not Blender's own log (Cycles
    # logged "CUEW initialization failed" there where no CUDA is installed, and Blender's start-up
    # "Using OCIO=..." where that variable is set)
    lines = out.stdout.strip().splitlines()
    assert lines[-1] == "wrote " + str(tmp_path / "cell.png") and any(ln.startswith("Info: Scanned") for ln in lines)
    assert all(ln.startswith(("Info:", "Warning:")) for ln in lines[:-1]), lines


@needs_bpy
def test_overview_with_a_raycast_scan_shows_the_line_in_the_probes_panes(tmp_path):
    # (the panel put the robot back where it stood before the scan, which a raycast scan never
    # moved from: the panes were blank)
    import cv2

    demo = (Path(REPO) / "rigs" / "scenes" / "demo.toml").read_text()
    assert 'engine = "cycles"' in demo
    (tmp_path / "rc.toml").write_text(demo.replace('engine = "cycles"', 'engine = "raycast"'))
    out = run_cli("overview", "--scan", str(tmp_path / "rc.toml"), "--frames", "0:3", "--out",
                  str(tmp_path / "cell.png"), "--width", "240", "--height", "160", "--samples", "1")
    assert out.returncode == 0, out.stderr[-2000:]
    img = cv2.imread(str(tmp_path / "cell.png"))
    assert img.shape == (160, 240 + 80, 3)
    right = img[:, 240:].astype(int)
    assert (right[..., 2] - right[..., 1]).max() > 100  # the red laser line shows in the probe images


@needs_bpy
@pytest.mark.parametrize("args, said", [
    (("--samples", "128", "--width", "800", "--height", "600"), "interrupted (Ctrl-C) before the first picture"),
    (("--scan", "demo", "--frames", "0:180", "--samples", "4", "--width", "320", "--height", "240"),
     "interrupted (Ctrl-C) after "),
])
def test_overview_stopped_by_ctrl_c_writes_nothing_and_exits_130(tmp_path, args, said):
    """Its render is one long Cycles call, during which a Ctrl-C is only noted: it then wrote
    the picture and exited 0; stopped during --scan, the operator's report became a traceback
    and exit 2."""
    import signal
    import time

    proc = subprocess.Popen([sys.executable, "-m", "headless", "overview", "--out", str(tmp_path / "o.png"), *args],
                            cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        time.sleep(5.0)  # under way (or, on a slow start, still starting: stopped there the same)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=300)
    finally:
        proc.kill()
    assert proc.returncode == 130 and said in err and "Traceback" not in err, err[-2000:]
    assert not (tmp_path / "o.png").exists() and "wrote" not in out


@needs_bpy
def test_render_bench_runs_small():
    out = run_cli("bench", "render", "--frames", "3", "--repeats", "1")
    assert out.returncode == 0, out.stderr[-2000:]
    assert "one animation call, both cameras" in out.stdout and "frames/s" in out.stdout


@needs_bpy
def test_realism_bench_runs_small():
    out = run_cli("bench", "realism", "--scenes", "step_block", "--frames", "2", "--noise-frames", "2")
    assert out.returncode == 0, out.stderr[-2000:]
    for row in ("ideal", "pixel integration", "speckle", "motion blur", "all of the above", "line level"):
        assert row in out.stdout, row
    assert "Traceback" not in out.stderr


@needs_bpy
def test_realism_figure_shows_both_sensors(tmp_path):
    out = run_cli("realism-figure", "--frame", "3", "--out", str(tmp_path / "f.png"))
    assert out.returncode == 0, out.stderr[-2000:]
    assert "Ideal sensor" in out.stdout and "Realistic sensor" in out.stdout
    import cv2

    picture = cv2.imread(str(tmp_path / "f.png"))
    assert picture.shape[1] == 2 * 160 * 4 + 16  # two views side by side
    bad = run_cli("realism-figure", "--frame", "1000", "--out", str(tmp_path / "g.png"))
    assert bad.returncode == 2 and "--frame must be in" in bad.stderr and not (tmp_path / "g.png").exists()


@needs_bpy
def test_realism_figure_of_a_camera_that_sees_no_line_there_is_drawn_and_its_ideal_is_ideal(tmp_path):
    """A step block 250 mm wide: at frame 1 camera 0 sees no line, was not rendered (the scan
    leaves blind cameras out), and the figure failed with a traceback. And the 'ideal' panel of
    a config with its own realistic sensor (cylinder_realistic) showed that sensor: the same
    RMS on both sides."""
    config = tmp_path / "wide.toml"
    config.write_text((REPO / "rigs" / "scenes" / "step_block.toml").read_text().replace("width_mm = 50.0",
                                                                                          "width_mm = 250.0"))
    out = run_cli("realism-figure", "--config", str(config), "--frame", "1", "--camera", "0",
                  "--out", str(tmp_path / "f.png"))
    assert out.returncode == 0 and "Traceback" not in out.stderr, out.stderr[-2000:]
    assert (tmp_path / "f.png").exists()
    from addon.core.config.scan import load_scan_config
    from addon.core.optics.sensor import SensorModel
    from headless.bench.realism import ideal

    realistic = load_scan_config("cylinder_realistic")
    assert realistic.sensor != SensorModel() and realistic.material == "glossy" and realistic.render.bounces == 2
    base = ideal(realistic)
    assert base.sensor == SensorModel() and base.material == "grey" and base.render.ambient == 0.0
    assert base.render.bounces == 0 and base.detect.saturation == float("inf")
    demo = load_scan_config("demo")
    assert ideal(demo).sensor == demo.sensor and ideal(demo).render == demo.render  # the bench's scenes: as loaded


def test_bench_realism_readme_refuses_a_partial_run_of_fewer_frames():
    """--readme --frames 2 rewrote docs/realism.md with a two-frame table (nothing on the part
    in one row, against the text below it)."""
    out = run_cli("bench", "realism", "--readme", "--frames", "2")
    assert out.returncode == 2 and "--readme rewrites the docs' whole table and --frames runs part of it" in out.stderr


@needs_bpy
def test_demo_scan_runs_and_summarises(tmp_path):
    out = run_cli("demo", "--frames", "::15", "--out", str(tmp_path / "demo"), "--quiet")
    assert out.returncode == 0, out.stderr[-2000:]
    for word in ("points", "error", "coverage", "profiles/s", "cloud.ply", "report.json", "preview.png"):
        assert word in out.stdout
    assert {p.name for p in (tmp_path / "demo").iterdir()} == {"cloud.ply", "report.json", "preview.png"}
    # Blender's own per-frame log ("Fra: ...", "Saved: '...exr'") stays off the terminal.
    assert "Saved:" not in out.stdout and "Fra:" not in out.stdout
    assert len(out.stdout.strip().splitlines()) < 15, out.stdout


@needs_bpy
def test_progress_is_plain_lines_when_not_a_terminal(tmp_path):
    out = run_cli("demo", "--frames", "::6", "--out", str(tmp_path / "demo"))
    assert out.returncode == 0, out.stderr[-2000:]
    lines = [ln for ln in out.stderr.splitlines() if ln.startswith("scan: ")]
    assert 3 <= len(lines) <= 11 and "\r" not in out.stderr  # a line per 10 %, no redrawn bar
    assert lines[-1].startswith("scan: 30/30 frames") and "frames/s" in lines[-1] and "left" in lines[-1]


def test_progress_bar_redraws_one_line_on_a_terminal():
    import io

    from headless.scan import ProgressBar

    class Tty(io.StringIO):
        def isatty(self):
            return True

    stream = Tty()
    bar = ProgressBar(quiet=False, stream=stream)
    for done in range(0, 101, 10):
        bar("scan", done, 100)
    text = stream.getvalue()
    assert text.count("\r") == 11 and text.count("\n") == 1 and text.endswith("\n")
    assert "100/100 frames" in text and "left" in text and "frames/s" in text


def test_a_benchmark_stopped_between_its_scans_says_so(capsys):
    """It said "after 160 of 160 frames of the scan under way" where no scan was under way."""
    import argparse

    from headless.cli import _exit_code
    from headless.lifecycle import Interrupted, StopRequests

    def stopped(done, total):
        def run(args):
            raise Interrupted(2, done, total)
        return argparse.Namespace(run=run, bench="adaptive")

    assert _exit_code(stopped(160, 160), StopRequests()) == 130
    assert capsys.readouterr().err.strip() == "interrupted (Ctrl-C) between two of the benchmark's scans: nothing written"
    assert _exit_code(stopped(40, 160), StopRequests()) == 130
    assert capsys.readouterr().err.strip() == ("interrupted (Ctrl-C) after 40 of 160 frames of the scan under way: "
                                               "nothing written")


LATE_STOP = """
import os, signal, sys
from addon.core.geometry import cloud
own = cloud.CloudAccumulator.cloud


def stopped_while_put_together(self):  # every frame measured, the bar at 100 %: then Ctrl-C
    os.kill(os.getpid(), signal.SIGINT)
    return own(self)


cloud.CloudAccumulator.cloud = stopped_while_put_together
from headless.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_a_stop_after_the_last_frame_is_measured_waits_for_the_results(tmp_path):
    """A Ctrl-C just after the bar said 100 % threw the whole scan away ("interrupted after 3
    of 3 frames: nothing written") while the docs promise that once every frame is measured a
    stop waits for the results (a user hit it 2 times in 5)."""
    script = tmp_path / "late_stop.py"
    script.write_text(LATE_STOP)
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, str(script), "scan", "demo", "--engine", "raycast", "--frames", "0:3",
                           "--out", str(out)], cwd=REPO, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(REPO)})
    assert proc.returncode == 0, proc.stderr[-600:]
    assert "every frame is measured, so the results are written first" in proc.stderr
    assert sorted(p.name for p in out.iterdir()) == ["cloud.ply", "preview.png", "report.json"]
    assert json.loads((out / "report.json").read_text())["frames"] == 3


def test_a_log_shows_each_stage_of_a_two_stage_run():
    """calibrate renders its board images, then its laser images: in a log (not a terminal)
    the second stage never showed, its count starting where the first had reached 100 %."""
    import io

    from headless.scan import ProgressBar

    stream = io.StringIO()
    bar = ProgressBar(quiet=False, stream=stream)
    for stage in ("board images", "laser images"):
        for done in (2, 4):
            bar(stage, done, 4)
    lines = stream.getvalue().splitlines()
    assert [ln.split(":")[0] for ln in lines] == ["board images", "board images", "laser images", "laser images"]
    assert lines[-1].endswith("(100 %)") and "4/4 frames" in lines[-1]


def test_an_adaptive_bar_counts_profiles_against_the_budget_and_log_lines_do_not_run_into_it(capsys):
    import io

    from headless.lifecycle import Interrupted
    from headless.scan import ProgressBar

    class Tty(io.StringIO):
        def isatty(self):
            return True

    stream = Tty()
    bar = ProgressBar(quiet=False, stream=stream)
    bar("adaptive", 120, 10**5)
    bar.say("adaptive: sweep 1: a table turn")
    bar("adaptive", 240, 10**5)
    bar.finish()
    text = stream.getvalue()
    assert "240 profiles of a budget of 100000" in text and "left" not in text  # no years-long estimate
    # The bar is cleared before the log line and drawn again after it; finish() ends its line.
    assert text.count("\r\033[K") == 1 and text.endswith("\n") and text.count("\n") == 1
    assert capsys.readouterr().out == "adaptive: sweep 1: a table turn\n"
    assert Interrupted(2, 240, 600, "profiles").describe() == "interrupted (Ctrl-C) after 240 profiles of a budget of 600"
    # A farm stopped before its first shard came back (its count not yet known) names shards, not frames.
    assert Interrupted(2, 0, 0, "shards").describe() == "interrupted (Ctrl-C) before the first shard"


def test_a_second_ctrl_c_after_the_stop_is_through_still_exits_130():
    # The race a user can hit: the first Ctrl-C's stop has unwound the command and given the
    # signals back, and the second press lands before the process is gone. It must stay one
    # stop (exit 130), not die of Python's KeyboardInterrupt (exit -2).
    script = (
        "import os, signal, sys, time\n"
        "sys.modules.setdefault('bpy', object())  # a Blender process: the first signal only asks\n"
        "from headless.lifecycle import StopRequests\n"
        "stops = StopRequests(exiting=True).install()\n"
        "os.kill(os.getpid(), signal.SIGINT)\n"
        "time.sleep(0.2)\n"
        "stops.restore()\n"
        "os.kill(os.getpid(), signal.SIGINT)\n"
        "time.sleep(0.2)\n"
        "print('survived')\n"
    )
    out = subprocess.run([sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True)
    assert out.returncode == 130, (out.returncode, out.stderr)
    assert "survived" not in out.stdout and "Traceback" not in out.stderr


def test_a_stop_asked_for_after_the_last_frame_says_the_results_were_written(monkeypatch, capsys):
    # In a Blender process a Ctrl-C is recorded and acted on at the next frame; one that comes
    # when no frame is left finds the command finishing: exit 0, and a line saying so.
    import signal

    from headless import cli

    def finished(args):
        args.stops.signum = signal.SIGINT  # recorded while the results were being written
        return 0

    parser = cli.build_parser()
    monkeypatch.setattr(cli, "build_parser", lambda: parser)
    monkeypatch.setattr(parser, "parse_args", lambda argv: argparse.Namespace(run=finished))
    assert cli.main(["x"]) == 0
    assert "Ctrl-C came after the last frame" in capsys.readouterr().err


def test_a_signal_ignored_at_start_up_stays_ignored():
    # A script's background job (``scan ... &`` in a non-interactive shell) starts with SIGINT
    # ignored: a Ctrl-C meant for the script's foreground must not stop it.
    import signal

    script = (
        "import os, signal, time\n"
        "from headless.lifecycle import StopRequests\n"
        "stops = StopRequests(exiting=True).install()\n"
        "assert signal.getsignal(signal.SIGTERM) == stops._on_signal\n"
        "os.kill(os.getpid(), signal.SIGINT)\n"
        "time.sleep(0.2)\n"
        "stops.check()\n"
        "stops.restore()\n"
        "assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN\n"
        "print('survived')\n"
    )
    out = subprocess.run([sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    assert out.returncode == 0 and "survived" in out.stdout, (out.returncode, out.stderr)


def test_signals_are_given_back_when_no_stop_was_asked_for():
    import signal

    from headless.lifecycle import StopRequests

    before = signal.getsignal(signal.SIGINT)
    stops = StopRequests().install()
    assert signal.getsignal(signal.SIGINT) == stops._on_signal
    stops.restore()
    assert signal.getsignal(signal.SIGINT) is before


def test_main_called_in_process_gives_the_signals_back_even_after_a_stop(monkeypatch, capsys):
    # A caller that goes on after main() (a notebook, a test, a farm's own loop) must get its
    # Ctrl-C back; only ``python -m headless``, which exits right after, keeps the stop's.
    import signal

    from headless import cli

    def stopped(args):
        os.kill(os.getpid(), signal.SIGINT)
        args.stops.check()
        return 0

    before = signal.getsignal(signal.SIGINT)
    parser = cli.build_parser()
    monkeypatch.setattr(cli, "build_parser", lambda: parser)
    monkeypatch.setattr(parser, "parse_args", lambda argv: argparse.Namespace(run=stopped))
    try:
        assert cli.main(["x"]) == 130
        assert signal.getsignal(signal.SIGINT) is before
        assert "interrupted" in capsys.readouterr().err
    finally:  # whatever failed, pytest keeps its own Ctrl-C
        signal.signal(signal.SIGINT, before)


def test_python_m_headless_keeps_the_stop_against_a_second_ctrl_c_on_its_way_out():
    # ``python -m headless`` exits right after main(): a second Ctrl-C landing between main's
    # return and the exit must still end the process as one stop (130), not as a traceback.
    script = (
        "import argparse, os, runpy, signal, sys, time\n"
        "sys.modules.setdefault('bpy', type(sys)('bpy'))  # a Blender process: a signal is recorded\n"
        "from headless import cli\n"
        "parser = cli.build_parser()\n"
        "cli.build_parser = lambda: parser\n"
        "def stopped(args):\n"
        "    os.kill(os.getpid(), signal.SIGINT)\n"
        "    time.sleep(0.1)\n"
        "    args.stops.check()\n"
        "parser.parse_args = lambda argv=None: argparse.Namespace(run=stopped)\n"
        "real_exit = sys.exit\n"
        "def late_second_press(code=0):\n"
        "    os.kill(os.getpid(), signal.SIGINT)\n"
        "    time.sleep(0.2)\n"
        "    print('survived', flush=True)\n"
        "    real_exit(code)\n"
        "sys.exit = late_second_press\n"
        "runpy.run_module('headless', run_name='__main__')\n"
    )
    out = subprocess.run([sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True, timeout=60)
    assert out.returncode == 130, (out.returncode, out.stderr[-500:])
    assert "Traceback" not in out.stderr


def test_ctrl_c_while_the_command_starts_stops_it_before_the_first_frame(tmp_path):
    # Ctrl-C during the imports used to be swallowed (trimesh imports its optional parts under
    # a catch-all except) and the scan ran to the end with exit 0. The signal is sent here at
    # the start of building the parser, before those imports, deterministically.
    out = tmp_path / "out"
    script = (
        "import os, signal, sys\n"
        "import headless.cli as cli\n"
        "build = cli.build_parser\n"
        "def early():\n"
        "    os.kill(os.getpid(), signal.SIGINT)\n"
        "    return build()\n"
        "cli.build_parser = early\n"
        f"sys.exit(cli.main(['scan', 'demo', '--engine', 'raycast', '--quiet', '--out', {str(out)!r}]))\n"
    )
    run = subprocess.run([sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert run.returncode == 130, (run.returncode, run.stderr[-2000:])
    assert run.stderr.strip().splitlines()[-1] == "interrupted (Ctrl-C) before the first frame", run.stderr
    assert not out.exists() and "Traceback" not in run.stderr


def test_a_reader_that_closes_the_pipe_is_no_scan_failure(tmp_path):
    # ``... | head -1``: the summary's print fails once the scan's files are written. It used to
    # say "error: Broken pipe (nothing was written)" beside the written files.
    out = tmp_path / "out"
    import os

    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}  # stdout block-buffered, as in a shell
    proc = subprocess.Popen([sys.executable, "-m", "headless", "scan", "demo", "--engine", "raycast", "--quiet",
                             "--out", str(out)], cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env)
    assert proc.stdout.readline().startswith("scan: ")
    proc.stdout.close()
    stderr = proc.stderr.read()
    assert proc.wait(timeout=300) == 141, stderr
    assert stderr.strip().splitlines()[-1] == "stopped: the program reading the output closed it (broken pipe)"
    assert "Traceback" not in stderr and "nothing was written" not in stderr
    assert sorted(p.name for p in out.iterdir()) == ["cloud.ply", "preview.png", "report.json"]


@pytest.mark.parametrize("closed", ["stdout", "stderr"])
def test_a_scan_started_with_stdout_or_stderr_closed_writes_its_results_and_exits_0(tmp_path, closed):
    """`... >&-` or `2>&-` (a daemon's start): Python has None for the closed stream; the scan
    wrote its files and ended on an AttributeError's traceback, exit 1 (with stderr closed it
    wrote nothing)."""
    out = tmp_path / "out"
    kw = {"stdout": subprocess.DEVNULL if closed == "stderr" else None,
          "stderr": subprocess.PIPE if closed == "stdout" else None}
    import os

    fd = 1 if closed == "stdout" else 2
    proc = subprocess.run([sys.executable, "-m", "headless", "scan", "demo", "--engine", "raycast", "--frames", "0:4",
                           "--out", str(out)], cwd=REPO, text=True, timeout=300, preexec_fn=lambda: os.close(fd), **kw)
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in out.iterdir()) == ["cloud.ply", "preview.png", "report.json"]


def test_adaptive_takes_the_engine_as_scan_does(tmp_path):
    out = run_cli("adaptive", "demo", "--engine", "raycast", "--max-profiles", "200", "--quiet",
                  "--out", str(tmp_path / "out"))
    assert out.returncode == 0, out.stderr
    import json

    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["render_device"] == "CPU (Embree ray casting)" and 0 < report["frames"] <= 200


def test_the_default_output_folder_names_an_engine_the_command_line_changed():
    from addon.core.config.scan import load_scan_config
    from headless.scan import default_out

    demo = load_scan_config("demo")
    assert default_out(demo) == default_out(demo, demo.render.engine) == str(Path("out") / "demo")
    assert default_out(demo, "raycast") == str(Path("out") / "demo-raycast")
    assert default_out(demo, "raycast", "adaptive") == str(Path("out") / "demo-adaptive-raycast")


@needs_bpy
def test_a_scan_of_part_of_the_path_says_which_frames_and_sensor_and_its_report_is_the_same_file_twice(tmp_path):
    """--frames: report.json gives the path's frame number of each frame scanned; --resolution:
    the probe's name says the sensor used; two equal runs write byte-equal report.json files
    but for the times taken."""
    import json

    from addon.core.geometry.cloud import load_ply

    reports = []
    for k in range(2):
        out = run_cli("scan", "demo", "--engine", "raycast", "--frames", "150:154", "--resolution", "320x240",
                      "--quiet", "--out", str(tmp_path / f"out{k}"))
        assert out.returncode == 0, out.stderr
        assert "320x240" in out.stdout and "160x160" not in out.stdout
        reports.append(json.loads((tmp_path / f"out{k}" / "report.json").read_text()))
    r = reports[0]
    assert r["config"]["path_frames"] == [150, 151, 152, 153] and r["config"]["sensor_px"] == [320, 240]
    assert "320x240" in r["config"]["probe"]
    assert sorted(load_ply(tmp_path / "out0" / "cloud.ply").frame.tolist())[-1] <= 3  # numbered 0.. as picked
    for a, b in zip(*reports):
        assert a == b  # the same keys in the same order
    assert [list(x["points_dropped"]) for x in reports] == [sorted(r["points_dropped"])] * 2
    timed = ("time_s", "profiles_per_s")
    texts = [json.dumps({k: v for k, v in x.items() if k not in timed}) for x in reports]
    assert texts[0] == texts[1]  # as docs/scans.md says: only the times differ
    from addon.core.config.scan import load_scan_config

    whole = load_scan_config("demo")
    assert whole.path_frames is None  # null in the report: the whole path, numbered as written
    picked = whole.with_overrides(frames=slice(150, 160, 2)).with_overrides(frames=slice(1, 3))
    assert picked.path_frames.tolist() == [152, 154]  # a pick of a pick keeps the path's numbers
    # ":" or "0:180" picks the whole path: scanned and reported as without --frames (its
    # frames were listed, and the whole path's coverage warning was lost).
    for every in (slice(None), slice(0, 180), slice(0, None, 1)):
        assert whole.with_overrides(frames=every).path_frames is None
    assert whole.with_overrides(frames=slice(0, 179)).path_frames.tolist() == list(range(179))


def test_the_default_output_folder_keeps_another_config_files_results(tmp_path, monkeypatch):
    """a/scan.toml and b/scan.toml share the default folder out/scan: b's scan is refused there
    (naming a's file and --out) rather than overwriting a's results; a's own runs go on."""
    import json

    from addon.core.config.scan import load_scan_config
    from addon.core.errors import InputError
    from headless.scan import default_out

    demo = (REPO / "rigs" / "scenes" / "demo.toml").read_text()
    for d in ("a", "b"):
        (tmp_path / d).mkdir()
        (tmp_path / d / "scan.toml").write_text(demo)
    monkeypatch.chdir(tmp_path)
    a, b = load_scan_config("a/scan.toml"), load_scan_config("b/scan.toml")
    assert default_out(b) == str(Path("out") / "scan")  # nothing there yet
    (tmp_path / "out" / "scan").mkdir(parents=True)
    (tmp_path / "out" / "scan" / "report.json").write_text(json.dumps({"config": {"file": a.source}}))
    assert default_out(a) == str(Path("out") / "scan")
    with pytest.raises(InputError, match="holds the results of .*a/scan.toml; give --out"):
        default_out(b)


@needs_bpy
def test_gym_baselines_prints_each_policys_curve_and_the_random_ones_over_seeds():
    out = run_cli("gym-baselines", "--config", "demo", "--engine", "raycast", "--max-profiles", "150", "--seeds", "2")
    assert out.returncode == 0, out.stderr[-2000:]
    lines = out.stdout.strip().splitlines()
    assert "seeds 0-1" in lines[0]
    planner, rnd, allowed = lines[1:4]
    assert planner.split()[:2] == ["reference", "planner"] and "profiles" in planner
    for line in (rnd, allowed):
        finals = [float(v) for v in line.split("final coverage ")[1].split(" %")[0].split(", ")]
        median = float(line.split("median ")[1].split(" %")[0])
        assert len(finals) == 2 and abs(median - sum(finals) / 2) < 0.051


@needs_bpy
def test_gym_baselines_refuses_a_negative_seed_in_one_line():
    out = run_cli("gym-baselines", "--engine", "raycast", "--seed", "-1", "--max-profiles", "75")
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert out.stderr.strip().splitlines()[-1] == "error: --seed must be a whole number in [0, 9223372036854775807], got -1"
    out = run_cli("gym-baselines", "--engine", "raycast", "--max-profiles", "-5")
    assert out.returncode == 2 and out.stderr.strip().splitlines()[-1].startswith("error: --max-profiles must be")
    out = run_cli("gym-baselines", "--engine", "raycast", "--max-profiles", "10")  # below the smallest view
    assert out.returncode == 2 and "smallest view" in out.stderr and out.stdout == ""
    assert "error: --max-profiles 10 is below" in out.stderr  # the option's name, not the constructor's


@needs_bpy
def test_an_adaptive_budget_below_every_view_names_the_smallest_and_that_budget_scans(tmp_path):
    out = run_cli("adaptive", "demo", "--engine", "raycast", "--max-profiles", "40", "--quiet",
                  "--out", str(tmp_path / "small"))
    assert out.returncode == 2 and not (tmp_path / "small").exists()
    (line,) = [ln for ln in out.stderr.splitlines() if ln.startswith("error:")]
    smallest = int(line.split("at least ")[1].split(")")[0])
    assert smallest > 40
    out = run_cli("adaptive", "demo", "--engine", "raycast", "--max-profiles", str(smallest), "--quiet",
                  "--out", str(tmp_path / "enough"))
    assert out.returncode == 0, out.stderr[-2000:]
    assert "1 view," in out.stdout  # one view, said so
    import json

    assert 0 < json.loads((tmp_path / "enough" / "report.json").read_text())["frames"] <= smallest


def test_a_stop_once_every_frame_is_measured_waits_for_the_results_and_one_after_the_command_keeps_its_code():
    """A process without Blender (a scan by ray casting), which a signal would interrupt at once:
    after finish() a Ctrl-C is recorded and the results are still written; once the command
    has returned (restore with its code) a signal ends the process with that code, quietly."""
    script = (
        "import io, os, signal, sys, time\n"
        "from headless.lifecycle import Interrupted, StopRequests\n"
        "early = StopRequests(stream=io.StringIO())\n"
        "early.signum = signal.SIGINT\n"
        "try:\n"
        "    early.finish()\n"
        "    print('finish let an earlier stop through')\n"
        "except Interrupted:\n"
        "    pass\n"
        "stops = StopRequests(exiting=True).install()\n"
        "stops.finish()\n"
        "os.kill(os.getpid(), signal.SIGINT)\n"
        "time.sleep(0.2)\n"
        "stops.check()\n"
        "print('written', stops.signum == signal.SIGINT, flush=True)\n"
        "stops.restore(0)\n"
        "os.kill(os.getpid(), signal.SIGINT)\n"
        "time.sleep(0.5)\n"
        "print('survived the teardown signal')\n"
    )
    out = subprocess.run([sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True)
    assert out.returncode == 0, (out.returncode, out.stderr)
    assert out.stdout.splitlines() == ["written True"], out.stdout
    assert "results are written first" in out.stderr and "Traceback" not in out.stderr


def test_a_stop_during_an_import_is_recorded_not_raised_there(tmp_path, monkeypatch):
    """An exception raised inside an import can leave an extension module half made (a QA
    trial's Ctrl-C while Blender's bpy loaded crashed the process on its way out): the handler
    sees the import on the stack, records the stop, and the next check raises it."""
    import io
    import signal

    from headless.lifecycle import Interrupted, StopRequests

    monkeypatch.delitem(sys.modules, "bpy", raising=False)  # a process without Blender: a stop raises at once
    stops = StopRequests(stream=io.StringIO())
    (tmp_path / "slow_module.py").write_text(
        "import sys\n"
        "STOPS._on_signal(__import__('signal').SIGINT, sys._getframe())\n"
        "LOADED = True\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import builtins

    monkeypatch.setattr(builtins, "STOPS", stops, raising=False)
    try:
        import slow_module  # noqa: F401
    except Interrupted:
        pytest.fail("the stop was raised inside the import")

    assert slow_module.LOADED and stops.signum == signal.SIGINT
    with pytest.raises(Interrupted):
        stops.check()
    outside = StopRequests(stream=io.StringIO())
    with pytest.raises(Interrupted):  # outside an import it does
        outside._on_signal(signal.SIGINT, sys._getframe())


def test_a_scan_hears_a_late_stop_before_it_measures_and_measures_once(tmp_path, monkeypatch):
    # Once the last frame is measured a stop waits for the results: finish() must come before
    # the cloud is measured against the truth (which took 15 s on a 1 M-face part), and that
    # measuring must happen once, for the summary and the files alike.
    import addon.pipeline
    from headless import cli, lifecycle

    order = []
    finish, assemble = lifecycle.StopRequests.finish, addon.pipeline.assemble
    monkeypatch.setattr(lifecycle.StopRequests, "finish", lambda self: order.append("finish") or finish(self))
    monkeypatch.setattr(addon.pipeline, "assemble", lambda *a, **k: order.append("measure") or assemble(*a, **k))
    code = cli.main(["scan", "demo", "--engine", "raycast", "--frames", "0:3", "--out", str(tmp_path / "o"),
                     "--quiet"])
    assert code == 0 and order == ["finish", "measure"]
    assert json.loads((tmp_path / "o" / "report.json").read_text())["frames"] == 3


def test_frames_counted_from_the_paths_end_are_taken_as_the_options_value():
    from headless import cli

    for value in ("-5:", "-10:-2", "-20::2"):
        assert cli.build_parser().parse_args(["scan", "demo", "--frames", value]).frames == value


def test_a_signal_while_an_error_is_told_ends_with_the_errors_code_and_line():
    """SIGTERM landing while the error line is printed (before Blender is loaded, where the
    first signal raises at once) is only noted: exit 2 and the error's one line, no traceback."""
    script = """
import argparse, os, signal, sys
from addon.core.errors import ScannerError
from headless.cli import _exit_code
from headless.lifecycle import StopRequests

class Loud:
    def __str__(self):
        os.kill(os.getpid(), signal.SIGTERM)
        return "the part is not readable"

def run(args):
    raise ScannerError(Loud())

stops = StopRequests(exiting=False).install()
print("code", _exit_code(argparse.Namespace(run=run), stops), "bpy" in sys.modules)
"""
    out = subprocess.run([sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["code", "2", "False"]
    assert out.stderr.strip().splitlines() == ["error: the part is not readable"]


def test_a_failed_write_says_no_results_were_written_and_which_shards_stay(tmp_path, capsys):
    """A disk that fills up mid-write: the results (all together or none) are not there; a
    farm's finished shards are kept for the next run, and the line says so."""
    import argparse
    import errno

    from headless.cli import _exit_code
    from headless.lifecycle import StopRequests

    (tmp_path / "shards").mkdir()
    for k in range(2):
        (tmp_path / "shards" / f"shard_{10 * k:06d}_{10 * k + 9:06d}.npz").write_bytes(b"x")
    (tmp_path / "shards" / "shard_000020_000029.npz").mkdir()  # a folder of that name is no shard (counted before)

    def full(args):
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "cloud.ply"))

    code = _exit_code(argparse.Namespace(run=full, out=str(tmp_path)), StopRequests(exiting=False))
    line = capsys.readouterr().err.strip()
    assert code == 2
    assert line == (f"error: {tmp_path / 'cloud.ply'}: No space left on device (no results written; 2 shard "
                    f"files kept in {tmp_path / 'shards'}, which the next run reuses where valid)")
    code = _exit_code(argparse.Namespace(run=full, out=str(tmp_path / "elsewhere")), StopRequests(exiting=False))
    assert capsys.readouterr().err.strip().endswith("No space left on device (no results written)")



def test_bench_incidence_refuses_an_open_part_before_scanning(tmp_path):
    """A signed error needs a closed part: an open sheet was refused only after the scan."""
    import time

    import trimesh

    sheet = trimesh.Trimesh([[-40, -40, 10], [40, -40, 10], [40, 40, 10], [-40, 40, 10]], [[0, 1, 2], [0, 2, 3]])
    sheet.export(tmp_path / "sheet.stl")
    text = (REPO / "rigs" / "scenes" / "tilted_plane.toml").read_text()
    start, end = text.index("[workpiece]"), text.index("[[path]]")
    (tmp_path / "sheet.toml").write_text(text[:start] + '[workpiece]\nfile = "sheet.stl"\n\n' + text[end:])
    t = time.perf_counter()
    out = run_cli("bench", "incidence", "--config", str(tmp_path / "sheet.toml"), "--engine", "raycast")
    assert out.returncode == 2 and "is not a closed mesh: a signed error" in out.stderr, out.stderr[-500:]
    assert "Traceback" not in out.stderr and time.perf_counter() - t < 60


@pytest.mark.parametrize("args, words", [
    (("overview", "--width", "0"), "--width: expected a whole number from 16 to 8192"),
    (("overview", "--frames", "0:3"), "--frames picks part of --scan's path"),
    (("overview", "--scan", "demo", "--robot", "puma560", "--workpiece", "step_block"),
     "--robot and --workpiece set the cell drawn without --scan"),
    (("overview", "--scan", "tilted_plane", "--frames", "abc"), "--frames: 'abc': expected A:B"),
    # An empty --frames (an unset shell variable) scanned the whole path without a word.
    (("overview", "--scan", "demo", "--frames", ""), "--frames: an empty part of the path"),
    (("scan", "demo", "--frames", " "), "--frames: an empty part of the path"),
    (("demo", "--frames", ""), "--frames: an empty part of the path"),
    (("bench", "versions", "--frames", ""), "--frames: an empty part of the path"),
    (("scan", "demo", "--frames", "0:9:0"), "--frames: '0:9:0': the step must be a whole number of at least 1"),
    # A bundled scene's file name, as if it lay here: said "no such file" and nothing more.
    (("scan", "demo.toml"), "demo.toml: no such file; the bundled scene 'demo' is named without .toml or a folder"),
    (("overview", "--out", "{tmp}"), "is a folder; give the name of the file to write"),
    (("overview", "--out", "{tmp}/newfolder/"), "is a folder; give the name of the file to write"),
    (("overview", "--out", "{tmp}/afile/x.png"), "afile is a file"),
    (("overview", "--out", "{tmp}/fifo"), "is a pipe (FIFO), not a file"),  # (replaced by the picture)
    (("realism-figure", "--frame", "1", "--out", "{tmp}"), "is a folder; give the name of the file to write"),
    (("build-extension", "--pythons", "foo"), "expected a CPython version as X.Y"),
    (("build-extension", "--out", ""), "an empty name is no folder"),
    (("build-extension", "--blender-ext", "{tmp}/nope.py"), "nope.py: no such file"),
    (("build-extension", "--out", "{tmp}/afile"), "is a file"),
])
def test_commands_refuse_bad_options_and_outputs_before_any_work(tmp_path, args, words):
    # (--width 0 divided by zero; --frames abc was the panel operator's traceback; an --out
    # folder was found after the renders, and named a hidden temporary file)
    (tmp_path / "afile").write_text("x")
    os.mkfifo(tmp_path / "fifo")
    out = run_cli(*(a.replace("{tmp}", str(tmp_path)) for a in args))
    assert out.returncode == 2 and "Traceback" not in out.stderr and out.stdout == "", (out.stdout, out.stderr[-800:])
    assert len(out.stderr.strip().splitlines()) == 1 and words in out.stderr, out.stderr


def test_the_ik_server_stopped_by_sigterm_exits_143():
    import signal
    import time

    proc = subprocess.Popen([sys.executable, "-m", "headless", "ik-server", "--port", "0"], cwd=REPO,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert "Ctrl-C stops it" in proc.stdout.readline()
        time.sleep(0.2)
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=30) == 128 + signal.SIGTERM  # it said 130, as for Ctrl-C
    finally:
        proc.kill()


def test_a_long_path_says_it_is_planned_first(tmp_path, monkeypatch, capsys):
    """A path of a million frames was planned for over five minutes before the first progress
    line, with nothing said. A long path now says so (the threshold lowered here to 3 frames)."""
    import headless.scan
    from headless import cli

    code = cli.main(["scan", "demo", "--engine", "raycast", "--frames", "0:3", "--out", str(tmp_path / "a"),
                     "--quiet"])
    assert code == 0 and "planning the path first" not in capsys.readouterr().out
    monkeypatch.setattr(headless.scan, "LONG_PLAN_FRAMES", 3)
    code = cli.main(["scan", "demo", "--engine", "raycast", "--frames", "0:3", "--out", str(tmp_path / "b"),
                     "--quiet"])
    assert code == 0
    assert "scan: planning the path first: inverse kinematics, reach and collision checks for each of its 3 " \
           "frames" in capsys.readouterr().out
