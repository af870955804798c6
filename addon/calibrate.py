"""Calibrating the simulated probe in its cell, as a lab calibrates a real one.

    from addon.calibrate import calibrate
    run = calibrate("demo", "out/calibration", views=20)   # renders, solves, writes
    run.fit.probe            # the probe carrying its calibration (triangulates with it)
    run.summary["camera0"]["reprojection_error_px"]

A ChArUco board lies on the table in place of the part. The robot shows it to the probe
from ``views`` poses (proposed by ``core.calibration.board_views``; poses the robot cannot
reach or that collide are left out before anything renders). At each pose both cameras
take two images: the board under the room light with the laser off, and the plate's plain
white side with the laser on and the room dark. The images go through the config's sensor
model (noise, distortion, ... when it is realistic) and the config's line detector; then
``core.calibration.calibrate_probe`` solves. Written into the output folder (all files or
none): ``probe.toml`` (the probe rig with a ``[calibration]`` table: a scan config takes
it as ``[probe] calibration = ".../probe.toml"``), ``calibration.json`` (reprojection
errors, standard deviations, every parameter's deviation from the truth, what the
deviations do to the points) and ``calibration.png`` (the corners found on each view).
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .core.calibration import BoardView, ChArUcoBoard, board2table, board_for, board_views, calibrate_probe
from .core.calibration import deviations, triangulation_error
from .core.calibration.solve import MIN_CORNERS, MIN_VIEWS
from .core.config.rigs import probe_toml
from .core.config.scan import ScanConfig, load_scan_config
from .core.errors import CalibrationError, CollisionError, check_whole
from .core.files import check_output_folder, png_bytes, write_set
from .core.geometry.workpiece import Workpiece
from .core.kinematics.path import Waypoints, solve_path
from .core.kinematics.transforms import rigid_inverse

FILES = ("probe.toml", "calibration.json", "calibration.png")
BOARD_SAMPLES = 32      # samples per pixel of the board images: a one-pixel box filter, integrated
CHUNK_PIXELS = 200_000  # sensor pixels per render call of the calibration images (both cameras render each)
CLIPPED_SHARE = 0.5     # a board image at least this clipped where the board went unfound: an exposure hint
ROOM_LIGHT = 0.7        # world strength for the board images: the white print at about 0.6 of full scale


@dataclass
class CalibrationRun:
    fit: object                 # core.calibration.ProbeFit
    summary: dict               # what calibration.json holds
    files: dict                 # name -> path (empty without an output folder)


def _board_workpiece(board: ChArUcoBoard) -> Workpiece:
    import trimesh

    w, h = board.plate_mm
    slab = trimesh.creation.box((w, h, board.thickness_mm))
    slab.apply_translation((0.0, 0.0, 0.5 * board.thickness_mm))
    return Workpiece("calibration board", slab, slab, "calibration board")


def plan_views(config: ScanConfig, board: ChArUcoBoard, views: int, poses=None):
    """(joints (n, 6), probe poses in the table frame (n, 4, 4), views left out with why):
    the views (``poses``, else ``views`` proposed ones) the robot reaches without a collision,
    in order, each solved from the one before. Raises CalibrationError when fewer than the
    calibration needs are left."""
    from .core.kinematics.transforms import check_transform
    from .core.scan.plan import check_motion

    if poses is None:
        targets = board_views(board, config.probe.z_range_mm, views)
    else:
        try:
            targets = np.asarray(poses, dtype=np.float64)
        except (TypeError, ValueError):
            raise CalibrationError("calibration poses must be (n, 4, 4) probe poses (numbers), got "
                                   f"{type(poses).__name__} {str(poses)[:60]!r}") from None
        if targets.ndim != 3 or targets.shape[1:] != (4, 4):
            raise CalibrationError(f"calibration poses must be (n, 4, 4) probe poses, got shape {targets.shape}")
        for k, T in enumerate(targets):
            check_transform(T, f"calibration view {k}")
        views = len(targets)
    if views < MIN_VIEWS:
        raise CalibrationError(f"{views} board view{'s' * (views != 1)} given; a calibration needs at least {MIN_VIEWS}"
                               + (" (give more [[view]] tables)" if poses is not None else ""))
    # The part and the table's fixtures make way for the board; the world's (a wall, a fence)
    # stay where they are, and a view that runs the robot into one is left out.
    cfg = replace(config, workpiece=_board_workpiece(board),
                  fixtures=tuple(f for f in config.fixtures if f.on != "table"))
    q_prev = np.asarray(config.q_start if config.q_start is not None else
                        np.clip(np.zeros(6), config.robot.q_min_rad, config.robot.q_max_rad), dtype=np.float64)
    kept_q, kept_T, dropped = [], [], []
    for k, T in enumerate(targets):
        sol = solve_path(cfg.cell, Waypoints(T[None], np.zeros(1), np.zeros(1, int)), q_prev)
        if not sol.ok.all():
            dropped.append((k, "unreachable: " + sol.messages[0]))
            continue
        q = np.asarray(sol.q, dtype=np.float64)
        try:
            check_motion(cfg, q, np.zeros(1), None, q_prev, 0.0, nearest=False)
        except CollisionError as exc:
            dropped.append((k, f"collision: {exc}"))
            continue
        kept_q.append(q[0])
        kept_T.append(T)
        q_prev = q[0]
    if len(kept_q) < MIN_VIEWS:
        why = f"; first refusal (view {dropped[0][0]}): {dropped[0][1]}" if dropped else ""
        raise CalibrationError(f"only {len(kept_q)} of {views} board views can be reached without a collision "
                               f"({len(dropped)} left out); a calibration needs at least {MIN_VIEWS}{why}")
    return np.array(kept_q), np.array(kept_T), dropped


def calibrate(config: ScanConfig | str | Path, out_dir: str | Path | None = None, *, views: int = 20,
              board: ChArUcoBoard | None = None, distortion: bool | None = None, poses=None,
              progress=None, scene=None) -> CalibrationRun:
    """Calibrate the config's probe (see the module's text). ``distortion``: fit lens
    distortion (default: where the config's sensor has it); ``poses``: the views the user
    chose, (n, 4, 4) probe poses in the table frame (``core.calibration.load_views`` reads
    them from a file), instead of ``views`` proposed ones; ``progress(stage, done, total)``."""
    from .scanner import drain

    return drain(calibrate_steps(config, out_dir, views=views, board=board, distortion=distortion, poses=poses,
                                 progress=progress, scene=scene))


def calibrate_steps(config: ScanConfig | str | Path, out_dir: str | Path | None = None, *, views: int = 20,
                    board: ChArUcoBoard | None = None, distortion: bool | None = None, poses=None,
                    progress=None, scene=None):
    """:func:`calibrate` as a generator, for the panel (Esc drops it): yields (images rendered,
    images in all) after planning and after each render call; returns the CalibrationRun.
    Dropped, it writes nothing and takes the board out of the scene again."""
    t0 = time.perf_counter()
    progress = progress or (lambda stage, done, total: None)
    cfg = config if isinstance(config, ScanConfig) else load_scan_config(config, path_required=False)
    check_whole(views, "board views", 1, 1000)
    if out_dir is not None:
        check_output_folder(out_dir, FILES)
    truth = replace(cfg.probe, calibration=None)
    cfg = replace(cfg, probe=truth)
    if board is not None and not isinstance(board, ChArUcoBoard):
        raise CalibrationError(f"board must be a ChArUcoBoard (core.calibration.board_for(probe) gives the probe's), "
                               f"got {type(board).__name__}")
    if distortion is not None and not isinstance(distortion, (bool, np.bool_)):
        raise CalibrationError(f"distortion must be True, False or None (the config's sensor decides), got "
                               f"{distortion!r}")
    board = board or board_for(truth)
    sensor = cfg.sensor
    distortion = bool(sensor.distortion) if distortion is None else bool(distortion)
    q, poses, dropped = plan_views(cfg, board, views, poses)
    progress("plan", len(q), len(poses) + len(dropped))
    yield 0, 2 * len(q)

    images, lines = yield from _render(cfg, board, q, progress, scene)
    flange2base = cfg.cell.robot.fk(q) @ rigid_inverse(truth.mount)  # the controller's flange poses
    found = []
    for i in range(len(q)):
        det = [board.detect(images[i][c]) for c in (0, 1)]
        found.append(BoardView(flange2base[i], [d[0] for d in det], [d[1] for d in det], lines[i]))
    source = (f"calibrated in the cell of {cfg.name!r}: {len(q)} board views, {board.squares[0]}x{board.squares[1]} "
              f"ChArUco board of {board.square_mm:g} mm squares" + (", lens distortion fitted" if distortion else ""))
    _refuse_clipped_boards(images, found, sensor)
    fit = calibrate_probe(truth, board, found, distortion=distortion, source=source)
    suffix = " (calibrated)"  # once: a calibrated probe calibrated again is not "(calibrated) (calibrated)"
    fit.probe = replace(fit.probe, name=truth.name if truth.name.endswith(suffix) else truth.name + suffix)
    summary = _summary(cfg, board, fit, found, dropped, distortion, time.perf_counter() - t0)
    files = {}
    if out_dir is not None:
        contents = {"probe.toml": probe_toml(fit.probe).encode(),
                    "calibration.json": (json.dumps(summary, indent=2) + "\n").encode(),
                    "calibration.png": png_bytes(_picture(images, found))}
        files = write_set(out_dir, contents)
    return CalibrationRun(fit, summary, files)


def _refuse_clipped_boards(images, found, sensor) -> None:
    """Refuse, naming the exposure, where a camera found the board in too few views for the solve
    and the images it missed it in are mostly clipped (the sensor saturates): there the exposure,
    not the poses, is what to change."""
    if not sensor.clips:
        return
    for c in (0, 1):
        missed = [i for i, view in enumerate(found) if len(view.ids[c]) < MIN_CORNERS]
        if len(found) - len(missed) >= MIN_VIEWS or not missed:
            continue
        clipped = float(np.median([np.mean(np.asarray(images[i][c], float)[..., :3].mean(axis=-1) >= 0.999)
                                   for i in missed]))
        if clipped >= CLIPPED_SHARE:
            raise CalibrationError(
                f"camera {c} found the board in {len(found) - len(missed)} of {len(found)} views (a calibration "
                f"needs at least {MIN_VIEWS}): the images it missed it in are {clipped:.0%} clipped (median); lower "
                f"[sensor] exposure_ms or gain (the board images take exposure_ms as set, auto-exposure or not)")


def _cell_keeping_cloud(cfg: ScanConfig, scene):
    """Build the config's scan cell in ``scene`` (the panel's), keeping the scene's scan cloud:
    rebuilt, a cell drops what it made, the cloud included; unmarked for the rebuild, the cloud
    is kept as an object of the artist's on the turntable, then filed with the results again."""
    import bpy

    from .pipeline import build_scan_cell
    from .scene.cell import CELL_NAME, cell_object
    from .scene.cloud_object import CLOUD_ROLE
    from .scene.ownership import ROLE_KEY, disown, mark, register_made

    cloud = cell_object(CLOUD_ROLE, scene=scene)
    if cloud is None or ROLE_KEY not in cloud:  # none, or a cell from before the marks, which owns all it holds
        return build_scan_cell(cfg, scene)
    disown(bpy.data.collections[CELL_NAME], cloud)
    try:
        sc = build_scan_cell(cfg, scene)
    finally:
        mark(cloud, CLOUD_ROLE)  # the cloud's again, even where the build failed
    for col in list(cloud.users_collection):
        col.objects.unlink(cloud)
    sc.results_collection().objects.link(cloud)
    register_made(sc.root, cloud)
    return sc


def _render(cfg: ScanConfig, board: ChArUcoBoard, q: np.ndarray, progress, scene):
    """Board images (room light, laser off) and laser lines on the plain plate (dark room) per
    view: ([view][camera] images, [view][camera] (m, 2) line pixels). A generator: yields
    (images rendered, images in all) after each render call."""
    from .core.scan.frames import detect_all
    from .pipeline import build_scan_cell, render_settings
    from .scene.ownership import register_made
    from .scene.target import add_board, show_print

    # The cell a scan of the config builds, the scene's cloud kept on its table: the panel's
    # cell is as it was once the calibration is over. Its part and fixtures stay out of the
    # calibration's images (the board takes the part's place).
    sc = _cell_keeping_cloud(cfg, scene) if scene is not None else build_scan_cell(cfg)
    scene = sc.scene
    put_away = [o for o in sc.root.children["Table"].objects if o != sc.table and not o.hide_render]
    plate = add_board(sc.root.children["Table"], board, board2table(board), sc.table)
    register_made(sc.root, plate)
    frames = sc.keyframe(q, np.zeros(len(q)))
    first, last = frames.start, frames.stop - 1
    sensor = cfg.sensor
    laser_settings = render_settings(cfg)
    # The probe stands still for each calibration image: no motion blur from one view to the next.
    board_settings = replace(laser_settings, samples=max(BOARD_SAMPLES, laser_settings.samples), pixel_filter="BOX",
                             filter_width_px=1.0, ambient=ROOM_LIGHT, motion_blur_shutter=0.0)
    for light in sc.laser:
        light.hide_render = True
    # A few frames per render call: progress (and a stop request) between calls, within about
    # a second or two of work each on two cores.
    chunk = max(1, min(len(q), CHUNK_PIXELS // (cfg.probe.rows_px * cfg.probe.cols_px)))

    def render_all(settings, stage, before):
        images = []
        for a in range(first, last + 1, chunk):
            images += sc.render(a, min(a + chunk, last + 1) - 1, settings)
            progress(stage, len(images), len(q))
            yield before + len(images), 2 * len(q)
        return images

    import bpy

    try:
        for obj in put_away:
            obj.hide_render = True
        show_print(plate, True)
        try:
            board_images = yield from render_all(board_settings, "board images", 0)
        finally:
            for light in sc.laser:
                light.hide_render = False
        show_print(plate, False)
        laser_images = yield from render_all(replace(laser_settings, ambient=0.0, motion_blur_shutter=0.0),
                                             "laser images", len(q))
    finally:
        bpy.data.objects.remove(plate, do_unlink=True)  # the cell is the scan's again (Esc too)
        for obj in put_away:
            obj.hide_render = False
    images, lines = [], []
    for i in range(len(q)):
        pair = board_images[i]
        if sensor.changes_images:  # a fixed exposure: auto-exposure meters a laser line, not a lit board
            pair = [sensor.apply(img, cfg.probe, c, 100_000 + i, exposure_ms=sensor.exposure_ms)
                    for c, img in enumerate(pair)]
        images.append(pair)
        lit = laser_images[i]
        if sensor.changes_images:
            lit = [sensor.apply(img, cfg.probe, c, 200_000 + i) for c, img in enumerate(lit)]
        found = detect_all(lit, None, cfg)
        lines.append([np.column_stack([ln.col[ln.valid], ln.row[ln.valid]]).astype(np.float64) for ln in found])
    return images, lines


def _summary(cfg, board, fit, views, dropped, distortion, seconds) -> dict:
    truth = cfg.probe
    true_dist = tuple(cfg.sensor.distortion)
    dev = deviations(truth, fit.probe.calibration, true_dist)
    out = {"config": cfg.name, "probe": truth.name, "views": len(views), "views_left_out": [
        {"view": k, "why": why} for k, why in dropped], "distortion_fitted": distortion,
        "board": {"squares": list(board.squares), "square_mm": board.square_mm, "marker_mm": board.marker_mm,
                  "dictionary": board.dictionary},
        "board2base_mm": fit.board2base.tolist(), "seconds": round(seconds, 3)}
    for c, cam in enumerate(fit.cameras):
        out[f"camera{c}"] = {
            "reprojection_error_px": cam.reprojection_error_px, "zhang_error_px": cam.zhang_error_px,
            "views_with_board": cam.views, "corners": cam.corners,
            "K": cam.K.tolist(), "distortion": cam.distortion.tolist(), "cam2flange_mm": cam.cam2flange.tolist(),
            "std": {**cam.std_intrinsics, **cam.std_pose},
            "deviation": dev[f"camera{c}"]}
    out["laser"] = {"normal": fit.probe.calibration.plane_normal.tolist(),
                    "offset_mm": fit.probe.calibration.plane_offset_mm, "fit_rms_mm": fit.plane_rms_mm,
                    "points": fit.plane_points, "views": fit.plane_views, "std": dict(fit.plane_std),
                    "deviation": dev["laser"]}
    out["triangulation_error"] = triangulation_error(truth, fit.probe, true_dist)
    return out


def _picture(images, views, columns: int = 6):
    """Up to 12 views × both cameras: the board image, found corners as green crosses."""
    import cv2

    tiles = []
    for i, pair in enumerate(images[:12]):
        for c in (0, 1):
            img = np.asarray(pair[c], dtype=np.float32)[..., :3]
            g = np.clip(img / max(float(np.percentile(img, 99.5)), 1e-9) * 255.0, 0, 255).astype(np.uint8)
            bgr = cv2.cvtColor(g.mean(axis=2).astype(np.uint8), cv2.COLOR_GRAY2BGR)
            scale = max(1, int(math.ceil(160 / max(bgr.shape[:2]))))
            bgr = cv2.resize(bgr, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
            for u, v in views[i].corners[c]:
                cv2.drawMarker(bgr, (int(round((u + 0.5) * scale - 0.5)), int(round((v + 0.5) * scale - 0.5))),
                               (0, 200, 0), cv2.MARKER_CROSS, max(7, 3 * scale), 2)
            line = views[i].line[c]
            if line is not None:
                for u, v in line[:: max(1, len(line) // 200)]:
                    cv2.circle(bgr, (int(round((u + 0.5) * scale - 0.5)), int(round((v + 0.5) * scale - 0.5))), 1,
                               (0, 0, 230), -1)
            cv2.putText(bgr, f"view {i} cam {c}: {len(views[i].ids[c])}", (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                        (0, 140, 255), 1, cv2.LINE_AA)
            tiles.append(bgr)
    h = max(t.shape[0] for t in tiles)
    w = max(t.shape[1] for t in tiles)
    tiles = [cv2.copyMakeBorder(t, 0, h - t.shape[0], 0, w - t.shape[1], cv2.BORDER_CONSTANT, value=(0, 0, 0))
             for t in tiles]
    while len(tiles) % columns:
        tiles.append(np.zeros_like(tiles[0]))
    rows = [np.hstack(tiles[r:r + columns]) for r in range(0, len(tiles), columns)]
    return np.vstack(rows)


__all__ = ["CalibrationRun", "calibrate", "plan_views"]
