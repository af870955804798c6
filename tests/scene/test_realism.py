"""Render-side realism: motion during the exposure, glossy surfaces with bounces, pixel area sampling."""

import math
from dataclasses import replace

import numpy as np
import pytest

from addon.core.kinematics.cell import Cell
from addon.core.optics.detect import DetectParams, detect_line
from addon.core.kinematics.euler import pose_from_xyz_yzz
from addon.core.config.rigs import load_robot
from addon.core.config.rigs import load_probe
from addon.core.config.scan import load_scan_config
from addon.core.optics.sensor import SensorModel
from addon.core.kinematics.transforms import trans
from addon.core.geometry.workpiece import builtin_workpiece
from addon.pipeline import render_settings, run_scan
from addon.scene.cell import build_cell
from addon.core.config.render import RenderOptions

FLOAT = DetectParams(saturation=np.inf)


def test_motion_blur_widens_the_line_by_its_travel_during_the_exposure(scene):
    # The probe backs away from a plane: the line's row changes steadily from frame to frame.
    wp = builtin_workpiece("plane", pose=trans(0, 0, 20))  # clear of the table top
    sc = build_cell(scene, Cell(load_robot("adept_viper_s650")), load_probe("default"), wp)
    qs, q = [], np.radians([0, 40, -100, 0, -30, 0])
    for z in np.linspace(150, 180, 7):  # 5 mm per frame
        res = sc.cell.ik(pose_from_xyz_yzz([0, 0, z], [math.pi / 2, math.pi, 0]), q, relative_to="table")
        q = res.q
        qs.append(q)
    frames = sc.keyframe(np.array(qs))
    sharp = sc.render(frames.start, frames.stop - 1, RenderOptions(samples=16, filter_width_px=1.0))
    shutter = 0.6
    i = 3  # the frame measured blurred (the motion around it comes from its neighbours' keys)
    blurred = sc.render(frames.start + i, frames.start + i, RenderOptions(samples=64, filter_width_px=1.0,
                                                                          motion_blur_shutter=shutter))
    lines = [detect_line(p[0], "gauss", FLOAT) for p in sharp]
    rows = [np.nanmedian(ln.row) for ln in lines]
    travel = shutter * abs(np.median(np.diff(rows)))  # rows swept while the shutter is open
    assert travel > 1.5
    w0 = np.nanmedian(lines[i].width)
    w1 = np.nanmedian(detect_line(blurred[0][0], "cog", FLOAT).width)
    # A Gaussian (FWHM w0) smeared by a box of b rows: variance grows by b²/12.
    expect = 2.355 * math.sqrt((w0 / 2.355) ** 2 + travel ** 2 / 12)
    assert w1 == pytest.approx(expect, rel=0.25), (w0, w1, travel)
    assert w1 > w0 * 1.15


def test_the_shutter_blurs_a_frames_own_motion_not_the_jump_to_the_next_path_entry(scene):
    """The last frame of a path entry, blurred, is as wide as one inside it, however far the
    next entry starts; a scan of every tenth frame blurs one frame's motion, not ten's."""
    wp = builtin_workpiece("plane", pose=trans(0, 0, 20))
    sc = build_cell(scene, Cell(load_robot("adept_viper_s650")), load_probe("default"), wp)
    qs, q = [], np.radians([0, 40, -100, 0, -30, 0])
    heights = [150, 155, 160, 165, 215, 220, 225]  # two entries: backing away 5 mm a frame, then 50 mm on
    for z in heights:
        q = sc.cell.ik(pose_from_xyz_yzz([0, 0, z], [math.pi / 2, math.pi, 0]), q, relative_to="table").q
        qs.append(q)
    settings = RenderOptions(samples=64, filter_width_px=1.0, motion_blur_shutter=0.6)

    def blurred_width(frame_index, **path):
        frames = sc.keyframe(np.array(qs), **path)
        image = sc.render(frames.start + frame_index, frames.start + frame_index, settings)[0][0]
        return float(np.nanmedian(detect_line(image, "cog", FLOAT).width))

    frames = sc.keyframe(np.array(qs))
    sharp = sc.render(frames.start + 2, frames.start + 2, RenderOptions(samples=16, filter_width_px=1.0))[0][0]
    w0 = float(np.nanmedian(detect_line(sharp, "gauss", FLOAT).width))
    entries = {"segments": [0, 0, 0, 0, 1, 1, 1]}
    inside, last = blurred_width(2, **entries), blurred_width(3, **entries)
    assert inside > 1.15 * w0  # the entry's own motion blurs it
    assert last == pytest.approx(inside, rel=0.1), (w0, inside, last)  # and only that
    tenth = blurred_width(2, segments=[0] * 7, path_frames=np.arange(7) * 10)  # 0.5 mm a frame of the path
    assert tenth < 0.5 * (w0 + inside), (w0, inside, tenth)


def test_glossy_part_with_bounces_shows_reflections_the_detector_rejects():
    # Frames 2-6 of the step block put the line next to a riser: with bounces, the lit
    # floor reflects into the wall (and back), a second line in the same columns. In
    # frame 5 the laser plane is 0.13 mm inside the block's end face: the edge cuts the
    # line across its width and camera 1 sees both parts, two peaks in each of the
    # block's 100 columns without any bounce.
    base = load_scan_config("step_block").with_overrides(frames=slice(2, 7))
    ideal = run_scan(base, None, write_outputs=False).report
    glossy_cfg = replace(base, material="glossy", roughness=0.1, render=replace(base.render, bounces=2))
    glossy = run_scan(glossy_cfg, None, write_outputs=False).report
    assert glossy["config"]["material"] == "glossy"
    assert ideal["column_codes"].get("AMBIGUOUS", 0) == 100, ideal["column_codes"]
    assert glossy["column_codes"].get("AMBIGUOUS", 0) > 100 + 20, glossy["column_codes"]
    # Rejected, not averaged: the points that remain are as good as the ideal ones.
    assert glossy["error_um"]["p95_um"] < 2 * ideal["error_um"]["p95_um"] + 10


def test_sensor_switches_set_the_render():
    cfg = load_scan_config("demo")
    assert render_settings(cfg).samples == 1
    area = render_settings(replace(cfg, sensor=SensorModel(integrate_pixels=True)))
    assert (area.pixel_filter, area.filter_width_px) == ("BOX", 1.0) and area.samples >= 16
    moving = render_settings(replace(cfg, sensor=SensorModel(motion_blur=True, exposure_ms=2.0, frame_rate_hz=100)))
    assert moving.motion_blur_shutter == pytest.approx(0.2)


def test_noisy_scans_are_reproducible():
    cfg = load_scan_config("step_block").with_overrides(frames=slice(0, 100, 20))
    cfg = cfg.with_realism(SensorModel(saturate=True, noise=True, speckle=True, seed=7))
    a = run_scan(cfg, None, write_outputs=False).cloud
    b = run_scan(cfg, None, write_outputs=False).cloud
    np.testing.assert_array_equal(a.points, b.points)
    c = run_scan(cfg.with_realism(replace(cfg.sensor, seed=8)), None, write_outputs=False).cloud
    assert len(a) != len(c) or not np.array_equal(a.points, c.points)


def test_the_bundled_realistic_scan_lands_in_real_profiler_territory():
    cfg = load_scan_config("cylinder_realistic").with_overrides(frames=slice(None, None, 4))
    assert cfg.sensor.integrate_pixels and cfg.sensor.speckle and cfg.material == "glossy"
    real = run_scan(cfg, None, write_outputs=False).report
    ideal_cfg = replace(cfg.with_realism(SensorModel(), "grey", ambient=0.0), render=replace(cfg.render, bounces=0,
                                                                                              ambient=0.0))
    ideal = run_scan(ideal_cfg, None, write_outputs=False).report
    assert len(real["config"]["sensor"]) == 7  # every effect on
    # The ideal sensor measures this cylinder to a few µm; the realistic one to tens of µm.
    assert ideal["error_um"]["rms_um"] < 15
    assert 20 < real["error_um"]["rms_um"] < 300 and real["error_um"]["rms_um"] > 3 * ideal["error_um"]["rms_um"]
