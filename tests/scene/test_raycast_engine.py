"""The raycast engine against Cycles, frame by frame: the same frames rendered by both, the
line found in each, the clouds of a scan by each. Cycles is the reference (one sample per
pixel, 0.01 px box filter, no bounces: the ideal conditions the engine is for)."""

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial import cKDTree

from addon.core.config.scan import load_scan_config
from addon.core.geometry.workpiece import Workpiece
from addon.core.optics.detect import detect_line
from addon.core.scan.plan import plan_scan
from addon.pipeline import build_raycaster, build_scan_cell, render_settings, run_scan


def cad_part_config(name: str, frames: int = 30):
    from headless.bench.parts import part_path
    from headless.parts import cad_parts

    mesh = cad_parts()[name]
    base = load_scan_config("demo")
    return replace(base, name=name, workpiece=Workpiece(name, mesh, mesh, f"test:{name}", np.eye(4)),
                   waypoints=part_path(mesh, base.table, frames))


def both_engines(cfg, step: int):
    """Every ``step``-th frame of the config's path: (Cycles images, raycast images with their rows)."""
    plan = plan_scan(cfg)
    idx = np.arange(0, len(plan.q), step)
    sc = build_scan_cell(cfg)
    keyed = sc.keyframe(plan.q[idx], plan.table_rad[idx])
    cycles = sc.render(keyed.start, keyed.stop - 1, render_settings(cfg), (0, 1))
    raycast = build_raycaster(cfg).render_frames(cfg.cell.probe2table(plan.q[idx], plan.table_rad[idx]), (0, 1))
    return cycles, raycast


@pytest.mark.parametrize("name, step, pixel_tol", [
    ("demo", 15, 1e-3),                          # sphere: measured 2.7e-4 of the peak, lines 2.6e-4 px
    ("step_block", 10, 1e-3),                    # sharp edges, occlusion: 2.9e-4, 2.8e-4 px
    ("L-bracket with fillet", 4, 5e-3),          # CAD part, fillet: 2.1e-3, 1.3e-3 px
])
def test_raycast_images_and_lines_match_cycles_frame_by_frame(name, step, pixel_tol):
    cfg = load_scan_config(name) if name in ("demo", "step_block") else cad_part_config(name)
    cycles, raycast = both_engines(cfg, step)
    worst_px, one_only, compared = 0.0, 0, 0
    for pair, (images, (r0, r1)) in zip(cycles, raycast):
        for camera in (0, 1):
            ref = pair[camera]
            mine = np.zeros_like(ref)
            mine[r0:r1] = images[camera]
            peak = ref[..., 0].max()
            if peak <= 0:
                continue
            assert np.abs(ref - mine).max() <= pixel_tol * peak
            a = detect_line(ref, cfg.detect_method, cfg.detect_params)
            b = detect_line(mine, cfg.detect_method, cfg.detect_params)
            both = a.valid & b.valid
            one_only += int((a.valid ^ b.valid).sum())
            compared += int(both.sum())
            if both.any():
                worst_px = max(worst_px, float(np.abs(a.row[both] - b.row[both]).max()))
    assert compared > 500
    assert worst_px <= 0.002, worst_px
    assert one_only <= 0.002 * compared, one_only


def test_raycast_cloud_is_the_cycles_cloud():
    """A scan of the step block (two sweeps, every 4th frame) by each engine: the same points
    to well under a micrometre."""
    cfg = load_scan_config("step_block").with_overrides(frames=slice(None, None, 4))
    clouds = {engine: run_scan(cfg.with_overrides(engine=engine), None, write_outputs=False)
              for engine in ("cycles", "raycast")}
    a, b = clouds["cycles"].cloud.points, clouds["raycast"].cloud.points
    assert len(a) > 1000 and abs(len(a) - len(b)) <= 0.002 * len(a)
    d, _ = cKDTree(a).query(b)
    rms_um = 1e3 * float(np.sqrt(np.mean(d ** 2)))
    assert rms_um <= 1.0, rms_um
    assert clouds["raycast"].report["render_device"].startswith("CPU (Embree")
