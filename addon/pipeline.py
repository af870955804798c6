"""One scan, end to end: config -> scene -> frames -> cloud -> report (UI operator and headless alike).

Stages, each timed:

1. plan: joint vectors for every waypoint (continuous, no flips); the laser fan
   cast against the part and the table. Unreachable waypoints and waypoints whose
   laser meets nothing inside the probe's range stop the scan here, before any
   rendering, with their indices.
2. scene: the Blender cell, the path keyframed.
3. render: chunks of frames, one render call each. With ``leave_out.render_band``
   only the rows where the line can fall are rendered: the rows the line held in
   the previous frames, widened by a margin that follows how fast it moves; the
   first frame, and any frame whose line touched the band's edge or thinned out,
   is rendered at full height. A camera that sees no laser light anywhere on the
   path (from the plan's ray casts) is not rendered at all.
4. detect, triangulate (both cameras fused), move into the table frame (Eq. 8).
5. measure against the ground truth: error of the points on the part, of the
   points on the table (its top is the plane z = 0), and coverage of the part.
6. write cloud.ply, report.json and preview.png, each atomically, all at the end.
"""

from __future__ import annotations

import json
import math
import platform
import time
from warnings import catch_warnings, simplefilter
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from .core.geometry import metrics
from .core.geometry.cloud import CloudAccumulator, save_ply
from .core.optics.detect import LineCode, detect_line
from .core.errors import InputError, ScannerError, UnreachablePose
from .core.optics.profile_filter import filter_profile
from .core.files import write_bytes_atomic, write_png
from .core.geometry.footprint import SurfaceCaster, laser_footprint
from .core.scan.preview import render_preview
from .core.scan.report import report_json
from .core.config.render import RenderOptions
from .core.config.scan import ScanConfig
from .core.kinematics.path import solve_path
from .core.optics.triangulate import fuse_profiles, triangulate_profile
from .core.kinematics.turntable import TABLE_RADIUS_MM, table_top_mesh

BAND_FULL_SHARE = 0.75     # a band this tall (share of the rows) is not worth cropping
EDGE_PX = 1.5              # a line this close to the band's edge may run outside it
LOST_COLUMNS = 0.02        # more than this share of a camera's columns lost since the last frame: re-render

Progress = Callable[[str, int, int], None]


@dataclass
class Plan:
    """q (n, 6); table_rad (n,); cameras to render; predicted_rows (n, 2): lowest and highest
    sensor row of the line in each frame from the ray casts (NaN: none), rendered cameras only."""

    q: np.ndarray
    table_rad: np.ndarray
    cameras: tuple[int, ...]
    predicted_rows: np.ndarray
    warnings: list = field(default_factory=list)


@dataclass
class ScanResult:
    """cloud (table frame); report (the report.json content); files written; per point:
    |error| to the part in µm and whether the point counts as the part's (else the table's)."""

    cloud: object
    report: dict
    files: dict
    error_um: np.ndarray | None = None
    on_part: np.ndarray | None = None


def frame_ranges(indices) -> str:
    """[0, 1, 2, 5, 7, 8] -> '0-2, 5, 7-8' (the first 12 runs)."""
    idx = sorted(int(i) for i in indices)
    runs, start = [], None
    for a, b in zip(idx, idx[1:] + [None]):
        start = a if start is None else start
        if b != a + 1:
            runs.append(f"{start}" if start == a else f"{start}-{a}")
            start = None
    more = f" and {len(runs) - 12} more runs" if len(runs) > 12 else ""
    return ", ".join(runs[:12]) + more


def plan_scan(config: ScanConfig, allow_blind: bool = False) -> Plan:
    """IK for the whole path and the laser footprint check; raises before anything renders.

    ``allow_blind``: frames whose laser meets nothing in range are kept (a step-by-step
    scanner measures nothing there) instead of refusing the path; where no camera sees
    the line on any frame, ``cameras`` is empty and nothing needs rendering."""
    cell = config.cell
    wp = config.waypoints
    sol = solve_path(cell, wp, config.q_start)
    if not sol.ok.all():
        bad = sol.unreachable
        raise UnreachablePose(f"{len(bad)} of {len(wp)} waypoints cannot be reached (frames {frame_ranges(bad)}); "
                              f"first, frame {bad[0]}: {sol.messages[bad[0]]}")
    warnings = []
    if sol.jumps:
        warnings.append(f"joint jumps over {math.degrees(max(sol.max_step_rad)):.0f}° between neighbouring "
                        f"waypoints at frames {frame_ranges(sol.jumps)} (near a singularity or a limit)")
    return plan_frames(config, sol.q, wp.table_rad, allow_blind, warnings)


def plan_frames(config: ScanConfig, q: np.ndarray, table_rad: np.ndarray, allow_blind: bool = False,
                warnings: list | None = None, surfaces: SurfaceCaster | None = None) -> Plan:
    """The plan for frames whose joints are known (q (n, 6), table_rad (n,)): the laser fan cast
    against the part and the table (``surfaces``, built here when not given) for the cameras to
    render and the rows the line can fall on."""
    wp_probe2table = config.cell.probe2table(q, table_rad)
    foot = laser_footprint(config.probe, wp_probe2table, surfaces or cell_surfaces(config))
    warnings = [] if warnings is None else warnings
    n = len(q)
    if foot.empty_frames and not allow_blind:
        z0, z1 = config.probe.z_range_mm
        raise ScannerError(f"{len(foot.empty_frames)} of {n} waypoints put no surface inside the probe's "
                           f"range {z0:.0f}-{z1:.0f} mm (frames {frame_ranges(foot.empty_frames)}): "
                           "move the path closer to or farther from the part")
    cameras = foot.cameras_needed() if config.leave_out.skip_blind_cameras or allow_blind else (0, 1)
    if not cameras and not allow_blind:
        raise ScannerError("neither camera sees the laser line anywhere on the path (hidden or off the sensors)")
    predicted = np.full((n, 2), np.nan)
    if cameras:
        with np.errstate(all="ignore"), catch_warnings():
            simplefilter("ignore", RuntimeWarning)  # frames no camera sees: NaN, as meant
            rows = foot.rows[:, list(cameras)]
            predicted = np.column_stack([np.nanmin(rows[:, :, 0], axis=1), np.nanmax(rows[:, :, 1], axis=1)])
    return Plan(np.asarray(q, dtype=np.float64), np.asarray(table_rad, dtype=np.float64), cameras, predicted,
                warnings)


def cell_surfaces(config: ScanConfig) -> SurfaceCaster:
    """What the laser can meet in a scan: the part and the table top, ready for ray casts."""
    return SurfaceCaster([config.workpiece.mesh, table_top_mesh()])


class _Band:
    """The rows to render next: where the line was in the last frame, widened by a margin that
    follows its motion, joined with where the plan's ray casts put it in the coming frames."""

    def __init__(self, rows_px: int, margin_px: int, chunk: int, predicted: np.ndarray):
        self.H, self.margin, self.chunk = rows_px, margin_px, chunk
        self.predicted = predicted
        self.last: tuple[float, float] | None = None
        self.speed = 0.0

    def rows(self, first: int, count: int) -> tuple[int, int] | None:
        """Band for frames first..first+count−1 (0-based path indices); None: all rows."""
        lo, hi = [], []
        if self.last is not None:
            m = self.margin + self.speed * count
            lo.append(self.last[0] - m)
            hi.append(self.last[1] + m)
        pred = self.predicted[first:first + count]
        if np.isfinite(pred).any():
            lo.append(np.nanmin(pred[:, 0]) - self.margin)
            hi.append(np.nanmax(pred[:, 1]) + self.margin)
        if not lo:
            return None
        r0 = max(0, int(math.floor(min(lo))))
        r1 = min(self.H, int(math.ceil(max(hi))) + 1)
        return None if r1 - r0 >= BAND_FULL_SHARE * self.H else (r0, r1)

    def update(self, extent: tuple[float, float] | None) -> None:
        if extent is None:
            self.last, self.speed = None, 0.0
            return
        if self.last is not None:
            self.speed = max(abs(extent[0] - self.last[0]), abs(extent[1] - self.last[1]))
        self.last = extent


def _line_extent(lines) -> tuple[float, float] | None:
    rows = np.concatenate([ln.row[ln.valid] for ln in lines if ln is not None] or [np.zeros(0)])
    return (float(rows.min()), float(rows.max())) if rows.size else None


def _needs_full_frame(lines, rows, previous_rows, rows_px: int, margin_px: int) -> bool:
    """Whether a band render may have cut the line: it touches an inner edge of the band, or
    columns lost it whose line, in the previous frame, sat outside or near the band's edge
    (columns that lose the line well inside the band lost it for a real reason)."""
    if rows is None:
        return False
    low_edge, high_edge = rows[0] > 0, rows[1] < rows_px
    for cam, ln in enumerate(lines):
        if ln is None:
            continue
        r = ln.row[ln.valid]
        if r.size and ((low_edge and r.min() < rows[0] + EDGE_PX) or (high_edge and r.max() > rows[1] - 1 - EDGE_PX)):
            return True
        # A peak on the band's first or last row may be the flank of a line the band cut;
        # an edge elsewhere (the line cut by a depth edge of the part) is the scene's own.
        on_band_edge = (low_edge & (ln.peak_row <= rows[0])) | (high_edge & (ln.peak_row >= rows[1] - 1))
        if np.any((ln.code == LineCode.EDGE) & on_band_edge):
            return True
        prev = previous_rows[cam]
        if prev is None:
            continue
        lost = np.isfinite(prev) & ~ln.valid
        near = ((low_edge & (prev < rows[0] + margin_px)) | (high_edge & (prev > rows[1] - 1 - margin_px)))
        if np.sum(lost & near) > max(2, LOST_COLUMNS * len(ln.col)):
            return True
    return False


def run_scan(config: ScanConfig, out_dir: str | Path | None, scene=None, progress: Progress | None = None,
             write_outputs: bool = True) -> ScanResult:
    """Scan as configured; write cloud.ply, report.json and preview.png into ``out_dir``.

    ``scene``: build the cell there (the Blender UI passes its own); None resets
    Blender to an empty scene first (headless). Nothing is written unless the whole
    scan succeeds. A shorthand for ``Scanner(config=config).run()`` and its ``result``.
    """
    from .scanner import Scanner

    scanner = Scanner(config=config, scene=scene)
    scanner.run(progress)
    return scanner.result(out_dir if write_outputs else None)


class ScanRun:
    """A scan in steps, for callers that must stay responsive (the Blender panel's modal
    operator): construct (plans and builds; raises on refusal), call :meth:`step` until it
    returns True (one chunk of frames each), then :meth:`finish`. Dropping the object
    before :meth:`finish` discards everything; nothing has been written."""

    def __init__(self, config: ScanConfig, scene=None, progress: Progress | None = None, keep_images: bool = False,
                 *, plan: Plan | None = None, frames: range | None = None, scene_cell=None,
                 threads: int | None = None):
        """``plan``: the whole path's plan when it was made already (a farm's coordinator
        plans once for all shards); ``frames``: the part of the path to scan (path
        indices; the cloud keeps those indices); ``scene_cell``: a cell built earlier for
        this config, reused (a farm worker builds once for all its shards); ``threads``:
        render threads (None: all cores)."""
        self.config = config
        # keep_images: {frame index in the path: the two cameras' sensor images (band or full)}, for pictures
        self.images: dict[int, list] | None = {} if keep_images else None
        self.timing: dict[str, float] = {}
        self.t_all = time.perf_counter()
        self.progress = progress or (lambda stage, done, total: None)

        t = time.perf_counter()
        self.plan = plan_scan(config) if plan is None else plan  # refusals come before Blender is loaded
        self.timing["plan"] = time.perf_counter() - t
        total = len(self.plan.q)
        frames = range(total) if frames is None else frames
        if not (frames.step == 1 and 0 <= frames.start < frames.stop <= total):
            raise InputError(f"frames {frames.start}..{frames.stop - 1} are not a part of the {total}-frame path")
        a, b = frames.start, frames.stop
        self.first = a

        from .scene.cell import build_cell
        from .scene.laser import laser_power_w
        from .scene.session import new_scene

        t = time.perf_counter()
        probe = config.probe
        if scene_cell is None:
            if scene is None:
                scene = new_scene(config.render.device)
            scene_cell = build_cell(scene, config.cell, probe, config.workpiece, config.render.laser,
                                    laser_power_w(probe, peak=config.render.laser_peak), material=config.material,
                                    roughness=config.roughness)
        self.sc = scene_cell
        # The frames either side are keyframed too, so that motion during the exposure
        # (linear between keys) is the same whatever part of the path is scanned.
        lo, hi = max(0, a - 1), min(total, b + 1)
        keyed = self.sc.keyframe(self.plan.q[lo:hi], self.plan.table_rad[lo:hi])
        self.frames = range(keyed.start + a - lo, keyed.start + b - lo)
        self.settings = replace(render_settings(config), threads=threads)
        self.timing["scene"] = time.perf_counter() - t
        self.n = b - a
        self.acc = CloudAccumulator()
        self.probe2table = config.cell.probe2table(self.plan.q[a:b], self.plan.table_rad[a:b])
        self.band = _Band(probe.rows_px, config.leave_out.band_margin_px, config.leave_out.chunk_frames,
                          self.plan.predicted_rows[a:b])
        self.stats = new_stats()
        self.t_render = self.t_detect = self.t_tri = 0.0
        self.done = 0
        self.previous_rows: list = [None, None]
        self.frame_codes: dict[int, dict] = {}  # path index -> {detection code: columns}, for step-by-step callers

    @property
    def scene_cell(self):
        return self.sc

    def step(self) -> bool:
        """Render, detect and triangulate the next chunk of frames; True when all are done."""
        if self.done >= self.n:
            return True
        config, probe, plan, sc = self.config, self.config.probe, self.plan, self.sc
        chunk = config.leave_out.chunk_frames
        done = self.done
        size = 1 if done == 0 and not np.isfinite(plan.predicted_rows[self.first]).all() else min(chunk, self.n - done)
        first = self.frames.start + done
        rows = self.band.rows(done, size) if config.leave_out.render_band else None
        hide = config.leave_out.hide_robot
        t = time.perf_counter()
        images = sc.render(first, first + size - 1, self.settings, plan.cameras, rows=rows, leave_out_robot=hide)
        self.t_render += time.perf_counter() - t
        t = time.perf_counter()
        index = self.first + done  # path index of the chunk's first frame
        images = [self._sense(pair, rows, index + i) for i, pair in enumerate(images)]
        lines = [_detect_all(img, rows, config) for img in images]
        self.t_detect += time.perf_counter() - t
        # Frames whose line the band may have cut are rendered again at full height, in one call.
        redo = []
        for i in range(size):
            if _needs_full_frame(lines[i], rows, self.previous_rows, probe.rows_px, config.leave_out.band_margin_px):
                redo.append(i)
            self.previous_rows = [None if ln is None else ln.row for ln in lines[i]]
        if redo:
            t = time.perf_counter()
            full = sc.render(first + redo[0], first + redo[-1], self.settings, plan.cameras, leave_out_robot=hide)
            self.t_render += time.perf_counter() - t
            self.stats["rerendered"] += len(full)
            t = time.perf_counter()
            for i in redo:
                images[i] = self._sense(full[i - redo[0]], None, index + i)
                lines[i] = _detect_all(images[i], None, config)
            self.t_detect += time.perf_counter() - t
        if self.images is not None:
            self.images.update({index + i: images[i] for i in range(size)})
        stats = self.stats
        for i in range(size):
            t = time.perf_counter()
            self.acc.add(_profile(probe, lines[i], config), self.probe2table[done + i], index + i)
            self.t_tri += time.perf_counter() - t
            stats["valid"] += sum(int(ln.valid.sum()) for ln in lines[i] if ln is not None)
            stats["columns"] += sum(len(ln.col) for ln in lines[i] if ln is not None)
            codes: dict[str, int] = {}
            for ln in lines[i]:
                if ln is not None:
                    for name, count in ln.counts().items():
                        stats["codes"][name] = stats["codes"].get(name, 0) + count
                        codes[name] = codes.get(name, 0) + count
            self.frame_codes[index + i] = codes
            stats["band_rows"].append(probe.rows_px if rows is None or i in redo else rows[1] - rows[0])
            self.band.update(_line_extent(lines[i]))
        self.previous_rows = [None if ln is None else ln.row for ln in lines[size - 1]]
        self.done += size
        self.progress("scan", self.done, self.n)
        return self.done >= self.n

    def _sense(self, pair, rows, index: int):
        """What the real sensor makes of each camera's rendered light (unchanged for the ideal sensor)."""
        sensor = self.config.sensor
        if not sensor.changes_images:
            return pair
        row0 = 0 if rows is None else rows[0]
        return [None if img is None else sensor.apply(img, self.config.probe, camera, index, row0)
                for camera, img in enumerate(pair)]

    def finish(self, out_dir: str | Path | None) -> ScanResult:
        """Measure against the truth, build the report and (with ``out_dir``) write the files."""
        self.timing.update(render=self.t_render, detect=self.t_detect, triangulate=self.t_tri)
        used = getattr(self.sc, "device_used", None)
        asked = self.config.render.device
        if asked != "CPU" and used == "CPU" and self.config.render.engine == "cycles":
            self.plan.warnings.append(f"render device {asked} asked for, but no such GPU answered: "
                                      "rendered on the CPU")
        return assemble(self.config, self.plan, self.acc.cloud(), self.stats, self.timing, out_dir, self.t_all,
                        {"render_device": used})


def new_stats() -> dict:
    """Per-scan counters: sensor columns seen and kept, frames re-rendered at full height,
    rows rendered per frame, and columns per detection code."""
    return dict(columns=0, valid=0, rerendered=0, band_rows=[], codes={})


def merge_stats(parts: list[dict]) -> dict:
    """The counters of several parts of one scan (shards), added up."""
    out = new_stats()
    for st in parts:
        out["columns"] += int(st["columns"])
        out["valid"] += int(st["valid"])
        out["rerendered"] += int(st["rerendered"])
        out["band_rows"] += [int(v) for v in st["band_rows"]]
        for name, count in st["codes"].items():
            out["codes"][name] = out["codes"].get(name, 0) + int(count)
    return out


def assemble(config: ScanConfig, plan: Plan, cloud, stats: dict, timing: dict, out_dir: str | Path | None,
             t_start: float, extra: dict | None = None) -> ScanResult:
    """The scan's result from its cloud and counters: error against the truth, the report,
    and (with ``out_dir``) cloud.ply, report.json and preview.png written atomically."""
    probe = config.probe
    timing = dict(timing)
    t = time.perf_counter()
    quality, on_part, error_um = _measure(cloud, config)
    timing["metrics"] = time.perf_counter() - t
    n = int(len(stats["band_rows"]))
    scan_time = timing.get("render", 0.0) + timing.get("detect", 0.0) + timing.get("triangulate", 0.0)
    r = config.render
    report = {
        "config": {"name": config.name, "file": config.source, "robot": config.robot.name, "probe": probe.name,
                   "sensor_px": [probe.cols_px, probe.rows_px], "workpiece": config.workpiece.source,
                   "engine": r.engine, "samples": r.samples, "detect": config.detect_method,
                   "triangulate": config.triangulate_method, "fuse": config.fuse,
                   "sensor": "ideal" if config.sensor.ideal else _effects(config.sensor),
                   "material": config.material},
        "frames": n,
        "points": len(cloud),
        "valid_fraction": stats["valid"] / max(stats["columns"], 1),
        "column_codes": stats["codes"],
        "cameras_rendered": list(plan.cameras),
        "frames_rerendered_full": stats["rerendered"],
        "mean_rows_rendered": float(np.mean(stats["band_rows"])) if stats["band_rows"] else 0.0,
        "time_s": {k: round(v, 4) for k, v in timing.items()},
        "profiles_per_s": n / scan_time if scan_time > 0 else float("inf"),
        **quality,
        "warnings": plan.warnings,
        "software": {"python": platform.python_version(), "numpy": np.__version__, "opencv": cv2.__version__},
        **(extra or {}),
    }
    files = {}
    if out_dir is not None:
        t = time.perf_counter()
        files = _write_outputs(Path(out_dir), cloud, report, config, on_part, error_um)
        report["time_s"]["write"] = round(time.perf_counter() - t, 4)
    report["time_s"]["total"] = round(time.perf_counter() - t_start, 4)
    if files:
        write_bytes_atomic(files["report"], report_json(report).encode())
    return ScanResult(cloud, report, files, error_um, on_part)


def _detect_all(images, rows, config: ScanConfig):
    """Detections for each camera's image (None where the camera was not rendered), rows in full-image terms."""
    out = []
    for img in images:
        if img is None:
            out.append(None)
            continue
        line = detect_line(img, config.detect_method, config.detect_params, 0 if rows is None else rows[0])
        if rows is not None:  # the image holds rows r0..r1−1 of the sensor; its rows are the sensor's
            line.shape = (config.probe.rows_px, config.probe.cols_px)
            # (A peak on the band's first or last row is coded EDGE; the caller re-renders
            # such frames at full height: see _needs_full_frame.)
        out.append(line)
    return out


def render_settings(config: ScanConfig) -> RenderOptions:
    """The render options of a config: its [render] table, adjusted for the sensor model."""
    return with_sensor(config.render, config.sensor)


def with_sensor(settings, sensor):
    """``settings`` (a RenderOptions) with the sensor model's render-side effects: pixel
    area integration (box filter of one pixel, enough samples to fill it) and motion
    during the exposure (the shutter open for exposure × frame rate of each frame)."""
    samples, pixel_filter, width = settings.samples, settings.pixel_filter, settings.filter_width_px
    if sensor.integrate_pixels:
        samples, pixel_filter, width = max(samples, 16), "BOX", 1.0
    shutter = sensor.shutter_fraction if sensor.motion_blur else 0.0
    if shutter > 0:
        samples = max(samples, 16)
    return replace(settings, samples=samples, pixel_filter=pixel_filter, filter_width_px=width,
                   motion_blur_shutter=shutter)


def _effects(sensor) -> list[str]:
    names = ("integrate_pixels", "saturate", "noise", "speckle", "defocus", "motion_blur")
    return [n for n in names if getattr(sensor, n)] + (["distortion"] if sensor.distortion else [])


def _profile(probe, lines, config: ScanConfig):
    sensor = config.sensor
    if sensor.distortion and sensor.undistort:  # a calibrated probe removes its lens distortion
        undone = []
        for ln in lines:
            if ln is None:
                undone.append(None)
                continue
            ok = ln.valid
            u, v = ln.col.astype(np.float64), ln.row.copy()
            u[ok], v[ok] = sensor.undistort_pixels(probe, u[ok], v[ok])
            undone.append(replace(ln, col=u, row=v))
        lines = undone
    profs = [filter_profile(triangulate_profile(probe, ln, cam, config.triangulate_method), config.profile_filter)
             for cam, ln in enumerate(lines) if ln is not None]
    if len(profs) == 2 and config.fuse:
        return fuse_profiles(*profs)
    if len(profs) == 2:
        merged = profs[0].take(np.ones(len(profs[0]), bool))
        other = profs[1]
        merged.points = np.concatenate([merged.points, other.points])
        for name in ("col", "camera", "angle_rad", "sigma_mm"):
            setattr(merged, name, np.concatenate([getattr(merged, name), getattr(other, name)]))
        return merged
    return profs[0]


def _measure(cloud, config: ScanConfig) -> tuple[dict, np.ndarray, np.ndarray]:
    """Error against the truth: points nearer the part count as the part's, the rest as the table's.

    Returns (report entries, on_part (n,) bool, |error| (n,) µm to the part)."""
    wp = config.workpiece
    P = cloud.points
    if len(P) == 0:
        return ({"points_on_part": 0, "points_on_table": 0, "error_um": metrics.error_stats([]).as_dict(),
                 "table_error_um": metrics.error_stats([]).as_dict(), "coverage": 0.0,
                 "coverage_tolerance_mm": config.coverage_tolerance_mm}, np.zeros(0, bool), np.zeros(0))
    d_part, s_part = metrics.distances(P, wp.truth)
    radial = np.hypot(P[:, 0], P[:, 1])
    d_table = np.where(radial <= TABLE_RADIUS_MM, np.abs(P[:, 2]), np.inf)
    on_part = d_part <= d_table
    part = metrics.error_stats(d_part[on_part], None if s_part is None else s_part[on_part])
    table = metrics.error_stats(d_table[~on_part], P[~on_part, 2])
    coverage = metrics.coverage(P[on_part], wp.mesh, config.coverage_tolerance_mm)
    return ({"points_on_part": int(on_part.sum()), "points_on_table": int((~on_part).sum()),
             "error_um": part.as_dict(), "table_error_um": table.as_dict(), "coverage": coverage,
             "coverage_tolerance_mm": config.coverage_tolerance_mm}, on_part, d_part * 1e3)


def _write_outputs(out: Path, cloud, report: dict, config: ScanConfig, on_part, err) -> dict:
    e = report["error_um"]
    title = (f"{config.name}: {len(cloud)} points, RMS {e['rms_um']:.1f} um, p95 {e['p95_um']:.1f} um, "
             f"coverage {report['coverage'] * 100:.0f} %")
    picture = render_preview(config.workpiece.mesh, cloud.points, err, on_part, title)
    files = {"cloud": out / "cloud.ply", "report": out / "report.json", "preview": out / "preview.png"}
    save_ply(cloud, files["cloud"])
    write_png(files["preview"], picture)
    return files
