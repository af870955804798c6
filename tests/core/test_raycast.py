"""The raycast engine (addon/core/optics/raycast.py) against geometry: where the line falls on
planes, what its peak is, Blender's shading normals on shapes whose normals are known,
shadows, and that casting only the windows misses no light a full frame would show.

Its agreement with Cycles, frame by frame, is tests/scene/test_raycast_engine.py.
"""

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from addon.core.config.render import RenderOptions, raycast_mismatch
from addon.core.config.rigs import load_probe
from addon.core.errors import ConfigError, InputError
from addon.core.kinematics.transforms import rot_x, rot_y, trans
from addon.core.optics.surfaces import TABLE_TOP, WORKPIECE_GREY
from addon.core.optics.detect import DetectParams, detect_line
from addon.core.optics.laser_profile import mid_range_mm
from addon.core.optics.raycast import (DARK_SHARE, RaycastRenderer, RaycastScene, corner_normals,
                                       vertex_normals, visible_fan_half_angle)

FLOAT = DetectParams(saturation=np.inf, smoothing_px=0.0)
PROBE = load_probe("default")


def plate(pose, size=600.0):
    """A slab whose face z = 0 (in ``pose``) is towards the probe at the origin, looking along +z."""
    box = trimesh.creation.box([size, size, 1.0], trans(0, 0, 0.5))
    box.apply_transform(pose)
    return box


def predicted_rows(probe, pose, camera, cols):
    """Row of the laser line per column: the plate meets the laser plane x = 0 in a straight
    line, whose image is the straight line through two of its points, projected."""
    n, c = pose[:3, 2], pose[:3, 3]
    t = np.array([-4.0, 4.0])
    z = (n @ c - n[1] * t) / n[2]
    (u0, v0), (u1, v1) = probe.project(np.column_stack([np.zeros(2), t, z]), camera)
    return v0 + (cols - u0) * (v1 - v0) / (u1 - u0)


def full_frame(renderer, probe2table, camera):
    """Every pixel of one camera, shaded as the windows are (for comparing against the windows)."""
    H, W = renderer.probe.rows_px, renderer.probe.cols_px
    cam2table = (probe2table @ renderer.probe.cam2probe(camera))[None]
    cell = np.repeat(np.arange(W), H)
    row = np.tile(np.arange(H), W)
    value, albedo = renderer._shade(cam2table, probe2table[None], cell, row, W)
    img = np.zeros((H, W))
    img[row, cell] = value * albedo[:, 0]  # the red channel: the laser is red
    return img


@pytest.mark.parametrize("z", [90.0, 150.0, 220.0])
@pytest.mark.parametrize("tilt", [(0, 0), (30, 0), (0, 30), (-20, 25)])
def test_line_lies_where_the_laser_plane_meets_the_plate(z, tilt):
    pose = trans(0, 0, z) @ rot_x(math.radians(tilt[0])) @ rot_y(math.radians(tilt[1]))
    renderer = RaycastRenderer(PROBE, RaycastScene([(plate(pose), (WORKPIECE_GREY,) * 3)]))
    (images, (r0, r1)), = renderer.render_frames(np.eye(4)[None], (0, 1))
    for camera, img in enumerate(images):
        line = detect_line(img, "gauss", FLOAT, r0)
        assert line.valid.mean() > 0.6, line.counts()
        d = (line.row - predicted_rows(PROBE, pose, camera, line.col.astype(float)))[line.valid]
        # The pixel sample sits 4.8e-4 px off the centre (Cycles' place); a sampled Gaussian
        # seen at a slant reads a little off its centre: measured up to 0.0035 px here.
        assert np.sqrt(np.mean(d ** 2)) < 0.004, np.sqrt(np.mean(d ** 2))


def test_peak_is_the_calibrated_level_on_a_head_on_plate_at_mid_range():
    z = mid_range_mm(PROBE)
    peak = 0.37
    renderer = RaycastRenderer(PROBE, RaycastScene([(plate(trans(0, 0, z)), (WORKPIECE_GREY,) * 3)]), laser_peak=peak)
    (images, _), = renderer.render_frames(np.eye(4)[None], (0, 1))
    # Head on and on the beam the plate gets exactly the calibrated light. The pixels sample the
    # Gaussian across the line off its top: its height comes from the log-parabola through the
    # brightest pixel and its two neighbours, in the columns next to the beam (u ≈ c_x).
    for img in images:
        col = int(PROBE.principal_point[0])
        c = img[:, col, 0].astype(np.float64)
        r = int(np.argmax(c))
        lm, l0, lp = np.log(c[r - 1:r + 2])
        top = math.exp(l0 - (lp - lm) ** 2 / (8.0 * (lp + lm - 2.0 * l0)))
        assert top == pytest.approx(peak, rel=2e-3), top
    assert all(np.all(img[..., 1:] == 0) for img in images)  # the laser is red


def test_albedo_scales_the_image():
    pose = trans(0, 0, 150.0)
    grey = RaycastRenderer(PROBE, RaycastScene([(plate(pose), (WORKPIECE_GREY,) * 3)]))
    table = RaycastRenderer(PROBE, RaycastScene([(plate(pose), TABLE_TOP)]))
    (a, _), = grey.render_frames(np.eye(4)[None], (0,))
    (b, _), = table.render_frames(np.eye(4)[None], (0,))
    lit = a[0][..., 0] > 1e-3
    np.testing.assert_allclose(b[0][..., 0][lit] / a[0][..., 0][lit], TABLE_TOP[0] / WORKPIECE_GREY, rtol=1e-6)


def test_corner_normals_are_face_normals_on_a_box_and_radial_on_a_sphere():
    box = trimesh.creation.box([10, 20, 30])
    np.testing.assert_allclose(corner_normals(box), np.repeat(box.face_normals[:, None, :], 3, axis=1), atol=1e-12)
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=50.0)
    radial = sphere.vertices[sphere.faces] / 50.0
    angle = np.degrees(np.arccos(np.clip(np.einsum("fkj,fkj->fk", corner_normals(sphere), radial), -1, 1)))
    assert angle.max() < 0.5, angle.max()
    # Vertex normals know nothing of sharp edges: on a box each corner's is the mean of three faces.
    corner = vertex_normals(box)[0, 0]
    assert np.allclose(np.abs(corner), 1 / math.sqrt(3), atol=1e-9)


def test_corner_normals_keep_a_cylinder_smooth_round_and_its_caps_flat():
    cyl = trimesh.creation.cylinder(radius=20.0, height=40.0, sections=64)
    n = corner_normals(cyl)
    cap = np.abs(cyl.face_normals[:, 2]) > 0.99
    assert np.allclose(n[cap], cyl.face_normals[cap][:, None, :], atol=1e-12)
    side = ~cap
    pts = cyl.vertices[cyl.faces[side]]
    radial = pts * [1, 1, 0]
    radial /= np.linalg.norm(radial, axis=2, keepdims=True)
    assert np.degrees(np.arccos(np.clip(np.einsum("fkj,fkj->fk", n[side], radial), -1, 1))).max() < 1e-4


def test_a_slab_above_the_plate_shadows_it():
    """A slab 40 mm above the plate covers the beam's positive-y half: there the cameras see the
    line on the slab's top, and the plate below it stays dark."""
    z = 170.0
    slab = trimesh.creation.box([200, 100, 2], trans(0, 50 + 3, z - 40 - 1))  # y from 3 to 103, top at z − 42
    scene = RaycastScene([(plate(trans(0, 0, z)), (WORKPIECE_GREY,) * 3), (slab, (WORKPIECE_GREY,) * 3)])
    renderer = RaycastRenderer(PROBE, scene)
    (images, (r0, _)), = renderer.render_frames(np.eye(4)[None], (0,))
    line = detect_line(images[0], "gauss", FLOAT, r0)
    cols = line.col.astype(float)
    on_plate = predicted_rows(PROBE, trans(0, 0, z), 0, cols)
    on_slab = predicted_rows(PROBE, trans(0, 0, z - 42.0), 0, cols)
    ok = line.valid
    near_plate = np.abs(line.row - on_plate) < 0.05
    near_slab = np.abs(line.row - on_slab) < 0.05
    assert np.all(near_plate[ok] | near_slab[ok])
    # camera 0 looks along +y for larger columns: the slab's half and the plate's half both show
    assert near_plate[ok].sum() > 20 and near_slab[ok].sum() > 20
    # where the line is on the slab, the plate's row in that column is dark
    plate_rows = np.round(on_plate[ok & near_slab]).astype(int) - r0
    inside = (plate_rows >= 0) & (plate_rows < images[0].shape[0])
    assert np.all(images[0][plate_rows[inside], line.col[ok & near_slab][inside], 0] == 0)


@pytest.fixture(scope="module")
def parts():
    from headless.parts import cad_parts

    return cad_parts()


@pytest.mark.parametrize("name", ["thin-walled tube", "block with hole and pocket", "L-bracket with fillet"])
def test_windows_hold_all_the_light_a_full_frame_shows(parts, name):
    """Casting only the windows loses nothing: pixels outside them are dark in a full frame too
    (below DARK_SHARE of the column's peak), and inside they are the full frame's (to the film's
    float32)."""
    from addon.core.kinematics.turntable import table_top_mesh

    mesh = parts[name]
    scene = RaycastScene([(mesh, (WORKPIECE_GREY,) * 3), (table_top_mesh(), TABLE_TOP)])
    renderer = RaycastRenderer(PROBE, scene)
    top = mesh.bounds[1, 2]
    poses = [trans(x, y, top + 140.0) @ rot_x(math.pi) @ rot_y(math.radians(b)) @ rot_x(math.radians(a))
             for x, y, a, b in [(0, 0, 0, 0), (8, -5, 20, 0), (-12, 4, -15, 25), (3, 10, 0, -30)]]
    frames = renderer.render_frames(np.array(poses), (0, 1))
    for pose, (images, (r0, r1)) in zip(poses, frames):
        for camera in (0, 1):
            full = full_frame(renderer, pose, camera)
            band = np.zeros_like(full)
            band[r0:r1] = images[camera][..., 0]
            cast = band > 0
            assert cast.sum() > 200, (name, camera, cast.sum())  # the line is there to be checked
            np.testing.assert_allclose(band[cast], full[cast], rtol=1e-6)
            missed = full * ~cast
            peak = full.max(axis=0)
            assert np.all(missed <= DARK_SHARE * peak[None, :] + 1e-12), (name, camera, missed.max())


@pytest.mark.parametrize("tilt_deg", [60.0, 80.0, 86.0])
def test_windows_hold_the_wide_line_on_a_plate_the_laser_grazes(tilt_deg):
    """Turned about the line (the probe's y axis), the plate spreads the line across it (1/cos
    of the tilt: ×14 at 86°), and the camera on the side it turns to sees it over dozens of
    rows (27 at 86°; the other sees it edge on): the windows hold all of it."""
    pose = trans(0, 0, 150.0) @ rot_y(math.radians(tilt_deg))
    renderer = RaycastRenderer(PROBE, RaycastScene([(plate(pose), (WORKPIECE_GREY,) * 3)]))
    (images, (r0, r1)), = renderer.render_frames(np.eye(4)[None], (0, 1))
    lit_rows = []
    for camera in (0, 1):
        full = full_frame(renderer, np.eye(4), camera)
        band = np.zeros_like(full)
        band[r0:r1] = images[camera][..., 0]
        cast = band > 0
        np.testing.assert_allclose(band[cast], full[cast], rtol=1e-6)
        column_peak = full.max(axis=0)[None, :]
        assert np.all(full * ~cast <= DARK_SHARE * column_peak + 1e-12)
        lit_rows.append(int((full > DARK_SHARE * column_peak).sum(axis=0).max()))
    assert max(lit_rows) >= 5, lit_rows


def test_the_fan_covers_what_the_cameras_see_of_the_laser_plane():
    """The fan's rays reach as far from the beam as the cameras can see: points of the laser
    plane a little inside that angle are on a sensor somewhere in the range, a little outside it
    on neither."""
    half = visible_fan_half_angle(PROBE)
    assert 0 < half < PROBE.fan_rad / 2
    z0, z1 = PROBE.z_range_mm
    z = np.linspace(z0, z1, 200)

    def seen(angle):
        pts = np.concatenate([np.column_stack([np.zeros_like(z), s * z * math.tan(angle), z]) for s in (-1, 1)])
        return any(np.isfinite(PROBE.project(pts, camera)).all(axis=1).any() for camera in (0, 1))

    assert seen(0.98 * half)
    assert not seen(1.03 * half)


@pytest.mark.parametrize("change, words", [
    (dict(bounces=2), "bounces"), (dict(ambient=0.1), "ambient"), (dict(samples=16), "samples"),
    (dict(pixel_filter="GAUSSIAN", filter_width_px=1.5), "filter"), (dict(motion_blur_shutter=0.5), "motion"),
    (dict(laser="slit"), "slit"),
])
def test_raycast_refuses_what_needs_light_transport(change, words):
    why = raycast_mismatch(RenderOptions(engine="raycast", **change), "grey")
    assert why and words in why
    # One sample through Cycles' box, one pixel wide whatever its width, is the same point sample.
    assert raycast_mismatch(RenderOptions(engine="raycast", filter_width_px=1.0), "grey") is None
    assert raycast_mismatch(RenderOptions(engine="raycast"), "grey") is None
    assert "glossy" in raycast_mismatch(RenderOptions(engine="raycast"), "glossy")
    assert "robot" in raycast_mismatch(RenderOptions(engine="raycast"), "grey", hide_robot=False)


def test_configs_refuse_raycast_with_light_transport(tmp_path):
    from addon.core.config.scan import load_scan_config

    demo = load_scan_config("demo")
    assert demo.with_overrides(engine="raycast").render.laser == "gobo"
    with pytest.raises(InputError, match="raycast"):
        demo.with_realism(demo.sensor, material="glossy").with_overrides(engine="raycast")
    text = open(demo.source, encoding="utf-8").read()
    bad = tmp_path / "bad.toml"
    assert 'engine = "cycles"' in text
    bad.write_text(text.replace('engine = "cycles"', 'engine = "raycast"\nbounces = 3'), encoding="utf-8")
    with pytest.raises(ConfigError, match="bounces"):
        load_scan_config(str(bad))


@pytest.mark.skipif(not hasattr(os, "fork"), reason="fork is POSIX's")
def test_a_forked_child_of_a_process_that_cast_rays_casts_too(tmp_path):
    """The engine's thread pool is the process's: a child forked after it ran (a Gymnasium
    AsyncVectorEnv's worker) inherits the pool without its threads, and hung in its first cast."""
    script = (
        "import os, sys\n"
        f"sys.path.insert(0, {str(Path(__file__).resolve().parents[2])!r})\n"
        "from addon.core.optics.raycast import _pool\n"
        "assert _pool(2).submit(sum, [1, 2]).result() == 3\n"  # the parent's threads start
        "pid = os.fork()\n"
        "if pid == 0:\n"
        "    try:\n"
        "        os._exit(0 if _pool(2).submit(sum, [3, 4]).result(timeout=20) == 7 else 1)\n"
        "    except Exception:\n"
        "        os._exit(2)\n"
        "os._exit(os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]))\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, (done.returncode, done.stderr[-1000:])


def test_the_ray_casters_threads_are_the_cpus_this_process_may_use(monkeypatch):
    """Threads came from os.cpu_count(), the machine's CPUs: under taskset or a batch system's
    cpuset (one CPU of 64) every worker ran a thread per core it did not have (a hunt)."""
    import os

    from addon.core.machine import usable_cpus

    if hasattr(os, "sched_setaffinity"):
        allowed = os.sched_getaffinity(0)
        try:
            os.sched_setaffinity(0, {min(allowed)})
            assert usable_cpus() == 1
        finally:
            os.sched_setaffinity(0, allowed)
        assert usable_cpus() == len(allowed)
    monkeypatch.setattr(os, "process_cpu_count", lambda: 3, raising=False)
    assert usable_cpus() == 3
