"""The catalogue of bad inputs and faults: every case gives one clear line, the right exit
code and nothing in ``--out`` (issue: reliability).

Most cases call the command line in this process (``headless.cli.main``): they are all
refused before the first render, so they take milliseconds. Signals, file-size limits and
stale temporary folders need a process of their own. A case is (name, how to make the
command line, exit code, words the one line must hold).
"""

from __future__ import annotations

import os
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path
import json

import numpy as np
import pytest

from addon.core.geometry.cloud import load_ply
from headless.cli import main

REPO = Path(__file__).resolve().parents[2]
DEMO = (REPO / "rigs" / "scenes" / "demo.toml").read_text()
PROBE = (REPO / "rigs" / "probes" / "default.toml").read_text()
ROBOT = (REPO / "rigs" / "robots" / "ur5.toml").read_text()


# -- making bad files ---------------------------------------------------------------------
def _a_file(tmp: Path) -> Path:
    path = tmp / "afile"
    path.write_text("")
    return path


def scene(tmp: Path, text: str, name: str = "scene.toml") -> str:
    path = tmp / name
    path.write_text(text)
    return str(path)


def demo_with(old: str, new: str):
    """The demo config with one piece of text replaced (the piece must be there)."""
    def make(tmp: Path):
        assert old in DEMO, old
        return ["scan", scene(tmp, DEMO.replace(old, new, 1))]
    return make


def demo_plus(extra: str):
    return lambda tmp: ["scan", scene(tmp, DEMO + "\n" + extra + "\n")]


def probe_with(old: str, new: str):
    def make(tmp: Path):
        assert old in PROBE, old
        (tmp / "probe.toml").write_text(PROBE.replace(old, new, 1))
        return ["scan", scene(tmp, DEMO.replace('rig = "default"', f'rig = "{tmp / "probe.toml"}"'))]
    return make


def calibrated_on_another_sensor(tmp: Path):
    from dataclasses import replace

    from addon.core.config.rigs import load_probe, probe_toml
    from addon.core.optics.calibrated import ProbeCalibration

    hires = load_probe("hires")
    (tmp / "cal.toml").write_text(probe_toml(replace(hires, calibration=ProbeCalibration.of(hires))))
    return ["scan", scene(tmp, DEMO.replace('rig = "default"', 'rig = "default"\ncalibration = "cal.toml"', 1))]


def calibrated_on_another_probe(tmp: Path):
    """A calibration made on a probe of the same sensor but another geometry (a = 75 mm)."""
    from dataclasses import replace

    from addon.core.config.rigs import load_probe, probe_toml
    from addon.core.optics.calibrated import ProbeCalibration

    other = replace(load_probe("default"), a_mm=75.0)
    (tmp / "cal.toml").write_text(probe_toml(replace(other, calibration=ProbeCalibration.of(other))))
    return ["scan", scene(tmp, DEMO.replace('rig = "default"', 'rig = "default"\ncalibration = "cal.toml"', 1))]


def calibrated_rig_mounted_otherwise(tmp: Path):
    """A probe rig that carries its own calibration, mounted 20 mm farther out by the config's
    [probe.mount] (loaded before, where calibration = FILE refuses the same)."""
    from dataclasses import replace

    from addon.core.config.rigs import load_probe, probe_toml
    from addon.core.optics.calibrated import ProbeCalibration

    probe = load_probe("default")
    (tmp / "cal.toml").write_text(probe_toml(replace(probe, calibration=ProbeCalibration.of(probe))))
    z = float(probe.mount[2, 3]) + 20.0
    return ["scan", scene(tmp, DEMO.replace('rig = "default"', f'rig = "cal.toml"\n[probe.mount]\nxyz_mm = [0, 0, {z}]',
                                            1))]


def robot_with(old: str, new: str, count: int = 1):
    def make(tmp: Path):
        assert old in ROBOT, old
        (tmp / "robot.toml").write_text(ROBOT.replace(old, new, count))
        return ["scan", scene(tmp, DEMO.replace('rig = "adept_viper_s650"', f'rig = "{tmp / "robot.toml"}"'))]
    return make


def cube_mm(size: float = 40.0):
    import trimesh

    m = trimesh.creation.box((size, size, size))
    m.apply_translation((0, 0, size / 2))
    return m


def part_file(write):
    """A scan of the demo with its workpiece read from a file that ``write(tmp)`` makes."""
    def make(tmp: Path):
        path = write(tmp)
        text = DEMO.replace('shape = "sphere"\nradius_mm = 30.0', f'file = "{path}"')
        return ["scan", scene(tmp, text)]
    return make


def ascii_stl_with_nan(tmp):
    text = cube_mm().export(file_type="stl_ascii")
    lines = text.splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.strip().startswith("vertex"))
    lines[i] = "      vertex nan 0 0"
    (tmp / "nan.stl").write_text("\n".join(lines))
    return tmp / "nan.stl"


def binary_stl_with_nan(tmp):
    data = bytearray(cube_mm().export(file_type="stl"))
    for t in range(0, 12, 7):  # every 7th triangle gets a NaN vertex coordinate
        struct.pack_into("<f", data, 84 + 50 * t + 12, float("nan"))
    (tmp / "nan_bin.stl").write_bytes(bytes(data))
    return tmp / "nan_bin.stl"


def binary_stl_with_inf(tmp):
    data = bytearray(cube_mm().export(file_type="stl"))
    struct.pack_into("<f", data, 84 + 12, float("inf"))
    (tmp / "inf.stl").write_bytes(bytes(data))
    return tmp / "inf.stl"


def good_cube_stl(tmp):
    cube_mm().export(tmp / "cube.stl")
    return tmp / "cube.stl"


def obj_with_nan(tmp):
    text = cube_mm().export(file_type="obj").replace("v ", "v nan ", 1)
    (tmp / "nan.obj").write_text(text)
    return tmp / "nan.obj"


def ply_with_nan(tmp):
    m = cube_mm()
    m.vertices[3] = [np.nan, 0, 0]
    (tmp / "nan.ply").write_bytes(m.export(file_type="ply"))
    return tmp / "nan.ply"


def glb_with_nan(tmp):
    m = cube_mm()
    m.vertices[2] = [0, np.inf, 0]
    (tmp / "inf.glb").write_bytes(m.export(file_type="glb"))
    return tmp / "inf.glb"


def truncated_stl(tmp):
    data = cube_mm().export(file_type="stl")
    (tmp / "cut.stl").write_bytes(data[: len(data) // 2 + 7])
    return tmp / "cut.stl"


def png_named_stl(tmp):
    import cv2

    ok, png = cv2.imencode(".png", np.zeros((8, 8, 3), np.uint8))
    (tmp / "picture.stl").write_bytes(png.tobytes())
    return tmp / "picture.stl"


def empty_stl(tmp):
    (tmp / "empty.stl").write_bytes(b"")
    return tmp / "empty.stl"


def text_named_obj(tmp):
    (tmp / "notes.obj").write_text("this is not a mesh\njust words\n")
    return tmp / "notes.obj"


def part_in_metres(tmp):
    (tmp / "metres.stl").write_bytes(cube_mm(0.04).export(file_type="stl"))
    return tmp / "metres.stl"


def part_in_micrometres(tmp):
    (tmp / "microns.stl").write_bytes(cube_mm(40000.0).export(file_type="stl"))
    return tmp / "microns.stl"


def folder_as_mesh(tmp):
    (tmp / "folder.stl").mkdir()
    return tmp / "folder.stl"


def unknown_mesh_type(tmp):
    (tmp / "part.xyz123").write_text("1 2 3\n")
    return tmp / "part.xyz123"


def sparse_huge_stl(tmp):
    path = tmp / "huge.stl"
    with open(path, "wb") as fh:
        fh.write(b"\0" * 80 + struct.pack("<I", 40_000_000))
        fh.truncate(2 * 1024 ** 3)  # 2 GB, sparse: mostly zero triangles
    return path


def rig_mesh_is_text(tmp):
    (tmp / "link.txt").write_text("not a mesh")
    return robot_with("[[link]]  # J1\n", f'[[link]]  # J1\nmesh = "{tmp / "link.txt"}"\n')(tmp)


# -- options, output folders ----------------------------------------------------------------
def demo(*options):
    return lambda tmp: ["demo", *options]


def out_is_file(tmp):
    (tmp / "out").write_text("a file")
    return ["demo", "--out", str(tmp / "out")]


def out_below_file(tmp):
    (tmp / "blocker").write_text("a file")
    return ["demo", "--out", str(tmp / "blocker" / "out")]


def out_holds_folder(name):
    def make(tmp):
        (tmp / "out" / name).mkdir(parents=True)
        return ["demo", "--out", str(tmp / "out")]
    return make


def out_locked_by_live_process(tmp):
    (tmp / "out").mkdir()
    (tmp / "out" / ".scanner.lock").write_text(f"{os.getppid()}\n")
    return ["demo", "--out", str(tmp / "out")]


def out_locked_on_another_host(tmp):
    (tmp / "out").mkdir()
    (tmp / "out" / ".scanner.lock").write_text(f"{os.getpid()} render-node-that-is-not-this-one\n")
    return ["demo", "--out", str(tmp / "out")]


def out_shards_is_file(tmp):
    (tmp / "out").mkdir()
    (tmp / "out" / "shards").write_text("not a folder")
    return ["demo", "--workers", "2", "--out", str(tmp / "out")]


def demo_many_frames(tmp):
    return ["scan", scene(tmp, DEMO.replace("frames = 120", "frames = 100000"))]


CASES = [
    # config files: syntax, types, ranges, keys
    ("config: not TOML", lambda t: ["scan", scene(t, "name = 'x'\n[robot\n")], 2, "toml"),
    ("config: empty file", lambda t: ["scan", scene(t, "")], 2, "robot"),
    ("config: binary junk", lambda t: ["scan", scene(t, "\x00\x01\x02 = \x03")], 2, "scene.toml"),
    ("config: not UTF-8", lambda t: (t.joinpath("latin.toml").write_bytes(DEMO.encode() + b"\n# caf\xe9\n"),
                                     ["scan", str(t / "latin.toml")])[1], 2, "UTF-8"),
    ("config: missing file", lambda t: ["scan", str(t / "nothing.toml")], 2, "nothing"),
    ("config: unknown bundled name", lambda t: ["scan", "no_such_scene"], 2, "demo"),
    ("config: folder", lambda t: ["scan", str(t)], 2, "a folder, not"),
    ("config: unknown top key", demo_plus("colour = 'red'"), 2, "colour"),
    ("path: a turn of 0 degrees", demo_with("turn_deg = 360.0", "turn_deg = 0.0"), 2,
     "[path[1]]: a turntable path of 120 frames with turn_deg 0 takes one profile 120 times"),
    ("path: a sweep along its own line", demo_with("table_deg = 0.0", "table_deg = 0.0\nline = [1.0, 0.0, 0.0]"), 2,
     "runs along the sweep's motion"),
    ("config: unknown robot key", demo_with("[robot]\n", "[robot]\nspeed = 3\n"), 2, "speed"),
    ("config: unknown robot rig", demo_with('rig = "adept_viper_s650"', 'rig = "abb_irb_9999"'), 2, "abb_irb_9999"),
    ("config: start_deg too short", demo_with("start_deg = [0.0, 30.0, -15.0, 0.0, 75.0, 90.0]",
                                              "start_deg = [0.0, 40.0]"), 2, "start_deg"),
    ("config: start_deg NaN", demo_with("start_deg = [0.0, 30.0,", "start_deg = [nan, 30.0,"), 2, "start_deg"),
    ("config: start_deg inf", demo_with("start_deg = [0.0, 30.0,", "start_deg = [inf, 30.0,"), 2, "start_deg"),
    ("config: start_deg beyond a joint limit", demo_with("start_deg = [0.0, 30.0, -15.0, 0.0, 75.0, 90.0]",
                                                         "start_deg = [0.0, 30.0, -15.0, 0.0, 175.0, 90.0]"),
     2, "robot.start_deg: J5 = 175.000° outside"),
    ("config: start_deg a string", demo_with("start_deg = [0.0, 30.0, -15.0, 0.0, 75.0, 90.0]",
                                             'start_deg = "up"'), 2, "start_deg"),
    ("config: unknown probe rig", demo_with('rig = "default"', 'rig = "laser9000"'), 2, "laser9000"),
    ("config: table a_mm a string", demo_with("a_mm = -500.0", 'a_mm = "far"'), 2, "a_mm"),
    ("config: table d_mm NaN", demo_with("d_mm = -200.0", "d_mm = nan"), 2, "d_mm"),
    ("config: no workpiece", demo_with('[workpiece]\nshape = "sphere"\nradius_mm = 30.0', ""), 2, "workpiece"),
    ("config: unknown shape", demo_with('shape = "sphere"', 'shape = "torus"'), 2, "torus"),
    ("config: shape and file", demo_with('shape = "sphere"', 'shape = "sphere"\nfile = "x.stl"'), 2, "shape"),
    ("config: radius negative", demo_with("radius_mm = 30.0", "radius_mm = -30.0"), 2, "radius_mm"),
    ("config: radius zero", demo_with("radius_mm = 30.0", "radius_mm = 0.0"), 2, "radius_mm"),
    ("config: radius NaN", demo_with("radius_mm = 30.0", "radius_mm = nan"), 2, "radius_mm"),
    ("config: radius huge", demo_with("radius_mm = 30.0", "radius_mm = 1e300"), 2, "radius_mm"),
    ("config: no path", demo_with("[[path]]\nkind = \"turntable\"", "[[nopath]]\nkind = \"turntable\""), 2, "path"),
    ("config: unknown path kind", demo_with('kind = "turntable"', 'kind = "spiral"'), 2, "spiral"),
    ("config: frames zero", demo_with("frames = 120", "frames = 0"), 2, "frames"),
    ("config: frames negative", demo_with("frames = 120", "frames = -5"), 2, "frames"),
    ("config: frames fractional", demo_with("frames = 120", "frames = 12.5"), 2, "frames"),
    ("config: frames a bool", demo_with("frames = 120", "frames = true"), 2, "frames"),
    ("config: probe_mm NaN", demo_with("probe_mm = [12.0, 0.0, 210.0]", "probe_mm = [nan, 0.0, 210.0]"), 2,
     "probe_mm"),
    ("config: probe_mm two numbers", demo_with("probe_mm = [12.0, 0.0, 210.0]", "probe_mm = [12.0, 0.0]"), 2,
     "probe_mm"),
    ("config: turn_deg inf", demo_with("turn_deg = 360.0", "turn_deg = inf"), 2, "turn_deg"),
    ("config: sweep from = to", demo_with("to_mm = [40.0, 0.0, 210.0]", "to_mm = [-40.0, 0.0, 210.0]"), 2, ""),
    ("config: sweep beam zero", demo_with("table_deg = 0.0", "table_deg = 0.0\nbeam = [0.0, 0.0, 0.0]"), 2,
     "beam"),
    ("config: unreachable path", demo_with("to_mm = [40.0, 0.0, 210.0]", "to_mm = [4000.0, 0.0, 210.0]"), 2, ""),
    ("config: probe inside the part", demo_with("probe_mm = [12.0, 0.0, 210.0]", "probe_mm = [0.0, 0.0, 20.0]"),
     2, ""),
    ("config: unknown engine", demo_with('engine = "cycles"', 'engine = "povray"'), 2, "povray"),
    ("config: samples zero", demo_with("samples = 1", "samples = 0"), 2, "samples"),
    ("config: samples NaN", demo_with("samples = 1", "samples = nan"), 2, "samples"),
    ("config: filter width negative", demo_with("filter_width_px = 0.01", "filter_width_px = -1.0"), 2,
     "filter_width_px"),
    ("config: unknown laser", demo_with('laser = "gobo"', 'laser = "torch"'), 2, "torch"),
    ("config: gobo laser in eevee", demo_with('engine = "cycles"', 'engine = "eevee"'), 2, "spot"),
    ("config: raycast with bounces", demo_with('engine = "cycles"', 'engine = "raycast"\nbounces = 2'), 2,
     "light transport"),
    ("config: raycast with the slit", demo_with('engine = "cycles"\nsamples = 1\nfilter_width_px = 0.01\nlaser = "gobo"',
                                                'engine = "raycast"\nsamples = 1\nfilter_width_px = 0.01\nlaser = "slit"'),
     2, "gobo"),
    ("--engine raycast on a glossy part", lambda t: ["scan", "cylinder_realistic", "--engine", "raycast"], 2,
     "light transport"),
    ("config: unknown detect method", demo_with('method = "gauss"', 'method = "magic"'), 2, "magic"),
    ("config: unknown triangulate method", demo_with('method = "exact"', 'method = "guess"'), 2, "guess"),
    ("config: fuse a number", demo_with("fuse = true", "fuse = 3"), 2, "fuse"),
    ("config: max_sigma negative", demo_plus("") if False else
     demo_with("fuse = true", "fuse = true\nmax_sigma_mm = -1.0"), 2, "max_sigma_mm"),
    ("config: sensor noise negative", demo_plus("[sensor]\nnoise = -0.5"), 2, "noise"),
    ("config: unknown sensor key", demo_plus("[sensor]\nblur = 2"), 2, "blur"),
    ("config: defocus focused inside the lens", demo_plus("[sensor]\ndefocus = true\nfocus_mm = 1.0"), 2,
     "scene.toml: sensor: defocus: [sensor] focus_mm 1 mm must lie beyond the lens's focal length"),
    ("config: safety clearance negative", demo_plus("[safety]\nmin_clearance_mm = -2.0"), 2,
     "min_clearance_mm"),
    ("config: fixture without file", demo_plus("[[fixture]]\nname = 'clamp'"), 2, "file"),
    # Extreme values that looked valid (a QA trial): a clearance no measuring probe can keep
    # was accepted and then hung in the collision checks; one the start pose breaks was found
    # only after every sample of the path (132 s); a probe whose cameras cannot image the line
    # rendered and measured nothing; a blind probe was refused only after the motion checks.
    ("config: a clearance the probe cannot keep and still measure", demo_plus("[safety]\nmin_clearance_mm = 250.0"),
     2, "is not below the end of the probe's range (250 mm)"),
    ("config: a clearance the start pose breaks", demo_plus("[safety]\nmin_clearance_mm = 200.0"), 2,
     "at the start pose: the probe comes within"),
    ("config: a clearance the whole path breaks (no start pose)", lambda t: ["scan", scene(t, "\n".join(
        ln for ln in DEMO.splitlines() if not ln.startswith("start_deg = [")) + "\n[safety]\nmin_clearance_mm = 150.0\n"),
        "--engine", "raycast"], 2, "at frames 0-179 (path[1] to path[2]): the probe comes within 148.00 mm of the "
                                   "workpiece"),
    ("probe: cameras that cannot image the line (a baseline of a nanometre)", probe_with("a_mm = 60.0", "a_mm = 1e-6"),
     2, "every point would be dropped as grazing"),
    ("config: a part wholly beyond the table", demo_with("radius_mm = 30.0", "radius_mm = 30.0\n[workpiece.pose]\n"
                                                                             "xyz_mm = [400.0, 0.0, 0.0]"), 2,
     "lies wholly beyond the table (its nearest point 370 mm from the table's axis"),
    ("probe: a range a micrometre deep: the range is named first", probe_with(
        "range_mm = [70.0, 250.0]", "range_mm = [150.0, 150.001]"), 2,
     "deep; a_mm 60, phi 21.8°, gamma 6.59e-05°): its view cannot hold the line; a deeper range (range_mm)"),
    ("probe: a line too thin to see on an unreachable path: the probe is named first", lambda t: (
        t.joinpath("probe.toml").write_text(PROBE.replace("line_width_mm = 1.2", "line_width_mm = 1e-9", 1)),
        ["scan", scene(t, DEMO.replace('rig = "default"', f'rig = "{t / "probe.toml"}"').replace(
            "to_mm = [40.0, 0.0, 210.0]", "to_mm = [4000.0, 0.0, 210.0]"))])[1], 2, "too thin for any pixel"),
    ("output: --out holds the part's own mesh where cloud.ply goes", lambda t: (
        t.joinpath("out").mkdir(), t.joinpath("out", "cloud.ply").write_bytes(cube_mm().export(file_type="ply")),
        ["scan", scene(t, DEMO.replace('shape = "sphere"\nradius_mm = 30.0', f'file = "{t / "out" / "cloud.ply"}"')),
         "--out", str(t / "out")])[2], 2, "would write its cloud.ply over"),
    ("output: --out holds a fixture's mesh where cloud.ply goes", lambda t: (
        t.joinpath("out").mkdir(), t.joinpath("out", "cloud.ply").write_bytes(cube_mm(10.0).export(file_type="ply")),
        ["scan", scene(t, DEMO + f'\n[[fixture]]\nname = "stop"\nfile = "{t / "out" / "cloud.ply"}"\n'
                              f'pose.xyz_mm = [100.0, 0.0, 0.0]\n'), "--out", str(t / "out")])[2],
     2, "a file it reads"),
    # Settings that would measure nothing at all, refused before the first render (a QA trial:
    # each ran to the end with an empty cloud and exit 0).
    ("probe: a laser line no pixel can catch", probe_with("line_width_mm = 1.2", "line_width_mm = 1e-9"), 2,
     "too thin for any pixel"),
    ("probe: a laser line wider than the detector takes", probe_with("line_width_mm = 1.2", "line_width_mm = 100.0"),
     2, "times what the detector takes"),
    ("config: edge_px dropping every column", demo_with("fuse = true", "fuse = true\nedge_px = 1000"), 2,
     "every point would go"),
    ("config: min_peak above the laser's peak", demo_with('method = "gauss"', 'method = "gauss"\nmin_peak = 1000'), 2,
     "ever bright enough to count"),
    ("option: --resolution with rows the line spans by hundreds",
     lambda t: ["scan", "demo", "--engine", "raycast", "--resolution", "160x100000"], 2, "times what the detector takes"),
    ("config: fixture colliding", lambda t: (t.joinpath("block.stl").write_bytes(cube_mm(400.0).export(
        file_type="stl")), ["scan", scene(t, DEMO + f'\n[[fixture]]\nname = "wall"\nfile = "{t / "block.stl"}"\n')])[1],
     2, ""),
    ("config: adaptive box inverted", demo_plus("[adaptive]\nbox_min_mm = [0, 0, 0]\nbox_max_mm = [10, -10, 10]"), 2,
     "box_max_mm"),
    ("config: adaptive box and cylinder", demo_plus("[adaptive]\nbox_min_mm = [0, 0, 0]\nbox_max_mm = [10, 10, 10]\n"
                                                  "radius_mm = 5.0\nheight_mm = 5.0"), 2, "radius_mm"),
    ("config: adaptive radius negative", demo_plus("[adaptive]\nradius_mm = -5.0\nheight_mm = 5.0"), 2, "radius_mm"),
    ("config: adaptive budget zero", demo_plus("[adaptive]\nmax_profiles = 0"), 2, "max_profiles"),
    ("config: adaptive box under the table", demo_plus("[adaptive]\nbox_min_mm = [-30, -30, -40]\n"
                                                     "box_max_mm = [30, 30, -5]"), 2, "under the table top"),
    ("config: adaptive box beyond the table", demo_plus("[adaptive]\nbox_min_mm = [300, 300, 0]\n"
                                                      "box_max_mm = [340, 340, 40]"), 2,
     "adaptive.box_min_mm: [300.0, 300.0, 0.0] .. [340.0, 340.0, 40.0]: the box lies wholly beyond the table (its "
     "nearest point 424 mm from the table's axis"),
    ("config: adaptive unknown key", demo_plus("[adaptive]\nvoxel = 3"), 2,
     "box_max_mm, box_min_mm, height_mm, max_profiles, min_gain, radius_mm, target_coverage, voxel_mm"),
    ("option: bench kinematics --n 0", lambda t: ["bench", "kinematics", "--n", "0"], 2,
     "--n: expected a whole number from 1 to"),
    ("option: bench kinematics --seed -1", lambda t: ["bench", "kinematics", "--seed", "-1"], 2,
     "--seed: expected a whole number from 0 to"),
    ("option: bench kinematics --fk-batch 0", lambda t: ["bench", "kinematics", "--fk-batch", "0"], 2, "--fk-batch"),
    ("option: bench metrics --rounds 0", lambda t: ["bench", "metrics", "--rounds", "0"], 2, "--rounds"),
    ("option: bench detect --images 0", lambda t: ["bench", "detect", "--images", "0"], 2, "--images"),
    ("option: bench render --frames 2.5", lambda t: ["bench", "render", "--frames", "2.5"], 2, "--frames"),
    # Values that ran the bench and then failed or were capped, refused at the option now:
    ("option: bench calibration --views 3", lambda t: ["bench", "calibration", "--views", "3"], 2,
     "--views: expected a whole number from 4 to"),
    ("option: bench parts --frames 1", lambda t: ["bench", "parts", "--frames", "1"], 2, "--frames: expected"),
    ("option: bench collision --frames 1", lambda t: ["bench", "collision", "--frames", "1"], 2, "--frames: expected"),
    ("option: bench farm --frames 100000", lambda t: ["bench", "farm", "--frames", "100000"], 2,
     "--frames: expected a whole number from 8 to 180"),
    ("option: bench scan --hires-frames 181", lambda t: ["bench", "scan", "--hires-frames", "181"], 2,
     "--hires-frames: expected a whole number from 1 to 180"),
    ("option: bench parts --only ,", lambda t: ["bench", "parts", "--only", ","], 2, "names no part"),
    ("option: bench realism --scenes empty", lambda t: ["bench", "realism", "--scenes", "", "--only", "scans"], 2,
     "names no scan config"),
    ("option: bench accuracy --out a file", lambda t: ["bench", "accuracy", "--out", str(_a_file(t))], 2,
     "is a file; give a folder"),
    ("option: adaptive --max-profiles a billion", lambda t: ["adaptive", "demo", "--max-profiles", "1000000000",
                                                             "--out", str(t / "out")], 2, "from 1 to 100000"),
    ("option: --device with the raycast engine", lambda t: ["scan", "demo", "--engine", "raycast", "--device", "gpu",
                                                            "--out", str(t / "out")], 2, "--engine cycles"),
    ("option: adaptive --min-gain zero", lambda t: ["adaptive", "demo", "--min-gain", "0", "--out",
                                                    str(t / "out")], 2, "--min-gain"),
    ("option: adaptive --max-profiles zero", lambda t: ["adaptive", "demo", "--max-profiles", "0", "--out",
                                                        str(t / "out")], 2, "--max-profiles"),
    ("config: adaptive target coverage over 1", demo_plus("[adaptive]\ntarget_coverage = 1.5"), 2, "target_coverage"),
    ("option: adaptive --target-coverage NaN", lambda t: ["adaptive", "demo", "--target-coverage", "nan", "--out",
                                                          str(t / "out")], 2, "--target-coverage: the target coverage"),
    ("option: adaptive --target-coverage 2", lambda t: ["adaptive", "demo", "--target-coverage", "2", "--out",
                                                        str(t / "out")], 2, "--target-coverage: the target coverage"),
    ("option: adaptive --min-gain beyond the config's limit", lambda t: ["adaptive", "demo", "--min-gain", "99999999999",
                                                                         "--out", str(t / "out")], 2,
     "--min-gain must be from 1 to 1e+09"),
    ("config: adaptive budget below a view", lambda t: ["adaptive", scene(t, DEMO + "\n[adaptive]\nmax_profiles = 10\n"),
                                                        "--engine", "raycast", "--out", str(t / "out")], 2,
     "raise --max-profiles, or [adaptive] max_profiles, to at least"),
    # from a bug hunt in the loaders (an OpenCV assertion at the first frame, an OverflowError,
    # a device ignored, a UnicodeError at the first IK call)
    ("config: steger without smoothing", demo_with('method = "gauss"', 'method = "steger"\nsmoothing_px = 0.0'), 2,
     'detect.smoothing_px: 0 is not allowed with method "steger"'),
    ("config: a number of 400 digits", demo_with("a_mm = -500.0", "a_mm = 1" + "0" * 400), 2,
     "table.a_mm: 1" + "0" * 400 + " is not allowed; it must be a finite number"),
    ("config: a GPU device for Eevee", demo_with('engine = "cycles"', 'engine = "eevee"\ndevice = "OPTIX"'), 2,
     "render.device: 'OPTIX' picks Cycles' render device"),
    ("config: controller host too long",
     lambda t: ["scan", scene(t, DEMO.replace('rig = "adept_viper_s650"', 'rig = "adept_viper_s650"\nik = "controller"', 1)
                            + '\n[robot.controller]\nhost = "' + "a" * 64 + '.local"\n')], 2,
     "robot.controller.host: 'aaaa"),
    ("config: controller IK without host", demo_with('rig = "adept_viper_s650"',
                                                   'rig = "adept_viper_s650"\nik = "controller"'), 2, "controller"),
    # probe rigs
    ("probe: range inverted", probe_with("range_mm = [70.0, 250.0]", "range_mm = [250.0, 70.0]"), 2, "range_mm"),
    ("probe: range NaN", probe_with("range_mm = [70.0, 250.0]", "range_mm = [nan, 250.0]"), 2, "range_mm"),
    ("probe: baseline zero", probe_with("a_mm = 60.0", "a_mm = 0.0"), 2, "a_mm"),
    ("probe: rows zero", probe_with("rows_px = 160", "rows_px = 0"), 2, "rows_px"),
    ("probe: a sensor of 10 gigapixels", probe_with("rows_px = 160        # H: along the triangulation direction\n"
                                                    "cols_px = 160", "rows_px = 100000\ncols_px = 100000"), 2,
     "more than the 50,000,000 allowed"),
    ("probe: cols fractional", probe_with("cols_px = 160", "cols_px = 160.5"), 2, "cols_px"),
    ("probe: line width negative", probe_with("line_width_mm = 1.2", "line_width_mm = -1.2"), 2,
     "line_width_mm"),
    ("probe: fan zero", probe_with("fan_deg = 60.0", "fan_deg = 0.0"), 2, "fan_deg"),
    ("probe: fan 200 degrees", probe_with("fan_deg = 60.0", "fan_deg = 200.0"), 2, "fan_deg"),
    ("probe: wavelength NaN", probe_with("wavelength_nm = 650.0", "wavelength_nm = nan"), 2, "wavelength_nm"),
    ("probe: mount rotation short", probe_with("yzz_deg = [0.0, 0.0, 0.0]", "yzz_deg = [0.0]"), 2, "yzz_deg"),
    ("probe: unknown key", probe_with("[laser]\n", "[laser]\npower_w = 5\n"), 2, "power_w"),
    ("probe: no camera table", probe_with("[camera]\n", "[kamera]\n"), 2, "camera"),
    # robot rigs
    ("robot: five links", robot_with("[[link]]  # J1\n", "[[notalink]]  # J1\n"), 2, "link"),
    ("robot: a_mm NaN", robot_with("a_mm = -425.0", "a_mm = nan"), 2, "a_mm"),
    ("robot: limits inverted", robot_with("min_deg = -360.0\nmax_deg = 360.0", "min_deg = 360.0\nmax_deg = -360.0"),
     2, "min_deg"),
    ("robot: alpha a string", robot_with("alpha_deg = 90.0", 'alpha_deg = "right"'), 2, "alpha_deg"),
    ("robot: unknown link key", robot_with("[[link]]  # J1\n", "[[link]]  # J1\nmass_kg = 3\n"), 2, "mass_kg"),
    ("robot: link mesh is a text file", rig_mesh_is_text, 2, "link.txt"),
    ("robot: link mesh missing", robot_with("[[link]]  # J1\n", '[[link]]  # J1\nmesh = "no/such.stl"\n'), 2,
     "such.stl"),
    # meshes
    ("mesh: ASCII STL with nan", part_file(ascii_stl_with_nan), 2, "nan.stl"),
    ("mesh: binary STL with NaN", part_file(binary_stl_with_nan), 2, "nan_bin.stl"),
    ("mesh: binary STL with inf", part_file(binary_stl_with_inf), 2, "inf.stl"),
    ("mesh: OBJ with nan", part_file(obj_with_nan), 2, "nan.obj"),
    ("mesh: PLY with NaN", part_file(ply_with_nan), 2, "nan.ply"),
    ("mesh: glTF with inf", part_file(glb_with_nan), 2, "inf.glb"),
    ("mesh: truncated STL", part_file(truncated_stl), 2, "cut.stl"),
    ("mesh: PNG named .stl", part_file(png_named_stl), 2, "not a readable"),
    ("mesh: empty file", part_file(empty_stl), 2, "empty.stl"),
    ("mesh: text named .obj", part_file(text_named_obj), 2, "notes.obj"),
    ("mesh: 2 GB sparse STL", part_file(sparse_huge_stl), 2, "announces 40000000 triangles, more than the"),
    ("mesh: saved in metres", part_file(part_in_metres), 2, "scale"),
    ("mesh: saved in micrometres", part_file(part_in_micrometres), 2, "scale"),
    ("mesh: a folder", part_file(folder_as_mesh), 2, "folder.stl"),
    ("mesh: unknown file type", part_file(unknown_mesh_type), 2, "part.xyz123"),
    ("mesh: missing", part_file(lambda t: t / "gone.stl"), 2, "gone.stl"),
    ("mesh: sunk 5 mm into the table", lambda t: ["scan", scene(t, DEMO.replace(
        'shape = "sphere"\nradius_mm = 30.0', f'file = "{good_cube_stl(t)}"\n[workpiece.pose]\nxyz_mm = [0, 0, -5]'))],
     2, "workpiece.pose: the workpiece cube reaches 5.00 mm below the table top"),
    ("mesh: scale negative", lambda t: ["scan", scene(t, DEMO.replace('shape = "sphere"\nradius_mm = 30.0',
                                        f'file = "{binary_stl_with_inf(t)}"\nscale = -1.0'))], 2, "scale"),
    ("mesh: scale that overflows", lambda t: ["scan", scene(t, DEMO.replace('shape = "sphere"\nradius_mm = 30.0',
                                              f'file = "{good_cube_stl(t)}"\nscale = 1e308'))], 2,
     "scale 1e+308 makes the mesh's coordinates overflow"),
    # 0 used to count as "not given" and the part was scanned at its file's own scale
    ("mesh: scale zero", lambda t: ["scan", scene(t, DEMO.replace('shape = "sphere"\nradius_mm = 30.0',
                                    f'file = "{good_cube_stl(t)}"\nscale = 0'))], 2, "allowed > 0"),
    ("fixture: scale zero",
     lambda t: ["scan", scene(t, DEMO + f'\n[[fixture]]\nfile = "{good_cube_stl(t)}"\nscale = 0\n')], 2, "allowed > 0"),
    ("fixture: scale far too large",
     lambda t: ["scan", scene(t, DEMO + f'\n[[fixture]]\nfile = "{good_cube_stl(t)}"\nscale = 1e6\n')], 2,
     "the mesh is 4e+07 mm across, larger than 5000 mm: is scale 1e+06 right"),
    ("fixture: two of one name", lambda t: ["scan", scene(t, DEMO + 2 * (
        f'\n[[fixture]]\nname = "c"\nfile = "{good_cube_stl(t)}"\n[fixture.pose]\nxyz_mm = [100, 0, 0]\n'))],
     2, "fixture[2].name: 'fixture c' names an earlier fixture too"),
    ("fixture: a default name taken", lambda t: ["scan", scene(t, DEMO + (
        f'\n[[fixture]]\nname = "fixture 2"\nfile = "{good_cube_stl(t)}"\n[fixture.pose]\nxyz_mm = [100, 0, 0]\n'
        f'\n[[fixture]]\nfile = "{good_cube_stl(t)}"\n[fixture.pose]\nxyz_mm = [-100, 0, 0]\n'))],
     2, "fixture[2].name: 'fixture 2' (the name it gets without a name key) names an earlier fixture too"),
    ("fixture: empty name",
     lambda t: ["scan", scene(t, DEMO + f'\n[[fixture]]\nname = " "\nfile = "{good_cube_stl(t)}"\n')], 2,
     "fixture[1].name: is empty"),
    ("fixture: on the table but wholly beyond it", lambda t: ["scan", scene(t, DEMO + (
        f'\n[[fixture]]\nname = "far"\nfile = "{good_cube_stl(t)}"\n[fixture.pose]\nxyz_mm = [400, 0, 0]\n'))],
     2, "fixture far lies wholly beyond the table"),
    ("fixture: on the table but wholly below its top", lambda t: ["scan", scene(t, DEMO + (
        f'\n[[fixture]]\nname = "sunk"\nfile = "{good_cube_stl(t)}"\n[fixture.pose]\nxyz_mm = [60, 0, -40]\n'))],
     2, "fixture sunk lies wholly below the table top"),
    # options
    ("option: --frames step zero", demo("--frames", "0:4:0"), 2, "--frames"),
    ("option: --frames open end past the path", demo("--frames", "500:"), 2, "--frames (the panel's Frames) 500: "),
    ("option: --frames words", demo("--frames", "a:b"), 2, "--frames"),
    ("option: --frames empty slice", demo("--frames", "5:2"), 2, "--frames"),
    ("option: --frames beyond the path", demo("--frames", "1000:2000"), 2, "--frames"),
    ("option: --frames a fraction", demo("--frames", "1.5"), 2, "--frames"),
    ("option: --resolution words", demo("--resolution", "big"), 2, "--resolution"),
    ("option: --resolution 1x1", demo("--resolution", "1x1"), 2, "--resolution"),
    ("option: --resolution negative", demo("--resolution", "-160x160"), 2, "--resolution"),
    ("option: --resolution 100000x100000", demo("--resolution", "100000x100000"), 2, "memory"),
    ("option: --resolution 30000x30000", demo("--resolution", "30000x30000"), 2, "memory"),
    ("option: --resolution for 12 hours", demo("--resolution", "8000x6000"), 2, "--force"),
    ("option: 100000 frames at 1280x1024", lambda t: demo_many_frames(t) + ["--resolution", "1280x1024"], 2,
     "--force"),
    ("option: --samples zero", demo("--samples", "0"), 2, "samples"),
    ("option: --samples negative", demo("--samples", "-4"), 2, "samples"),
    ("option: --samples words", demo("--samples", "many"), 2, "--samples"),
    ("option: --max-rms-um negative", demo("--max-rms-um", "-1"), 2, "--max-rms-um"),
    ("option: --max-rms-um NaN", demo("--max-rms-um", "nan"), 2, "--max-rms-um"),
    ("option: --max-rms-um infinite", demo("--max-rms-um", "inf"), 2, "finite"),
    ("option: --min-coverage zero", demo("--min-coverage", "0"), 2, "--min-coverage"),
    ("option: --min-coverage over 100", demo("--min-coverage", "101"), 2, "at most 100"),
    ("option: --min-coverage NaN", demo("--min-coverage", "nan"), 2, "--min-coverage"),
    ("option: --max-rms-um on one shard", demo("--shard", "0", "--shard-frames", "60", "--max-rms-um", "9"), 2,
     "--merge task"),
    ("option: --engine unknown", demo("--engine", "povray"), 2, "--engine"),
    ("option: --detect unknown", demo("--detect", "magic"), 2, "--detect"),
    ("option: --device unknown", demo("--device", "TPU"), 2, "--device"),
    ("option: unknown option", demo("--colour", "red"), 2, "--colour"),
    ("option: --shard-frames zero", demo("--shard-frames", "0"), 2, "--shard-frames"),
    ("option: --shard-frames beyond the path", demo("--shard-frames", "100000"), 2, "--shard-frames"),
    ("option: --shard without --shard-frames", demo("--shard", "0"), 2, "--shard-frames"),
    ("option: --shard out of range", demo("--shard", "99", "--shard-frames", "60"), 2, "--shard"),
    ("option: --shard negative", demo("--shard", "-1", "--shard-frames", "60"), 2, "--shard"),
    ("option: --merge with no shards", lambda t: ["demo", "--merge", "--shard-frames", "60", "--out",
                                                  str(t / "out")], 2, "not ready"),
    ("option: --workers with --merge", demo("--merge", "--shard-frames", "60", "--workers", "2"), 2,
     "--merge computes nothing"),
    ("option: --workers zero", demo("--workers", "0"), 2, "--workers"),
    ("option: --workers with --shard", demo("--shard", "0", "--shard-frames", "60", "--workers", "2"), 2,
     "has nothing to do"),
    ("option: --scheduler not an address", demo("--scheduler", "localhost"), 2, "--scheduler"),
    ("option: --scheduler no port", demo("--scheduler", "tcp://127.0.0.1"), 2, "--scheduler"),
    ("option: --scheduler nothing listening", demo("--scheduler", "tcp://127.0.0.1:9"), 2, "--scheduler"),
    ("option: no command", lambda t: [], 2, "COMMAND"),
    ("option: unknown command", lambda t: ["scna"], 2, "scna"),
    ("option: scan without config", lambda t: ["scan"], 2, "config"),
    ("option: unknown bench", lambda t: ["bench", "everything"], 2, "everything"),
    ("option: bench kinematics robot unknown", lambda t: ["bench", "kinematics", "--robots", "abb_irb120",
                                                          "--n", "10"], 2, "abb_irb120"),
    # calibration
    ("config: calibration file without [calibration]",
     demo_with('rig = "default"', f'rig = "default"\ncalibration = "{REPO / "rigs" / "probes" / "default.toml"}"'),
     2, "no [calibration]"),
    ("config: calibration file missing", demo_with('rig = "default"', 'rig = "default"\ncalibration = "nope.toml"'),
     2, "nope.toml"),
    ("config: calibration for another sensor", calibrated_on_another_sensor, 2, "sensor"),
    ("config: calibration of another probe", calibrated_on_another_probe, 2,
     "was calibrated on another probe (a_mm 75 mm there, 60 mm here"),
    ("config: a calibrated rig mounted otherwise", calibrated_rig_mounted_otherwise, 2,
     "probe.mount: moves the probe on the flange, and the rig"),
    ("calibrate: too few views", lambda t: ["calibrate", "demo", "--views", "3", "--out", str(t / "out")], 2,
     "--views"),
    ("calibrate: poses file missing", lambda t: ["calibrate", "demo", "--poses", str(t / "none.toml"), "--out",
                                                str(t / "out")], 2, "none.toml"),
    ("calibrate: poses file without views", lambda t: ((t / "p.toml").write_text("x = 1\n"),
                                                       ["calibrate", "demo", "--poses", str(t / "p.toml")])[1], 2,
     "[[view]]"),
    ("calibrate: a view with NaN", lambda t: ((t / "p.toml").write_text("[[view]]\nxyz_mm = [0, 0, nan]\n"
                                                                        "yzz_deg = [0, 180, 0]\n"),
                                              ["calibrate", "demo", "--poses", str(t / "p.toml")])[1], 2, "xyz_mm"),
    ("calibrate: views and poses both", lambda t: ["calibrate", "demo", "--views", "8", "--poses", str(t / "p.toml"),
                                                  "--out", str(t / "out")], 2, "give one"),
    ("calibrate: out is a file", lambda t: ((t / "f").write_text("x"), ["calibrate", "demo", "--out", str(t / "f")])[1],
     2, "is a file"),
    ("calibrate: calibration.json is a folder",
     lambda t: ((t / "out" / "calibration.json").mkdir(parents=True),
                ["calibrate", "demo", "--out", str(t / "out")])[1], 2, "calibration.json"),
    # output folders
    ("out: an existing file", out_is_file, 2, "is a file"),
    ("out: below a file", out_below_file, 2, "is a file"),
    # Writable by its permission bits for root, refused by the kernel: used to be the bare
    # "No such file or directory" without naming --out or what to do.
    ("config: samples not whole", lambda t: ["scan", scene(t, DEMO.replace("samples = 1\n", "samples = 1e12\n", 1))],
     2, "is not an integer (allowed: a whole number [1, 65536])"),
    ("out: empty", demo("--out", ""), 2, "--out: an empty name is no folder"),
    ("option: --workers with --scheduler", demo("--workers", "2", "--scheduler", "tcp://127.0.0.1:1"), 2,
     "--workers N starts a local cluster of N workers and --scheduler uses a running one's: give one of them"),
    ("out: under /proc", demo("--out", "/proc/scanner-test/out"), 2, "--out /proc/scanner-test/out cannot be written"),
    ("out: a device", demo("--out", "/dev/null"), 2, "--out /dev/null is a device; give a folder"),  # "is a file"
    ("out: cloud.ply is a folder", out_holds_folder("cloud.ply"), 2, "cloud.ply"),
    ("out: report.json is a folder", out_holds_folder("report.json"), 2, "report.json"),
    ("out: preview.png is a folder", out_holds_folder("preview.png"), 2, "preview.png"),
    ("out: a running scan owns it", out_locked_by_live_process, 75, "running scan"),
    ("out: a scan on another host owns it", out_locked_on_another_host, 75, "render-node-that-is-not-this-one"),
    ("out: farm's shards is a file", out_shards_is_file, 2, "shards"),
    ("out: farm into an existing file", lambda t: out_is_file(t) + ["--workers", "2"], 2, "is a file"),
]


def _listing(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*")) if folder.exists() else []


@pytest.mark.parametrize("name,make,code,words", CASES, ids=[c[0] for c in CASES])
def test_bad_input_gives_one_line_and_leaves_nothing(name, make, code, words, tmp_path, capsys):
    work = tmp_path / "work"
    work.mkdir()
    argv = make(work)
    out = work / "out"
    if "--out" not in argv and argv and argv[0] in ("demo", "scan"):
        argv = argv + ["--out", str(out)]
    before = _listing(out)
    try:
        rc = main(argv)
    except SystemExit as exc:  # argparse
        rc = exc.code
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == code, (rc, err[-3000:])
    assert len(lines) == 1 and lines[0].startswith("error: "), err[-3000:]
    assert words.lower() in lines[0].lower(), lines[0]
    assert "Traceback" not in err
    assert _listing(out) == before, "the output folder changed"


def test_the_catalogue_is_large():
    assert len(CASES) + len(PROCESS_CASES) >= 100


# -- cases that need a process of their own -------------------------------------------------
def _start(args, tmp, **kw):
    env = dict(os.environ, TMPDIR=str(tmp / "tmp"), PYTHONUNBUFFERED="1")
    (tmp / "tmp").mkdir(exist_ok=True)
    return subprocess.Popen([sys.executable, "-m", "headless", *args], cwd=REPO, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **kw)


def _wait_for(proc, text: str, timeout: float = 120.0, stream: str = "stderr") -> str:
    """Read the child's stderr (its progress) until a line holds ``text``; returns what was read."""
    seen = []
    t = time.monotonic()
    while time.monotonic() - t < timeout:
        line = getattr(proc, stream).readline()
        if not line:
            break
        seen.append(line)
        if text in line:
            return "".join(seen)
    raise AssertionError(f"never printed {text!r}: {''.join(seen)[-2000:]}")


def _stop(tmp, signals, after: str = "frames/s"):
    out = tmp / "out"
    proc = _start(["demo", "--out", str(out)], tmp)
    _wait_for(proc, after)
    t = time.monotonic()
    for s in signals:
        proc.send_signal(s)
        time.sleep(0.05)  # two presses, not one merged signal
    stdout, stderr = proc.communicate(timeout=60)
    return proc.returncode, stderr, time.monotonic() - t, out


def _temp_left(tmp) -> list[str]:
    return sorted(p.name for p in (tmp / "tmp").iterdir())


def case_ctrl_c_once(tmp):
    rc, err, took, out = _stop(tmp, [signal.SIGINT])
    assert rc == 130, err
    last = err.strip().splitlines()[-1]
    assert last.startswith("interrupted (Ctrl-C) after ") and "nothing written" in last, err
    done, total = (int(v) for v in last.split("after ")[1].split(" frames")[0].split(" of "))
    assert 0 < done < total == 180
    assert took < 5.0, took  # the frames being rendered, then the stop
    assert not out.exists() and _temp_left(tmp) == []
    assert "Traceback" not in err


def case_ctrl_c_twice(tmp):
    # Two presses in a row: almost always the second lands while the frames under way are
    # still rendering ("stopped at once"); when the first stop is already through, the second
    # must not turn it into a KeyboardInterrupt death (exit -2): the stop stays one stop.
    rc, err, took, out = _stop(tmp, [signal.SIGINT, signal.SIGINT])
    last = err.strip().splitlines()[-1]
    assert rc == 130, err
    assert last.endswith("stopped at once, nothing written") or (
        last.startswith("interrupted (Ctrl-C) after ") and "nothing written" in last), err
    assert not out.exists() and _temp_left(tmp) == []
    assert "Traceback" not in err


def case_sigterm(tmp):
    rc, err, took, out = _stop(tmp, [signal.SIGTERM])
    assert rc == 143 and "interrupted (SIGTERM)" in err, err
    assert not out.exists() and _temp_left(tmp) == []


def case_ctrl_c_farm(tmp):
    # As a terminal sends it: to the whole process group, the cluster's workers too (each printed
    # a traceback of its own until they started deaf to it). The stop counts the finished shards
    # on disk, which the next run keeps.
    out = tmp / "out"
    proc = _start(["demo", "--workers", "1", "--shard-frames", "30", "--out", str(out)], tmp, start_new_session=True)
    _wait_for(proc, "done:")  # the farm's log, with the progress on stderr
    os.killpg(proc.pid, signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=90)
    assert proc.returncode == 130, stderr[-3000:]
    last = stderr.strip().splitlines()[-1]
    kept = sorted((out / "shards").iterdir())
    assert last.startswith("interrupted (Ctrl-C) after ") and (
        f"no cloud or report written to {out}; {len(kept)} of the 6 shards are finished in {out / 'shards'}" in last), \
        stderr[-3000:]
    assert not any((out / n).exists() for n in ("cloud.ply", "report.json", "preview.png"))
    assert kept and all(p.name.startswith("shard_") and p.suffix == ".npz" for p in kept)
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr[-3000:]
    time.sleep(1.0)  # the workers' own cleanup
    assert _temp_left(tmp) == []


def case_ctrl_c_bench(tmp):
    # A benchmark's scans pass no progress callback of their own; Ctrl-C still stops the one
    # under way after its current frames, and nothing of the benchmark is written.
    proc = _start(["bench", "parts", "--only", "hex nut,block with hole", "--frames", "12"], tmp)
    _wait_for(proc, "block with hole and pocket:", stream="stdout")  # the first part is done
    t = time.monotonic()
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=90)
    assert proc.returncode == 130, stderr[-3000:]
    last = stderr.strip().splitlines()[-1]
    assert last.startswith("interrupted (Ctrl-C) after ") and "nothing written" in last, stderr[-3000:]
    assert "hex nut:" not in stdout and "| part |" not in stdout  # the second part and the table never came
    assert time.monotonic() - t < 20.0
    assert "Traceback" not in stderr and _temp_left(tmp) == []


def case_file_size_limit(tmp):
    import resource

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (1_000_000, 1_000_000))

    proc = _start(["demo", "--resolution", "1000x1000", "--out", str(tmp / "out")], tmp, preexec_fn=limit)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 2, stderr[-3000:]
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and "ulimit" in lines[0]
    assert not (tmp / "out").exists() and _temp_left(tmp) == []


def case_stale_temp_folders_are_removed(tmp):
    (tmp / "tmp").mkdir()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp / "tmp" / f"scanner-run-{dead.pid}-abc"
    (stale / "blender_x").mkdir(parents=True)
    alive = tmp / "tmp" / f"scanner-run-{os.getpid()}-abc"
    alive.mkdir()
    proc = _start(["kinematics"], tmp)
    proc.communicate(timeout=120)
    assert proc.returncode == 0
    assert not stale.exists() and alive.exists()  # a live process's folder is left alone


def case_broken_pipe_free_exit_on_bad_config(tmp):
    proc = _start(["scan", str(tmp / "none.toml")], tmp)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 2 and len(stderr.strip().splitlines()) == 1 and _temp_left(tmp) == []


def case_ctrl_c_once_the_results_are_written(tmp):
    # A QA trial's Ctrl-C as the summary printed (the files written): it said "nothing written"
    # of three files, left the folder's lock, or died with a traceback from the teardown. The
    # scan by ray casting, whose process has no Blender to hold the signal back.
    out = tmp / "out"
    proc = _start(["scan", "demo", "--engine", "raycast", "--quiet", "--out", str(out)], tmp)
    _wait_for(proc, "  points", stream="stdout")
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 0, stderr
    assert sorted(p.name for p in out.iterdir()) == ["cloud.ply", "preview.png", "report.json"], stderr
    assert "nothing written" not in stderr and "Traceback" not in stderr, stderr
    assert _temp_left(tmp) == []


PROCESS_CASES = [case_ctrl_c_once, case_ctrl_c_twice, case_sigterm, case_ctrl_c_farm, case_ctrl_c_bench,
                 case_ctrl_c_once_the_results_are_written, case_file_size_limit, case_stale_temp_folders_are_removed, case_broken_pipe_free_exit_on_bad_config]


@pytest.mark.parametrize("case", PROCESS_CASES, ids=[c.__name__[5:] for c in PROCESS_CASES])
def test_process_case(case, tmp_path):
    case(tmp_path)


@pytest.mark.parametrize("make,key", [
    (demo_plus("[[fixture]]\nname = 'clamp'\nfile = 'c.stl'\n[fixture.pose]\nxyz_mm = [nan, 0.0, 0.0]"),
     "fixture[1].pose.xyz_mm: element 0"),
    (lambda t: ["scan", scene(t, (REPO / "rigs" / "scenes" / "ur5_urdf.toml").read_text().replace(
        "[robot]", "[robot]\npackage_dirs = \"~/ros\"", 1))], "robot.package_dirs: '~/ros'"),
])
def test_a_bad_value_in_a_table_names_its_own_key_once_not_the_file_it_sits_beside(tmp_path, capsys, make, key):
    argv = make(tmp_path)
    assert main(argv + ["--out", str(tmp_path / "out"), "--engine", "raycast"]) == 2
    line = capsys.readouterr().err.strip()
    assert f"scene.toml: {key}" in line and line.count("scene.toml") == 1 and "robot.urdf:" not in line \
        and ".file:" not in line, line


def test_a_scan_that_measures_nothing_of_the_part_says_so_and_counts_only_the_points_it_kept(tmp_path, capsys):
    """A QA trial: scans that found no point on the part exited 0 without a word (the small-share
    warning asked for a share above 0), and report.json counted fused points that the
    neighbouring profiles had then dropped (10 points, 429 of them fused). ``max_sigma_mm = inf``,
    which the docs give for "keep every point", is taken."""
    tiny = scene(tmp_path, DEMO.replace("radius_mm = 30.0", "radius_mm = 0.005", 1).replace(
        "fuse = true", "fuse = true\nmax_sigma_mm = inf", 1), "tiny.toml")
    rc = main(["scan", tiny, "--engine", "raycast", "--frames", "0:4", "--out", str(tmp_path / "tiny"), "--quiet"])
    report = json.loads((tmp_path / "tiny" / "report.json").read_text())
    assert rc == 0 and report["points"] > 0 and report["points_on_part"] == 0
    said = [w for w in report["warnings"] if w.startswith("the scan measured")]
    assert said == [f"the scan measured {report['points']} points, none of them on the part: none of the laser rays "
                    f"sampled along the path (one per sensor column) meets the part within the probe's range and a "
                    f"camera's view: a path onto the part ([[path]] entries; the preview shows where the points are), "
                    f"or a part narrower than the line or a column's footprint"]
    assert said[0] in capsys.readouterr().out
    # Coarse rows: most fused points are dropped as uncertain once their neighbours are in.
    rc = main(["scan", "demo", "--engine", "raycast", "--frames", "0:12", "--resolution", "160x96",
               "--out", str(tmp_path / "coarse"), "--quiet"])
    report = json.loads((tmp_path / "coarse" / "report.json").read_text())
    assert rc == 0 and report["points_dropped"]["uncertain"] > report["points"] > 0
    cloud = load_ply(tmp_path / "coarse" / "cloud.ply")
    assert report["points_fused"] == int(np.sum(cloud.camera == 3)) <= report["points"] == len(cloud)


def test_a_scan_saturated_throughout_names_the_exposure(tmp_path):
    """A second-long exposure clipped every line: the warning blamed "the sensor's settings, the
    detector's, or the probe's view" and the summary counted "no detection"."""
    bright = scene(tmp_path, DEMO + "\n[sensor]\nsaturate = true\nexposure_ms = 1000.0\n", "bright.toml")
    assert main(["scan", bright, "--engine", "raycast", "--frames", "0:180:30", "--out", str(tmp_path / "o"),
                 "--quiet"]) == 0
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    said = [w for w in report["warnings"] if w.startswith("the scan measured")]
    assert len(said) == 1 and "were saturated" in said[0] and "exposure_ms" in said[0], report["warnings"]
    assert report["column_codes"]["SATURATED"] > 0


def test_a_scan_that_lost_most_of_its_line_to_saturation_says_so(tmp_path):
    """Columns clipped at full scale are dropped one by one: a scan left with 160 of its 3 320
    points on the part said nothing while any point survived (a hunt). The shares are counted
    from the report's own columns; an exposure that clips none says nothing."""
    # the realistic-sensor scene's glossy cylinder, turned grey, its [sensor] table ours
    base = (REPO / "rigs" / "scenes" / "cylinder_realistic.toml").read_text()
    base = base[:base.index("\n[sensor]\n")].replace('material = "glossy"', 'material = "grey"').replace(
        "roughness = 0.2\n", "").replace("bounces = 2", "bounces = 0").replace("ambient = 0.25", "ambient = 0.0")
    lines = []
    for exposure in (6.0, 0.5):
        text = base + f"\n[sensor]\nsaturate = true\nexposure_ms = {exposure}\nseed = 1\n"
        config = scene(tmp_path, text, f"bright{exposure}.toml")
        out = tmp_path / f"o{exposure}"
        assert main(["scan", config, "--engine", "raycast", "--frames", "0:40:4", "--out", str(out), "--quiet"]) == 0
        report = json.loads((out / "report.json").read_text())
        codes = report["column_codes"]
        lit = sum(v for k, v in codes.items() if k != "NO_LINE")
        said = [w for w in report["warnings"] if "were saturated" in w]
        lines.append((exposure, codes["SATURATED"] / lit, said, report["points_on_part"]))
    (_, share, said, _), (_, low_share, low_said, _) = lines
    assert share > 0.3 and len(said) == 1 and "exposure_ms" in said[0], lines
    assert low_share < 0.1 and not low_said, lines
