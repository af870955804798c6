"""Scan configs: one TOML file (``rigs/scenes/<name>.toml``) describes a whole scan.

Sections (units in the key names; every key is checked, unknown keys are errors)::

    name = "..."                      description = "..."
    [robot]      rig (name or path of a DH table) or urdf (a .urdf file; + base_link, tool_link,
                 package_dirs: folders for package:// meshes), start_deg = [6 joint angles] (IK seed),
                 ik = "local" | "controller", [robot.controller] host, port, timeout_s (IK from
                 the robot controller over TCP/IP: addon.core.kinematics.ik_remote)
    [probe]      rig (name or path), [probe.mount] xyz_mm, yzz_deg (optional T_L^6 override),
                 calibration (a probe file with a [calibration] table, e.g. written by
                 ``python -m headless calibrate``: the scan renders with the rig's true
                 geometry and triangulates with what the calibration found)
    [table]      a_mm, d_mm (Eq. 4 placement; defaults −500, −200)
    [workpiece]  shape = plane|sphere|cylinder|step_block (+ its size keys) or file (+ scale),
                 material = grey|dark|glossy|mirror, roughness (glossy),
                 [workpiece.pose] xyz_mm, yzz_deg (placement in the table frame)
    [[path]]     kind = "sweep": frames, from_mm, to_mm, beam, line, table_deg
                 kind = "turntable": frames, probe_mm, beam, line, start_deg, turn_deg
    [render]     engine, device, samples, pixel_filter, filter_width_px, bounces, ambient,
                 laser (gobo|spot|slit; gobo is Cycles' Gaussian line, spot Eevee's), laser_peak,
                 resolution = [W, H] (the probe's optics on another sensor: W columns along
                 the line, H rows along the triangulation)
    [detect]     method (threshold|cog|gauss|steger), min_peak, second_peak_ratio, max_width_px,
                 max_width_ratio (1.6: wider than that × the median width is rejected),
                 smoothing_px (default: none on noise-free images of the gobo line; otherwise matched
                 to the line, none for lines under 0.8 px σ; the slit's flat top always smoothed)
    [triangulate] method (exact|paper), fuse (both cameras into one profile),
                 max_incidence_deg (65), edge_px (1), max_sigma_mm (0.05): see
                 addon.core.optics.profile_filter
    [leave_out]  render_band, skip_blind_cameras, hide_robot, chunk_frames, band_margin_px
    [sensor]     the realistic sensor (all off by default): integrate_pixels, saturate, noise,
                 speckle, defocus, distortion = [k1, k2, p1, p2(, k3)], undistort, motion_blur, and
                 exposure_ms, auto_exposure, target_peak, gain, bit_depth, full_well_e,
                 electrons_per_unit, read_noise_e, dark_offset_dn, prnu, sensor_width_mm,
                 pixel_pitch_um, f_number, focus_mm, wavelength_nm (default: the probe's [laser]), frame_rate_hz, seed
                 (see addon.core.optics.sensor)
    [adaptive]   what the adaptive planner is told: box_min_mm, box_max_mm (the part's bounding box,
                 table frame) or radius_mm, height_mm (a cylinder on the table's axis), max_profiles
                 (600), min_gain (15 cells), target_coverage (a share, 0..1: stop once the planner's
                 own coverage estimate reaches it; none by default), voxel_mm (2); see addon.adaptive
    [safety]     check (true), min_clearance_mm (2): the least distance between the robot or the
                 probe and the table, the workpiece or a fixture (see addon.core.safety)
    [[fixture]]  name, file (+ scale), [fixture.pose] xyz_mm, yzz_deg, on = "table" (turns with
                 it, default; the pose in the table frame) | "world" (the pose in the world
                 frame: the robot's base frame unless its rig gives [base]): solids the robot
                 must keep clear of
    [truth]      coverage_tolerance_mm

Paths in the file (robot/probe rigs, workpiece files) are relative to the file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..kinematics import path as scanpath
from ..kinematics.cell import Cell
from ..kinematics.ik_remote import DEFAULT_PORT, Controller, ControllerIK
from .toml import Table, load_toml, resolve_rig
from ..optics.detect import METHODS as DETECT_METHODS
from ..optics.detect import DetectParams
from ..errors import ConfigError, InputError, check_number, check_whole, is_whole
from ..kinematics.robot import Robot
from ..config.rigs import load_robot
from ..optics.probe import MAX_PIXELS, MIN_PIXELS, Probe
from .render import (DEFAULT_LASER, DEVICES, ENGINES, LASERS, PIXEL_FILTERS, RenderOptions, box_width,
                     laser_engine_mismatch, raycast_mismatch, with_sensor)
from .rigs import URDF_SUFFIXES, load_probe
from ..optics.sensor import BIT_DEPTHS, SensorModel
from ..optics.profile_filter import ProfileFilter
from ..optics.triangulate import TRIANGULATION_METHODS
from ..kinematics.turntable import (PAPER_A_R_MM, PAPER_D_R_MM, TABLE_RADIUS_MM, Turntable, box_beyond_table,
                                    nearest_to_axis_mm)
from ..geometry.workpiece import (BUILTINS, Workpiece, builtin_workpiece, check_on_table, check_over_table,
                                  depth_below_table, load_workpiece)
from ..safety import FIXTURE_CARRIERS, Fixture, Safety

PATH_KINDS = ("sweep", "turntable")
MATERIALS = ("grey", "dark", "glossy", "mirror")
MAX_FRAMES = scanpath.MAX_FRAMES


@dataclass(frozen=True)
class LeaveOut:
    """render_band: render only the rows where the line can fall; skip_blind_cameras: do not
    render a camera that sees no laser light on the whole path; hide_robot: leave the robot
    (which the probe cameras cannot see) out of probe renders, unevaluated; chunk_frames:
    frames per render call (one band each); band_margin_px: rows added above and below the band."""

    render_band: bool = True
    skip_blind_cameras: bool = True
    hide_robot: bool = True
    chunk_frames: int = 8
    band_margin_px: int = 6


# Steep points and the ends of runs are dropped unless a config says otherwise: on the
# tilted plate they are all of the error above 8 µm (see profile_filter and the README).
# One column at each end of a run: the detector already rejects a line cut across its
# width, and a second column cost coverage (bunny 77 → 82 %, step block 92 → 95 % of the
# measurable surface) without moving any part's error.
# A point whose own σ (see triangulate and detect) exceeds 50 µm is dropped: a quarter of the
# 0.2 mm a point may stray from the part, so that what is kept strays less than that.
DEFAULT_FILTER = ProfileFilter(max_incidence_deg=65.0, edge_px=1, max_sigma_mm=0.05)
# Columns whose line is 1.6 times wider than the image's median are rejected: the part turns
# away from the laser across the line there (grazing along the scan); and those whose profile
# is narrower than 0.8 times the median (σ₃, see detect): an edge of the part cuts the line
# across its width. On the real-parts bench, 95 % of the columns of whole lines lie within
# 0.8..1.2 of their image's median, and 216 of 227 points off their part by more than
# 0.2 mm below 0.8.
WIDTH_RATIO = 1.6
NARROW_RATIO = 0.8


# The most profiles an adaptive scan may be given (config, command line, Gymnasium env): hours
# of rendering, far beyond any part here (a table turn takes 120-450).
MAX_PROFILES = 100_000
MAX_MIN_GAIN = 10**9  # [adaptive] min_gain at most (more cells than any model holds)


@dataclass(frozen=True)
class AdaptiveSettings:
    """[adaptive]: what the adaptive planner is told and may spend. ``box``: the part's
    bounding volume (lo, hi) in the table frame, mm, from box_min_mm / box_max_mm or a
    cylinder on the table's axis (radius_mm, height_mm); None: the workpiece's box grown by
    10 % (a cell would be told roughly that much). max_profiles: the budget; min_gain: the
    new cells a sweep must promise; target_coverage: stop once the planner's coverage
    estimate reaches this share (None: at the budget or when nothing promises min_gain);
    voxel_mm: the model's cell size."""

    box: tuple | None = None
    max_profiles: int = 600
    # 15, not 30: on the stepped shaft the 75° turn that finds the groove's floor (a ring
    # 3 mm deep, which the 2 mm model sees mostly as surface already) promises 17-21 cells,
    # and at 30 the planner stopped with 258 of its 450 profiles left and 4 points of the
    # part under the table turns' (docs/adaptive.md).
    min_gain: int = 15
    voxel_mm: float = 2.0
    target_coverage: float | None = None
    # The box is a cylinder's on the table's axis (radius_mm, height_mm): the same at any turn
    # of the part (a box is the bounds of what it holds, and those of a turned box grow).
    cylinder: bool = False


@dataclass(frozen=True)
class ScanConfig:
    name: str
    source: str
    robot: Robot
    probe: Probe
    table: Turntable
    workpiece: Workpiece
    waypoints: scanpath.Waypoints
    q_start: np.ndarray | None = None
    render: RenderOptions = field(default_factory=RenderOptions)
    detect_method: str = "gauss"
    detect: DetectParams = field(default_factory=lambda: DetectParams(saturation=np.inf,
                                                                      max_width_ratio=WIDTH_RATIO,
                                                                      min_width_ratio=NARROW_RATIO))
    triangulate_method: str = "exact"
    fuse: bool = True
    leave_out: LeaveOut = field(default_factory=LeaveOut)
    coverage_tolerance_mm: float = 1.0
    description: str = ""
    sensor: SensorModel = field(default_factory=SensorModel)
    material: str = "grey"
    roughness: float = 0.2
    profile_filter: ProfileFilter = field(default_factory=lambda: DEFAULT_FILTER)
    safety: Safety = field(default_factory=Safety)
    fixtures: tuple = ()
    adaptive: AdaptiveSettings = field(default_factory=AdaptiveSettings)
    # The path's own frame number of each waypoint where --frames picked some (the scan numbers
    # its frames from 0 in the order picked); None: the whole path, numbered as written.
    path_frames: np.ndarray | None = None

    @property
    def detect_params(self) -> DetectParams:
        """The detector's settings for this scan. Unless the config sets ``smoothing_px``,
        ``gauss`` reads a noise-free image of the Gaussian (gobo) line unsmoothed: the
        three-point fit is exact on a point-sampled Gaussian, while smoothing a line
        only a pixel or two wide biases it (33 against 0.9 µm RMS on the tilted plate).
        Noisy images (the sensor's noise or speckle) and the slit laser's flat-topped
        line get the detector's automatic choice: the matched smoothing, except for lines
        narrower than a pixel or so, which it reads unsmoothed too (see detect._smoothing)."""
        d = self.detect
        if self.render.laser == "slit":
            return replace(d, flat_top=True)
        noisy = self.sensor.noise or self.sensor.speckle
        if d.smoothing_px is None and self.detect_method == "gauss" and not noisy:
            return replace(d, smoothing_px=0.0)
        return d

    @property
    def cell(self) -> Cell:
        """The robot carrying this probe (its mount as the tool) and the table (built once per
        config: a step-by-step scanner asks for it at every measurement)."""
        cell = self.__dict__.get("_cell")
        if cell is None:
            cell = self.__dict__["_cell"] = Cell(self.robot.with_tool(self.probe.mount), self.table)
        return cell

    def with_realism(self, sensor: SensorModel, material: str | None = None, roughness: float | None = None,
                     ambient: float | None = None) -> "ScanConfig":
        """A copy with this sensor model (and, if given, workpiece surface and ambient light).
        A sensor that clips makes the detector flag lines that reach full scale."""
        if material is not None and material not in MATERIALS:
            raise InputError(f"material {material!r} is not one of: {', '.join(MATERIALS)}")
        if roughness is not None:
            check_number(roughness, "roughness", 0.0, 1.0)
        detect = replace(self.detect, saturation=sensor.clip_level) if sensor.clips else self.detect
        render = self.render if ambient is None else replace(self.render, ambient=check_number(ambient, "ambient", 0, 100))
        return replace(self, sensor=sensor, detect=detect, render=render,
                       material=self.material if material is None else material,
                       roughness=self.roughness if roughness is None else float(roughness))

    def input_files(self) -> list[str]:
        """The files this scan reads that an output could overwrite: the config, the part's
        and the fixtures' mesh files."""
        sources = [self.source, self.workpiece.source] + [f.source for f in self.fixtures]
        return [s for s in sources if s and not s.startswith(("builtin:", "bench:", "test:"))]

    def raycast_refusal(self) -> str | None:
        """With engine raycast: why this scan needs Cycles instead (see
        :func:`~addon.core.config.render.raycast_mismatch`), else None."""
        if self.render.engine != "raycast":
            return None
        return raycast_mismatch(with_sensor(self.render, self.sensor), self.material, self.leave_out.hide_robot)

    def start_joints_for(self, robot: Robot, table: Turntable):
        """This config's start joints for a cell built from it with ``robot`` and ``table``:
        its own where both are its own (the robot's name, DH table, limits, base and tool; the
        table's placement), else None (the IK seeds itself): another arm or table would start
        from a meaningless posture, or one outside its limits."""
        mine = self.robot
        same = robot.name == mine.name and all(
            np.array_equal(getattr(robot, k), getattr(mine, k))
            for k in ("a_mm", "d_mm", "alpha_rad", "theta_offset_rad", "q_min_rad", "q_max_rad", "base", "tool"))
        return self.q_start if same and table == self.table else None

    def with_overrides(self, *, engine=None, samples=None, resolution=None, detect=None, frames=None,
                       device=None) -> "ScanConfig":
        """A copy with command-line overrides applied; ``frames`` is a slice of the path."""
        cfg = self
        render = cfg.render
        if device is not None:
            if device not in DEVICES:
                raise InputError(f"--device (device) {device!r} is not one of: {', '.join(DEVICES)}")
            render = replace(render, device=device)
        if engine is not None:
            if engine not in ENGINES:
                raise InputError(f"--engine (engine) {engine!r} is not one of: {', '.join(ENGINES)}")
            laser = render.laser
            if laser_engine_mismatch(engine, laser) and laser != "slit":  # each engine's own Gaussian line
                laser = DEFAULT_LASER[engine]
            if engine == "eevee" and (render.bounces > 0 or render.pixel_filter != "BOX"):  # as [render] says
                what = (f"bounces = {render.bounces}, which Eevee does not trace" if render.bounces > 0 else
                        f"pixel_filter = {render.pixel_filter!r}, which Eevee does not have (it takes the width only)")
                raise InputError(f"--engine (engine) eevee: this config's [render] {what}; leave it out of the config, or "
                                 f"render with cycles")
            width = box_width(engine, render.pixel_filter, render.samples, render.filter_width_px)
            render = replace(render, engine=engine, laser=laser, filter_width_px=width)
            why = replace(cfg, render=render).raycast_refusal()
            if why:
                raise InputError(f"--engine (engine) raycast: {why}")
        if device is not None and render.engine != "cycles":
            raise InputError(f"--device {device} picks Cycles' render device, and this scan renders with "
                             f"{render.engine} ({'OpenGL' if render.engine == 'eevee' else 'Embree on the CPU'}): "
                             f"leave --device out, or add --engine cycles")
        if samples is not None:
            samples = check_whole(samples, "--samples (samples)", 1, 65536)
            render = replace(render, samples=samples,
                             filter_width_px=box_width(render.engine, render.pixel_filter, samples,
                                                       render.filter_width_px))
            why = replace(cfg, render=render).raycast_refusal()
            if why:  # (refused by the first frame's worker before, after a local farm had started)
                raise InputError(f"--samples (samples) {samples} with the raycast engine: {why}")
        cfg = replace(cfg, render=render)
        if resolution is not None:
            size = resolution if isinstance(resolution, (tuple, list)) else ()
            if len(size) != 2 or not all(is_whole(v) and MIN_PIXELS <= v <= MAX_PIXELS for v in size):
                raise InputError(f"--resolution (resolution) must be two whole numbers (width, height) of {MIN_PIXELS} to "
                                 f"{MAX_PIXELS} pixels, got {resolution!r}")
            W, H = (int(v) for v in size)
            cfg = replace(cfg, probe=cfg.probe.with_resolution(H, W))
        if detect is not None:
            if detect not in DETECT_METHODS:
                raise InputError(f"--detect (detect) {detect!r} is not one of: {', '.join(DETECT_METHODS)}")
            if detect == "steger" and cfg.detect.smoothing_px == 0.0:  # as the config's own [detect] method
                raise InputError(f"--detect (detect) steger: this config's [detect] smoothing_px = 0, which steger "
                                 f"cannot take (its ridge test works on the smoothed image); pick another method, "
                                 f"or set smoothing_px in (0, 100] px or leave it out")
            cfg = replace(cfg, detect_method=detect)
        if frames is not None:
            if isinstance(frames, str):
                frames = parse_frames(frames, "--frames (frames)")
            if not isinstance(frames, slice) or not all(v is None or is_whole(v)
                                                        for v in (frames.start, frames.stop, frames.step)):
                raise InputError(f"--frames (frames) must be a slice of the path with whole numbers (slice(0, 40), "
                                 f"or as text \"0:40\"), got {frames!r}")
            if frames.step is not None and frames.step < 1:
                raise InputError(f"--frames (frames): the step must be a whole number of at least 1, got {frames.step}")
            picked = np.arange(len(cfg.waypoints))[frames]
            if picked.size == 0:
                asked = frames if not isinstance(frames, slice) else ":".join(
                    "" if v is None else str(v) for v in (frames.start, frames.stop)) + (
                    "" if frames.step is None else f":{frames.step}")
                raise InputError(f"--frames (the panel's Frames) {asked} selects no frames of the "
                                 f"{len(cfg.waypoints)} in the path (0 to {len(cfg.waypoints) - 1})")
            whole = cfg.path_frames is None and np.array_equal(picked, np.arange(len(cfg.waypoints)))
            if not whole:  # (":" or "0:N" is the whole path: scanned and reported as without --frames)
                numbers = np.arange(len(cfg.waypoints)) if cfg.path_frames is None else cfg.path_frames
                cfg = replace(cfg, waypoints=cfg.waypoints.select(picked), path_frames=numbers[picked])
        return cfg


def parse_frames(text: str | None, what: str = "frames") -> slice | None:
    """A part of a path as the user writes it ("A:B", "A:B:STEP", "::2", "5") -> a slice; None
    for none given. Whole numbers only, a step of at least 1."""
    if text is None or not str(text).strip():
        return None
    parts = str(text).split(":")
    try:
        values = [int(p) if p.strip() else None for p in parts]
    except ValueError:
        values = []
    if len(parts) == 1 and values and values[0] is not None:
        return slice(values[0], values[0] + 1 if values[0] != -1 else None)  # "-1": the last frame
    if len(values) not in (2, 3):
        raise InputError(f"{what} {text!r}: expected A:B or A:B:STEP with whole numbers (e.g. 0:40 or ::2)")
    if len(values) == 3 and values[2] is not None and values[2] < 1:
        raise InputError(f"{what} {text!r}: the step must be a whole number of at least 1")
    return slice(*values)


def _rig_path(base: Path, value: str) -> str:
    """A rig given as a path or a file name (.toml, .urdf, .xml) is relative to the config file
    (``~`` is the home folder); a bare name is a bundled rig."""
    if "/" in value or "\\" in value or value.lower().endswith((".toml",) + URDF_SUFFIXES) or value.startswith("~"):
        p = Path(value).expanduser()
        return str(p if p.is_absolute() else (base / p))
    return value


def load_scan_config(name_or_path: str | Path, *, path_required: bool = True) -> ScanConfig:
    """Read and check a scan config; every problem is a ConfigError naming file, key and allowed values.
    ``path_required=False`` (the adaptive planner's, a Scanner's, calibrate's, ik-server's: they
    ignore [[path]] or move step by step) takes a config without [[path]] entries, its path then
    empty."""
    path = resolve_rig("scenes", name_or_path)
    top = load_toml(path)  # (its errors name the file as given)
    # The files it names are found from its folder, and the report keeps them (and it) whole:
    # relative, a report named files relative to wherever the scan ran, and an output folder's
    # owner was read from another folder as a file that is not there.
    base = path.absolute().parent
    name = top.string("name", default=path.stem)
    description = top.string("description", default="")

    rt = top.table("robot")
    if rt.has("rig") == rt.has("urdf"):
        raise rt.error("rig", "give exactly one of rig (a bundled name or a .toml DH table) or urdf (a .urdf file)")
    key = "rig" if rt.has("rig") else "urdf"
    # The table's own values first: their errors name their own keys; the file's errors after.
    if key == "rig":
        rig = rt.string("rig")
    else:
        f = Path(rt.string("urdf")).expanduser()
        dirs = [Path(d).expanduser() for d in rt.strings("package_dirs", default=[])]
        links = rt.string("base_link", default="") or None, rt.string("tool_link", default="") or None
    try:
        if key == "rig":
            robot = load_robot(_rig_path(base, rig))
        else:
            robot = load_robot(f if f.is_absolute() else base / f, base_link=links[0], tool_link=links[1],
                               package_dirs=[d if d.is_absolute() else base / d for d in dirs], urdf=True)
    except ConfigError as exc:
        raise ConfigError(f"{path}: robot.{key}: {exc}") from None
    q_start = None
    if rt.has("start_deg"):  # degrees; a sliding joint's value is millimetres
        values = np.array(rt.numbers("start_deg", 6, lo=-1e6, hi=1e6))
        q_start = np.where(robot.prismatic, values, np.radians(values))
        turning = ~np.array(robot.prismatic)
        if (np.abs(values[turning]) > 720).any():
            raise ConfigError(f"{path}: robot.start_deg: {values[turning].tolist()} holds an angle beyond ±720°")
        outside = robot.limit_violations(q_start)
        if outside:  # where the robot stands when the scan starts: it cannot stand beyond a limit
            raise ConfigError(f"{path}: robot.start_deg: {'; '.join(outside)} (the robot's limits)")
    if rt.string("ik", default="local", choices=["local", "controller"]) == "controller":
        ct = rt.table("controller", default={})
        host = ct.string("host", default="127.0.0.1")
        port = ct.integer("port", default=DEFAULT_PORT, lo=1, hi=65535)
        timeout_s = ct.number("timeout_s", default=2.0, lo=0.0, hi=600.0, lo_open=True)
        try:
            controller = Controller(host, port, timeout_s)
        except InputError as exc:  # Controller checks its host
            raise ct.error("host", str(exc)) from None
        ct.finish()
        robot = replace(robot, ik_via=ControllerIK(controller))
    elif rt.has("controller"):  # (it read as an unknown key, its allowed keys not naming it)
        raise rt.error("controller", 'is read only with ik = "controller" (the IK from a robot controller); '
                                     'set that, or leave [robot.controller] out')
    rt.finish()

    pt = top.table("probe")
    try:
        rig = _rig_path(base, pt.string("rig"))
        probe = load_probe(rig)
    except ConfigError as exc:
        raise ConfigError(f"{path}: probe.rig: {exc}") from None
    if probe.calibration is not None:  # a rig that carries its calibration: the report names its file
        made = probe.calibration.source  # (as with [probe] calibration = FILE: with_calibration)
        probe = replace(probe, calibration=replace(probe.calibration, source=f"{resolve_rig('probes', rig)}"
                                                   + (f" ({made})" if made else "")))
    if pt.has("mount"):
        mounted = replace(probe, mount=pt.pose("mount", base=probe.mount))  # a key left out keeps the rig's
        if probe.calibration is not None and probe.geometry_differences(mounted):
            # (as calibration = FILE refuses a probe mounted otherwise: the calibration's laser
            # plane and cameras are in the flange's frame through this mount)
            raise pt.error("mount", f"moves the probe on the flange, and the rig {rig} carries a calibration made "
                                    f"with the rig's own mount: a calibration holds for the mount it was made "
                                    f"on; leave [probe.mount] out, or calibrate the probe so mounted (python -m "
                                    f"headless calibrate CONFIG --out DIR)")
        probe = mounted
    # Applied once [render] resolution has set the sensor (a calibration is made at one size).
    calibration = _rig_path(base, pt.string("calibration")) if pt.has("calibration") else None
    pt.finish()

    tt = top.table("table", default={})
    table = Turntable(tt.number("a_mm", default=PAPER_A_R_MM, lo=-1e5, hi=1e5),
                      tt.number("d_mm", default=PAPER_D_R_MM, lo=-1e5, hi=1e5))
    tt.finish()

    wt = top.table("workpiece")
    material = wt.string("material", default="grey", choices=MATERIALS)
    roughness = wt.number("roughness", default=0.2, lo=0.0, hi=1.0)
    if wt.has("roughness") and material != "glossy":  # grey and dark are matt, a mirror polished
        raise wt.error("roughness", f"applies to material = \"glossy\" only (this part's is {material!r}: "
                                    f"{'polished' if material == 'mirror' else 'matt'}); leave it out, or make "
                                    f"the material glossy")
    workpiece = _workpiece(wt, base)
    waypoints = _paths(top, table, path_required)
    render, resolution = _render(top.table("render", default={}))
    if resolution is not None:
        try:
            probe = probe.with_resolution(resolution[1], resolution[0])
        except InputError as exc:  # a probe rig that carries its own calibration
            raise ConfigError(f"{path}: render.resolution: {exc}") from None
    if calibration is not None:
        probe = with_calibration(probe, calibration, f"{path}: probe.calibration")
    detect_method, detect = _detect(top.table("detect", default={}))
    tri = top.table("triangulate", default={})
    tri_method = tri.string("method", default="exact", choices=TRIANGULATION_METHODS)
    if tri_method == "paper" and probe.calibration is not None:  # refused here, not at the first frame
        raise ConfigError(f"{path}: triangulate.method \"paper\" (Eq. 6) assumes the nominal symmetric probe, and "
                          f"probe.calibration gives a calibrated one: use method \"exact\" or leave the calibration out")
    fuse = tri.boolean("fuse", default=True)
    profile_filter = ProfileFilter(
        max_incidence_deg=tri.number("max_incidence_deg", default=DEFAULT_FILTER.max_incidence_deg, lo=0.0, hi=90.0,
                                     lo_open=True),
        edge_px=tri.integer("edge_px", default=DEFAULT_FILTER.edge_px, lo=0, hi=1000),
        max_sigma_mm=tri.number("max_sigma_mm", default=DEFAULT_FILTER.max_sigma_mm, lo=0.0, lo_open=True,
                                inf_ok=True))  # inf: keep every point
    tri.finish()
    lo = top.table("leave_out", default={})
    leave_out = LeaveOut(lo.boolean("render_band", default=True), lo.boolean("skip_blind_cameras", default=True),
                         lo.boolean("hide_robot", default=True), lo.integer("chunk_frames", default=8, lo=1, hi=10000),
                         lo.integer("band_margin_px", default=6, lo=0, hi=10000))
    lo.finish()
    st = top.table("sensor", default={})
    own_wavelength = st.has("wavelength_nm")
    sensor = _sensor(st)
    if not own_wavelength:  # speckle's wavelength is the probe's laser's ([laser] wavelength_nm) unless set here
        sensor = replace(sensor, wavelength_nm=probe.wavelength_nm)
    if sensor.defocus:  # a focus the lens cannot reach is refused here, not at the scan's start
        try:
            sensor.spread_px(probe)
        except InputError as exc:
            raise ConfigError(f"{path}: sensor: {exc}") from None
    st = top.table("safety", default={})
    safety = Safety(st.boolean("check", default=True),
                    st.number("min_clearance_mm", default=Safety().min_clearance_mm, lo=0.0, hi=1e4))
    if safety.check and safety.min_clearance_mm >= probe.z_range_mm[1] * (1.0 - 1e-9):
        # The laser starts inside the probe, so the probe is nearer any point it measures than
        # the point is to the laser: a clearance this large keeps every point out of range.
        z1 = probe.z_range_mm[1]
        if "min_clearance_mm" not in st.data:  # the default: the probe's range is what is odd
            raise st.error("min_clearance_mm", f"the probe's range ends {z1:.4g} mm from its laser, within the "
                           f"{safety.min_clearance_mm:g} mm (the default) that the probe keeps from the part and the "
                           f"table: it could never measure a point; a probe whose range reaches farther (its range_mm, "
                           f"or phi and gamma), or a smaller min_clearance_mm")
        raise st.error("min_clearance_mm", f"{safety.min_clearance_mm:g} mm is not below the end of the probe's "
                       f"range ({z1:.4g} mm): the probe could never come near enough the part to measure it; "
                       f"allowed: 0 to under {z1:.4g} mm (default {Safety().min_clearance_mm:g})")
    st.finish()
    fixtures = _fixtures(top, base)
    adaptive = _adaptive(top.table("adaptive", default={}))
    truth = top.table("truth", default={})
    cov = truth.number("coverage_tolerance_mm", default=1.0, lo=0.0, hi=1e3, lo_open=True)
    truth.finish()
    top.finish()
    mismatch = laser_engine_mismatch(render.engine, render.laser)
    if mismatch:
        raise ConfigError(f"{path}: render.laser: {mismatch}")
    cfg = ScanConfig(name, str(path.absolute()), robot, probe, table, workpiece, waypoints, q_start, render, detect_method,
                     detect, tri_method, fuse, leave_out, cov, description, profile_filter=profile_filter,
                     safety=safety, fixtures=fixtures, adaptive=adaptive)
    cfg = cfg.with_realism(sensor, material, roughness)
    why = cfg.raycast_refusal()
    if why:
        raise ConfigError(f"{path}: render.engine raycast: {why}")
    return cfg


def _adaptive(t: Table) -> AdaptiveSettings:
    box = None
    if t.has("box_min_mm") or t.has("box_max_mm"):
        lo, hi = t.numbers("box_min_mm", 3, lo=-1e4, hi=1e4), t.numbers("box_max_mm", 3, lo=-1e4, hi=1e4)
        if not (hi > lo).all():
            raise t.error("box_max_mm", f"{hi.tolist()} must exceed box_min_mm {lo.tolist()} in x, y and z")
        if hi[2] <= 0.0:
            raise t.error("box_max_mm", f"{hi.tolist()}: the box lies under the table top (z = 0 in the table "
                                        f"frame); its top must be above 0")
        beyond = box_beyond_table(lo, hi)
        if beyond:
            raise t.error("box_min_mm", f"{lo.tolist()} .. {hi.tolist()}: {beyond}")
        box = (lo, hi)
    if t.has("radius_mm") or t.has("height_mm"):
        if box is not None:
            raise t.error("radius_mm", "give a box (box_min_mm, box_max_mm) or a cylinder (radius_mm, height_mm), "
                                       "not both")
        r = t.number("radius_mm", lo=0.0, hi=1e4, lo_open=True)
        h = t.number("height_mm", lo=0.0, hi=1e4, lo_open=True)
        box = (np.array([-r, -r, 0.0]), np.array([r, r, h]))
    t.allow("box_min_mm", "box_max_mm", "radius_mm", "height_mm")
    target = t.number("target_coverage", default=None, lo=0.0, hi=1.0, lo_open=True)
    out = AdaptiveSettings(box, t.integer("max_profiles", default=AdaptiveSettings.max_profiles, lo=1, hi=MAX_PROFILES),
                           t.integer("min_gain", default=AdaptiveSettings.min_gain, lo=1, hi=MAX_MIN_GAIN),
                           t.number("voxel_mm", default=AdaptiveSettings.voxel_mm, lo=0.1, hi=100.0), target,
                           cylinder=t.has("radius_mm"))
    t.finish()
    return out


def _fixtures(top: Table, base: Path) -> tuple:
    out = []
    for i, t in enumerate(top.tables("fixture") if top.has("fixture") else []):
        name = t.string("name", default=f"fixture {i + 1}").strip()
        if not name:
            raise t.error("name", "is empty: give each fixture a name, or leave the key out (fixture 1, 2, ...)")
        if not name.startswith("fixture"):
            name = f"fixture {name}"
        if any(f.name == name for f in out):
            given = t.has("name")
            raise t.error("name", f"{name!r}{'' if given else ' (the name it gets without a name key)'} names an "
                                  f"earlier fixture too: each needs its own name, which the collision messages and "
                                  f"warnings use")
        f = Path(t.string("file"))
        scale = t.number("scale", default=None, lo=0.0, lo_open=True)
        on = t.string("on", default="table", choices=list(FIXTURE_CARRIERS))
        pose = t.pose("pose")  # its own errors name its own keys
        try:
            f = f if f.is_absolute() else base / f
            mesh = load_workpiece(f, pose, scale, role="fixture").mesh
        except (InputError, ConfigError) as exc:
            raise t.error("file", str(exc)) from None
        if on == "table" and mesh.bounds[1][2] <= 0.0:
            raise t.error("pose", f"{name} lies wholly below the table top (its highest point z = "
                                  f"{mesh.bounds[1][2]:.1f} mm in the table frame, whose top is z = 0), where "
                                  f"nothing can see or meet it: raise it (pose xyz_mm) so that it stands on the "
                                  f"table")
        nearest = nearest_to_axis_mm(mesh)
        if on == "table" and nearest > TABLE_RADIUS_MM + 1.0:
            raise t.error("on", f"{name} lies wholly beyond the table (its nearest point {nearest:.0f} mm from the "
                                f"axis, the table's radius {TABLE_RADIUS_MM:g} mm), so nothing holds it as the table "
                                f"turns: place it on the table (pose xyz_mm in the table frame), or give "
                                f"on = \"world\" for a fixture that stands beside the cell")
        t.finish()
        out.append(Fixture(name, mesh, on, str(f)))
    return tuple(out)


def _workpiece(t: Table, base: Path) -> Workpiece:
    pose = t.pose("pose")
    if t.has("file") == t.has("shape"):
        raise t.error("shape", "give exactly one of shape (built-in: " + ", ".join(BUILTINS) + ") or file")
    try:
        if t.has("file"):
            f = Path(t.string("file"))
            scale = t.number("scale", default=None, lo=0.0, lo_open=True)
            wp = load_workpiece(f if f.is_absolute() else base / f, pose, scale)
        else:
            kind = t.string("shape", choices=list(BUILTINS))
            params = {}
            for key, default in BUILTINS[kind][1].items():
                if t.has(key):
                    params[key] = (tuple(t.number_list(key, lo=0.0, hi=1e4, lo_open=True))
                                   if isinstance(default, tuple) else t.number(key, lo=0.0, hi=1e4, lo_open=True))
            wp = builtin_workpiece(kind, pose, **params)
    except InputError as exc:
        raise t.error("shape" if t.has("shape") else "file", str(exc)) from None
    try:
        check_on_table(wp, f"raise [workpiece.pose] xyz_mm's z by at least {depth_below_table(wp):.2f} mm")
        check_over_table(wp, "place it on the table ([workpiece.pose] xyz_mm, in the table frame, whose axis is "
                             "x = y = 0)")
    except InputError as exc:
        raise t.error("pose", str(exc)) from None
    t.finish()
    return wp


def _paths(top: Table, table: Turntable, required: bool = True) -> scanpath.Waypoints:
    if not top.has("path"):
        if required:
            raise top.error("path", "missing: a scan needs at least one [[path]] entry (the adaptive command, "
                                    "which ignores the path, calibrate, ik-server and a Scanner take a config "
                                    "without one)")
        return scanpath.Waypoints(np.zeros((0, 4, 4)), np.zeros(0), np.zeros(0, int))
    parts = []
    for i, p in enumerate(top.tables("path")):
        kind = p.string("kind", choices=PATH_KINDS)
        frames = p.integer("frames", lo=1, hi=MAX_FRAMES)
        beam = p.numbers("beam", 3, default=list(scanpath.DOWN), lo=-1e6, hi=1e6)
        line = p.numbers("line", 3, lo=-1e6, hi=1e6) if p.has("line") else None
        try:
            if kind == "sweep":
                parts.append(scanpath.sweep(frames, p.numbers("from_mm", 3, lo=-1e5, hi=1e5),
                                            p.numbers("to_mm", 3, lo=-1e5, hi=1e5), beam, line,
                                            np.radians(p.number("table_deg", default=0.0, lo=-1e5, hi=1e5)), i))
            else:
                parts.append(scanpath.turntable(frames, p.numbers("probe_mm", 3, lo=-1e5, hi=1e5), beam, line,
                                                np.radians(p.number("start_deg", default=0.0, lo=-1e5, hi=1e5)),
                                                # past a whole turn its profiles measure the first turn's again
                                                np.radians(p.number("turn_deg", default=360.0, lo=-360.0, hi=360.0)),
                                                table, i))
        except InputError as exc:
            raise p.table_error(str(exc)) from None  # the message names the key
        p.finish()
    if not parts:
        raise top.error("path", "at least one [[path]] is needed" + (
            "" if required else " (or none at all: the adaptive planner and a Scanner take a config without one)"))
    return scanpath.concatenate(parts)


def _render(t: Table) -> tuple[RenderOptions, tuple[int, int] | None]:
    engine = t.string("engine", default="cycles", choices=ENGINES)
    samples = t.integer("samples", default=1, lo=1, hi=65536)
    pixel_filter = t.string("pixel_filter", default="BOX", choices=PIXEL_FILTERS)
    width = box_width(engine, pixel_filter, samples, 0.01)  # where none is given
    try:
        opts = _render_options(t, engine, samples, pixel_filter, width)
    except InputError as exc:
        raise t.error("filter_width_px" if t.has("filter_width_px") else "samples", str(exc)) from None
    if engine == "eevee" and t.has("pixel_filter"):  # Eevee has one filter, of which only the width is set
        raise t.error("pixel_filter", "Eevee has a pixel filter of its own and takes only its width "
                                      "(filter_width_px); leave pixel_filter out, or set engine = \"cycles\"")
    if engine == "eevee" and opts.bounces > 0:
        raise t.error("bounces", f"{opts.bounces}: Eevee traces no bounces (a glossy part's reflections of the line "
                                 f"need Cycles); leave bounces out, or set engine = \"cycles\"")
    if opts.device != "CPU" and engine != "cycles":  # as the command line's --device
        raise t.error("device", f"{opts.device!r} picks Cycles' render device, and this config renders with {engine}: "
                                f"leave device out, or set engine = \"cycles\"")
    resolution = None
    if t.has("resolution"):  # the same optics on another sensor: [W, H] = [columns, rows]
        w, h = t.numbers("resolution", 2, lo=MIN_PIXELS, hi=MAX_PIXELS)
        if w != int(w) or h != int(h):
            raise t.error("resolution", f"[{w:g}, {h:g}]: pixel counts must be whole numbers")
        resolution = (int(w), int(h))
    t.finish()
    return opts, resolution


def _render_options(t: Table, engine: str, samples: int, pixel_filter: str, width: float) -> RenderOptions:
    return RenderOptions(
        engine=engine,
        device=t.string("device", default="CPU", choices=DEVICES),  # Cycles' only (checked by the caller)
        samples=samples,
        pixel_filter=pixel_filter,
        filter_width_px=t.number("filter_width_px", default=width, lo=0.01, hi=10.0),
        bounces=t.integer("bounces", default=0, lo=0, hi=64),
        ambient=t.number("ambient", default=0.0, lo=0.0, hi=100.0),
        laser=t.string("laser", default=DEFAULT_LASER[engine], choices=LASERS),
        laser_peak=t.number("laser_peak", default=0.5, lo=0.0, hi=1e3, lo_open=True),
    )


def _detect(t: Table) -> tuple[str, DetectParams]:
    method = t.string("method", default="gauss", choices=DETECT_METHODS)
    defaults = DetectParams()
    params = DetectParams(
        min_peak=t.number("min_peak", default=defaults.min_peak, lo=0.0, hi=1e3),
        second_peak_ratio=t.number("second_peak_ratio", default=defaults.second_peak_ratio, lo=0.0, hi=1.0,
                                   lo_open=True),
        max_width_px=t.number("max_width_px", default=defaults.max_width_px, lo=0.0, hi=1e4, lo_open=True),
        max_width_ratio=t.number("max_width_ratio", default=WIDTH_RATIO, lo=1.0, hi=1e3),
        min_width_ratio=t.number("min_width_ratio", default=NARROW_RATIO, lo=0.0, hi=1.0),
        smoothing_px=t.number("smoothing_px", default=None, lo=0.0, hi=100.0),
        saturation=np.inf,  # renders are linear float: nothing clips unless a sensor model says so
    )
    if method == "steger" and params.smoothing_px == 0.0:  # its ridge test takes the smoothed Hessian
        raise t.error("smoothing_px", "0 is not allowed with method \"steger\", whose ridge test works on the "
                                      "smoothed image; allowed (0, 100] px, or leave it out (matched to the line)")
    t.finish()
    return method, params


def _sensor(t: Table) -> SensorModel:
    """[sensor]: each effect a switch (all off: the ideal sensor), with its parameters."""
    d = SensorModel()
    kw = {}
    for key in ("integrate_pixels", "saturate", "noise", "speckle", "defocus", "undistort", "motion_blur",
                "auto_exposure"):
        kw[key] = t.boolean(key, default=getattr(d, key))
    for key, lo in (("exposure_ms", 0.0), ("gain", 0.0), ("full_well_e", 0.0),
                    ("electrons_per_unit", 0.0), ("sensor_width_mm", 0.0), ("wavelength_nm", 0.0),
                    ("frame_rate_hz", 0.0)):
        kw[key] = t.number(key, default=getattr(d, key), lo=lo, hi=1e7, lo_open=True)
    # f/0.5 is the fastest a lens in air can be (f/0.3 was taken, and all but removed speckle)
    kw["f_number"] = t.number("f_number", default=d.f_number, lo=0.5, hi=1e7)
    kw["target_peak"] = t.number("target_peak", default=d.target_peak, lo=0.0, hi=1.0, lo_open=True)  # of full scale
    for key in ("read_noise_e", "dark_offset_dn", "prnu"):
        kw[key] = t.number(key, default=getattr(d, key), lo=0.0, hi=1e7)
    for key in ("pixel_pitch_um", "focus_mm"):  # absent: derived from the probe (see SensorModel)
        kw[key] = t.number(key, default=None, lo=0.0, hi=1e7, lo_open=True)
    if t.has("pixel_pitch_um") and t.has("sensor_width_mm"):  # (the pitch won without a word)
        raise t.error("pixel_pitch_um", "and sensor_width_mm both set the pixel pitch (the width over the "
                                        "sensor's columns): give one of them")
    kw["bit_depth"] = t.integer("bit_depth", default=d.bit_depth)
    if kw["bit_depth"] not in BIT_DEPTHS:
        raise t.error("bit_depth", f"must be one of {', '.join(map(str, BIT_DEPTHS))}, got {kw['bit_depth']}")
    kw["seed"] = t.integer("seed", default=d.seed, lo=0, hi=2 ** 31 - 1)
    kw["distortion"] = tuple(float(k) for k in t.number_list("distortion", default=(), lo=-10.0, hi=10.0,
                                                             min_len=4))
    # A parameter whose effect is off does nothing: said, not ignored (an 8-bit sensor with
    # neither saturate nor noise on scanned as the ideal one, its report saying "ideal").
    for keys, switches in (
            (("auto_exposure", "target_peak", "gain", "bit_depth", "full_well_e", "electrons_per_unit"),
             ("saturate", "noise")),
            (("read_noise_e", "dark_offset_dn", "prnu"), ("noise",)),
            (("exposure_ms",), ("saturate", "noise", "motion_blur")),
            (("frame_rate_hz",), ("motion_blur",)),
            # (these three were taken and did nothing: the clouds byte for byte the same)
            (("target_peak",), ("auto_exposure",)),
            (("f_number",), ("speckle", "defocus")),
            (("wavelength_nm",), ("speckle",)),
            (("focus_mm",), ("defocus",))):
        given = [k for k in keys if t.has(k) and not (k == "auto_exposure" and not kw[k])]
        if given and not any(kw[w] for w in switches):
            raise t.error(given[0], f"acts only with {' or '.join(switches)} = true, and this [sensor] has "
                                    f"{'neither' if len(switches) == 2 else 'none of them' if len(switches) > 2 else 'it off'}"
                                    f"; turn {'one of them' if len(switches) > 1 else 'it'} on, or leave "
                                    f"{given[0]} out")
    try:
        model = SensorModel(**kw)
    except InputError as exc:
        raise t.table_error(str(exc)) from None
    t.finish()
    return model


def with_calibration(probe: Probe, calibrated_file, where: str) -> Probe:
    """``probe`` (rendered as it is) triangulating with the calibration in ``calibrated_file``."""
    try:
        found = load_probe(calibrated_file)
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None
    if found.calibration is None:
        raise ConfigError(f"{where}: {calibrated_file} has no [calibration] table; make one with "
                          f"python -m headless calibrate CONFIG --out DIR (it writes DIR/probe.toml)")
    if (found.rows_px, found.cols_px) != (probe.rows_px, probe.cols_px):
        raise ConfigError(f"{where}: {calibrated_file} was calibrated on a {found.cols_px}x{found.rows_px} sensor; "
                          f"this probe has {probe.cols_px}x{probe.rows_px}")
    differ = found.geometry_differences(probe)
    if differ:
        raise ConfigError(f"{where}: {calibrated_file} was calibrated on another probe ({'; '.join(differ)}): a "
                          f"calibration holds for the probe it was made on; calibrate this one (python -m headless "
                          f"calibrate CONFIG --out DIR)")
    source = found.calibration.source
    return replace(probe, calibration=replace(found.calibration,
                                              source=f"{calibrated_file}" + (f" ({source})" if source else "")))
