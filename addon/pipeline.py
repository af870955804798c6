"""The chunk engine under ``Scanner``: a path's frames rendered, detected and triangulated in
chunks (UI operator, command line and farm workers alike).

Stages, each timed: plan (``core.scan.plan``: IK, reach and range, before anything
renders); scene (the Blender cell, the path keyframed); render (chunks of frames, one
render call each, only the band of rows the line can fall on: ``core.scan.band``);
detect and triangulate (``core.scan.frames``); then the result (``core.scan.outputs``:
error against the truth, report, files written atomically at the end). This module is
the only part of a scan that touches Blender.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path
from typing import Callable

import numpy as np

from .core.config.render import RenderOptions, with_sensor
from .core.config.scan import ScanConfig
from .core.errors import InputError
from .core.geometry.cloud import CloudAccumulator
from .core.geometry.workpiece import drawn_mesh
from .core.optics.triangulate import merged_counts
from .core.scan.band import Band, line_extent, needs_full_frame
from .core.scan.frames import add_counts, detect_all, frame_profile, merge_stats, new_stats
from .core.scan.outputs import ScanResult, assemble
from .core.scan.plan import Plan, cell_surfaces, frame_ranges, plan_frames, plan_scan

__all__ = ["Plan", "ScanResult", "ScanRun", "assemble", "build_raycaster", "build_scan_cell", "cell_surfaces", "frame_ranges", "merge_stats", "new_stats",
           "plan_frames", "plan_scan", "render_settings", "run_scan"]

Progress = Callable[[str, int, int], None]

CHUNK_SECONDS = 1.0  # a render call lasts about this long at most (see ScanRun._chunk_size)
RAYCAST_DEVICE = "CPU (Embree ray casting)"
RAYCAST_CHUNK_FRAMES = 32  # frames the raycast engine casts together (about 0.1 s of work)
PIXELS_PER_SECOND = 4e5  # Cycles at one sample on two CPU cores, before the first call has been timed


# Where a scan started without a progress callback reports after each chunk of frames:
# nowhere, unless the process says otherwise. The command line sets its stop requests
# (headless.lifecycle.StopRequests.progress) here, so that a benchmark's scans, which pass
# none, stop at Ctrl-C after the frames being rendered, as a scan does.
_default_progress: Progress | None = None


def set_default_progress(progress: Progress | None) -> None:
    """Report every scan that has no progress callback of its own to ``progress`` (None: to
    nothing); a stop request it raises ends that scan after its current chunk."""
    global _default_progress
    _default_progress = progress


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


def build_raycaster(config: ScanConfig, threads: int | None = None):
    """The raycast engine's renderer for a config: its part and table in one Embree scene;
    ``threads``: cores that cast rays (None: all). ``leave_out.render_band`` off casts every
    pixel instead of the windows around the line."""
    from .core.optics.raycast import RaycastRenderer, cell_raycast_scene

    why = config.raycast_refusal()
    if why:
        raise InputError(f"engine raycast: {why}")
    from .core.scan.plan import table_fixtures

    wp = config.workpiece
    scene = cell_raycast_scene(None if wp is None else drawn_mesh(wp), config.material, threads,
                               fixtures=[f.mesh for f in table_fixtures(config)])
    return RaycastRenderer(config.probe, scene, config.render.laser_peak,
                           windows=config.leave_out.render_band)


def build_scan_cell(config: ScanConfig, scene=None):
    """The Blender cell a config scans in: in ``scene``, or in a new empty scene (headless)."""
    from .scene.cell import build_cell
    from .core.optics.laser_profile import laser_power_w
    from .scene.session import new_scene

    if scene is None:
        scene = new_scene(config.render.device)
    from .core.scan.plan import table_fixtures

    return build_cell(scene, config.cell, config.probe, config.workpiece, config.render.laser,
                      laser_power_w(config.probe, peak=config.render.laser_peak), material=config.material,
                      roughness=config.roughness, fixtures=table_fixtures(config))


class ScanRun:
    """A scan in steps, for callers that must stay responsive (the Blender panel's modal
    operator): construct (plans and builds; raises on refusal), call :meth:`step` until it
    returns True (one chunk of frames each), then :meth:`finish`. Dropping the object
    before :meth:`finish` discards everything; nothing has been written."""

    def __init__(self, config: ScanConfig, scene=None, progress: Progress | None = None, keep_images: bool = False,
                 *, plan: Plan | None = None, frames: range | None = None, scene_cell=None,
                 threads: int | None = None, raycaster=None):
        """``plan``: the whole path's plan when it was made already (a farm's coordinator
        plans once for all shards); ``frames``: the part of the path to scan (path
        indices; the cloud keeps those indices); ``scene_cell``: a cell built earlier for
        this config, reused (a farm worker builds once for all its shards); ``threads``:
        render threads (None: all cores); ``raycaster``: with engine raycast, the renderer
        built earlier for this config (``build_raycaster``), reused. The raycast engine needs
        no Blender: ``scene_cell`` is then only kept for the caller."""
        self.config = config
        # keep_images: {frame index in the path: the two cameras' sensor images (band or full)}, for pictures
        self.images: dict[int, list] | None = {} if keep_images else None
        self.timing: dict[str, float] = {}
        self.t_all = time.perf_counter()
        self.progress = progress or _default_progress or (lambda stage, done, total: None)

        t = time.perf_counter()
        self.plan = plan_scan(config) if plan is None else plan  # refusals come before Blender is loaded
        self.timing["plan"] = time.perf_counter() - t
        total = len(self.plan.q)
        frames = range(total) if frames is None else frames
        if not (frames.step == 1 and 0 <= frames.start < frames.stop <= total):
            raise InputError(f"frames {frames.start}..{frames.stop - 1} are not a part of the {total}-frame path")
        a, b = frames.start, frames.stop
        self.first = a

        t = time.perf_counter()
        probe = config.probe
        self.raycaster = None
        if config.render.engine == "raycast":
            self.raycaster = raycaster if raycaster is not None else build_raycaster(config, threads)
            self.sc = scene_cell
            self.frames = range(a, b)
        else:
            self.sc = scene_cell if scene_cell is not None else build_scan_cell(config, scene)
            # The frames either side are keyframed too, so that motion during the exposure
            # (linear between keys) is the same whatever part of the path is scanned; and each
            # at its own frame number in the path, as Cycles' motion-blur samples depend on the
            # frame's number (a shard keyed from frame 1 gave points up to 0.86 µm away).
            lo, hi = max(0, a - 1), min(total, b + 1)
            keyed = self.sc.keyframe(self.plan.q[lo:hi], self.plan.table_rad[lo:hi], first_frame=lo + 1,
                                     **path_motion(config, total, lo, hi))
            self.frames = range(keyed.start + a - lo, keyed.start + b - lo)
        self.settings = replace(render_settings(config), threads=threads)
        self.timing["scene"] = time.perf_counter() - t
        self.n = b - a
        self.acc = CloudAccumulator()
        self.probe2table = config.cell.probe2table(self.plan.q[a:b], self.plan.table_rad[a:b])
        # Rows around the line: the leave-out's margin, and what the sensor's optics spread beyond it.
        self.margin = config.leave_out.band_margin_px + config.sensor.spread_px(probe)
        # A sensor that changes images is read, in each frame, on that frame's own rows (the
        # plan's prediction and the margin: _own_rows), rendered with the rows its optics reach
        # beyond them: so a frame's image, and its points, do not depend on the frames rendered
        # with it (a shard's band, which starts without history, gave 114 of 350 points apart).
        self.sensor_pad = config.sensor.band_pad_px(probe) if config.sensor.changes_images else 0
        self.band = Band(probe.rows_px, self.margin + self.sensor_pad, config.leave_out.chunk_frames,
                         self.plan.predicted_rows[a:b])
        self.stats = new_stats()
        self.t_render = self.t_detect = self.t_tri = 0.0
        self.done = 0
        self.previous_rows: list = [None, None]
        self.rendered_rows: list | None = None  # the last chunk's rows rendered per frame, where not the rows read
        self.frame_codes: dict[int, dict] = {}  # path index -> {detection code: columns}, for step-by-step callers

    @property
    def scene_cell(self):
        return self.sc

    def step(self) -> bool:
        """Render, detect and triangulate the next chunk of frames; True when all are done."""
        if self.done >= self.n:
            return True
        size = 1 if self.done == 0 and not np.isfinite(self.plan.predicted_rows[self.first]).all() else \
            min(self._chunk_size(), self.n - self.done)
        if self.raycaster is not None:
            images, lines, rows = self._raycast(size)
        else:
            images, lines, rows = self._render(size)
        index = self.first + self.done  # path index of the chunk's first frame
        if self.images is not None:
            self.images.update({index + i: images[i] for i in range(size)})
        self._accumulate(size, lines, rows)
        self.progress("scan", self.done, self.n)
        return self.done >= self.n

    def _raycast(self, size: int):
        """The chunk's images from the raycast engine (each frame's band of rows its own), their lines."""
        config, done = self.config, self.done
        index = self.first + done
        t = time.perf_counter()
        frames = self.raycaster.render_frames(self.probe2table[done:done + size], self.plan.cameras)
        if config.sensor.changes_images:
            # The sensor's noise lands on dark rows too, and the detector reads the noise off
            # rows away from the line: give it as many around the line as a Cycles band has.
            pad = config.detect_params.window_px + self.margin
            frames = [_padded(pair, band, pad, config.probe.rows_px) for pair, band in frames]
        self.t_render += time.perf_counter() - t
        t = time.perf_counter()
        images = [self._sense(pair, band, index + i) for i, (pair, band) in enumerate(frames)]
        rows = [band for _, band in frames]
        lines = [detect_all(pair, band, config) for pair, band in zip(images, rows)]
        self.t_detect += time.perf_counter() - t
        return images, lines, rows

    def _render(self, size: int):
        """The chunk's images from Blender (one render call, one band of rows for all frames;
        frames whose line the band may have cut rendered again at full height), their lines."""
        config, probe, plan, sc = self.config, self.config.probe, self.plan, self.sc
        done = self.done
        first = self.frames.start + done
        rows = self.band.rows(done, size) if config.leave_out.render_band else None
        hide = config.leave_out.hide_robot
        t = time.perf_counter()
        images = sc.render(first, first + size - 1, self.settings, plan.cameras, rows=rows, leave_out_robot=hide)
        self.t_render += time.perf_counter() - t
        t = time.perf_counter()
        index = self.first + done  # path index of the chunk's first frame
        rendered = images
        frame_rows = [self._own_rows(index + i, rows) for i in range(size)]
        own_rows = self._reads_own_rows()
        self.rendered_rows = [rows] * size  # (the report's rows rendered, beside the rows read)
        # A sensor that changes images is applied to each frame's own rows and the pad its
        # optics need (its auto-exposure then meters those rows alone, not a glint elsewhere in
        # the chunk's band), and the frame is read on its own rows.
        images = [self._sense_rows(pair, rows, own, index + i) for i, (pair, own) in enumerate(zip(images, frame_rows))]
        lines = [detect_all(img, own, config) for img, own in zip(images, frame_rows)]
        self.t_detect += time.perf_counter() - t
        # Frames whose line the band may have cut are read again at full height: rendered again
        # in one call, or, where the call rendered them whole, read off that render.
        redo = []
        # (A frame read on its own rows decides from itself alone, not from the frame before:
        # a shard's first frame has none.)
        previous = [None, None] if own_rows else self.previous_rows
        for i in range(size):
            if needs_full_frame(lines[i], frame_rows[i], previous, probe.rows_px, self.margin):
                redo.append(i)
            if not own_rows:
                previous = [None if ln is None else ln.row for ln in lines[i]]
        again = [i for i in redo if rows is not None]
        full = {}
        if again:
            t = time.perf_counter()
            calls = sc.render(first + again[0], first + again[-1], self.settings, plan.cameras, leave_out_robot=hide)
            self.t_render += time.perf_counter() - t
            self.stats["rerendered"] += len(calls)
            full = {i: calls[i - again[0]] for i in again}
        t = time.perf_counter()
        for i in redo:
            images[i] = self._sense(full[i] if i in full else rendered[i], None, index + i)
            lines[i] = detect_all(images[i], None, config)
            frame_rows[i] = self.rendered_rows[i] = None
        self.t_detect += time.perf_counter() - t
        return images, lines, frame_rows

    def _reads_own_rows(self) -> bool:
        """Whether frames are read on their own rows (see _own_rows)."""
        return self.config.sensor.changes_images and self.config.leave_out.render_band

    def _sense_rows(self, pair, rows, own, index: int):
        """The sensor's images of a frame rendered on ``rows`` (None: whole), read on ``own``:
        the sensor applied to ``own`` and the rows its optics reach beyond them, then cut to
        ``own`` (as rendered where the frame is not read on its own rows)."""
        if own == rows:
            return self._sense(pair, rows, index)
        H = self.config.probe.rows_px
        window = (max(0, own[0] - self.sensor_pad), min(H, own[1] + self.sensor_pad))
        sensed = self._sense(_cropped(pair, rows, window), window, index)
        return _cropped(sensed, window, own)

    def _accumulate(self, size: int, lines, rows) -> None:
        """Triangulate the chunk's lines into the cloud and count what was found."""
        probe, config, stats, done = self.config.probe, self.config, self.stats, self.done
        index = self.first + done
        for i in range(size):
            t = time.perf_counter()
            profile = frame_profile(probe, lines[i], config)
            add_counts(stats["points"], profile.masked)
            self.acc.add(profile, self.probe2table[done + i], index + i)
            self.t_tri += time.perf_counter() - t
            stats["valid"] += sum(int(ln.valid.sum()) for ln in lines[i] if ln is not None)
            stats["columns"] += sum(len(ln.col) for ln in lines[i] if ln is not None)
            codes = merged_counts(*(ln.counts() for ln in lines[i] if ln is not None))
            add_counts(stats["codes"], codes)
            self.frame_codes[index + i] = codes
            rendered = self.rendered_rows[i] if self.rendered_rows is not None else rows[i]
            stats["band_rows"].append(probe.rows_px if rendered is None else rendered[1] - rendered[0])
            self.band.update(line_extent(lines[i]))
        self.previous_rows = [None if ln is None else ln.row for ln in lines[size - 1]]
        self.done += size

    def _chunk_size(self) -> int:
        """Frames in the next render call: the config's chunk, fewer where that would take
        longer than CHUNK_SECONDS (judged from the frames rendered so far, or before the
        first call from the pixels it would render), so that a stop (Ctrl-C, the panel's Esc)
        takes effect within about that time."""
        chunk = self.config.leave_out.chunk_frames
        if self.raycaster is not None:
            # The config's chunk is a render call's (Blender's fixed cost per call); the raycast
            # engine casts a chunk in one go per step, and a few milliseconds a frame let it take more.
            chunk = max(chunk, RAYCAST_CHUNK_FRAMES)
        if self.done:
            per_frame = self.t_render / self.done
        elif self.config.render.engine == "eevee":
            # Eevee's first call compiles its shaders (21 s on a GPU) and, without one, renders
            # through software OpenGL at seconds a frame, and it gives Python no chance to stop
            # it meanwhile: one frame first, then the rate measured on it.
            return 1
        else:
            rows = self.band.rows(0, chunk) if self.config.leave_out.render_band else None
            height = self.config.probe.rows_px if rows is None else rows[1] - rows[0]
            per_frame = self.config.probe.cols_px * height * len(self.plan.cameras) / PIXELS_PER_SECOND
        return max(1, min(chunk, int(CHUNK_SECONDS / max(per_frame, 1e-9))))

    def _own_rows(self, index: int, rows):
        """The rows a frame's sensor image is read on: for a sensor that changes images, the
        frame's own band (its predicted rows and the margin), wherever the render call's band
        (``rows``, None: the full frame) holds those rows and the pad its optics need beyond
        them; otherwise, and where the plan predicts no rows, the call's band as rendered."""
        if not self._reads_own_rows():
            return rows
        pred = self.plan.predicted_rows[index]
        if not np.isfinite(pred).all():
            return rows
        H = self.config.probe.rows_px
        own = (max(0, int(math.floor(pred[0])) - self.margin), min(H, int(math.ceil(pred[1])) + self.margin + 1))
        r0, r1 = (0, H) if rows is None else rows
        exact = ((own[0] - self.sensor_pad >= r0 or r0 == 0) and (own[1] + self.sensor_pad <= r1 or r1 == H)
                 and own[0] >= r0 and own[1] <= r1 and own[1] > own[0])
        return own if exact else rows

    def _sense(self, pair, rows, index: int):
        """What the real sensor makes of each camera's rendered light (unchanged for the ideal sensor)."""
        sensor = self.config.sensor
        if not sensor.changes_images:
            return pair
        row0 = 0 if rows is None else rows[0]
        # Each frame's noise and speckle are drawn for its number in the whole path: a scan of
        # frames 5:10 gives frame 5 what the whole scan gives it, not frame 0's grain again.
        numbers = path_numbers(self.config, len(self.plan.q))
        frame = int(numbers[index]) if numbers is not None else index
        return [None if img is None else sensor.apply(img, self.config.probe, camera, frame, row0)
                for camera, img in enumerate(pair)]

    def stage_times(self) -> dict[str, float]:
        """Seconds spent so far rendering, detecting and triangulating (the report's stages)."""
        return {"render": self.t_render, "detect": self.t_detect, "triangulate": self.t_tri}

    def finish(self, out_dir: str | Path | None) -> ScanResult:
        """Measure against the truth, build the report and (with ``out_dir``) write the files."""
        self.timing.update(self.stage_times())
        return assemble(self.config, self.plan, self.acc.cloud(), self.stats, self.timing, out_dir, self.t_all,
                        {"render_device": self.render_device})

    @property
    def render_device(self) -> str | None:
        """What rendered the frames: the raycast engine, or the Blender cell's last render device."""
        return render_device(self.raycaster, self.sc)


def render_device(raycaster, scene_cell) -> str | None:
    """The report's render device: the raycast engine's, or the Blender cell's last one (None
    before it rendered)."""
    return RAYCAST_DEVICE if raycaster is not None else getattr(scene_cell, "device_used", None)


def _cropped(pair, rows, own):
    """Band images (rows ``rows``, None: the full frame) cut to the rows ``own``."""
    if own == rows:
        return pair
    r0 = 0 if rows is None else rows[0]
    return [None if img is None else img[own[0] - r0:own[1] - r0] for img in pair]


def _padded(pair, band: tuple[int, int], pad: int, rows_px: int):
    """Band images (None where a camera was not rendered) with ``pad`` dark rows added above and
    below (within the sensor), and their new band."""
    r0, r1 = max(0, band[0] - pad), min(rows_px, band[1] + pad)
    out = []
    for img in pair:
        if img is None:
            out.append(None)
            continue
        big = np.zeros((r1 - r0,) + img.shape[1:], dtype=img.dtype)
        big[band[0] - r0:band[1] - r0] = img
        out.append(big)
    return out, (r0, r1)


def path_motion(config: ScanConfig, total: int, lo: int, hi: int) -> dict:
    """What motion blur needs of frames lo..hi−1 of a ``total``-frame plan: each one's path
    entry and its number in the whole path (a scan of every tenth frame blurs one frame's
    motion, not ten's)."""
    wp = config.waypoints
    segments = wp.segment[lo:hi] if len(wp) == total else None
    numbers = path_numbers(config, total)
    return {"segments": segments, "path_frames": None if numbers is None else numbers[lo:hi]}


def path_numbers(config: ScanConfig, total: int):
    """Each of a ``total``-frame plan's frames' number in the whole path (config.path_frames),
    or None where the config numbers none or another plan (consecutive from 0)."""
    numbers = config.path_frames
    return numbers if numbers is not None and len(numbers) == total else None


def render_settings(config: ScanConfig) -> RenderOptions:
    """The render options of a config: its [render] table, adjusted for the sensor model."""
    return with_sensor(config.render, config.sensor)
