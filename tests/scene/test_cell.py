"""The cell: turntable carries the workpiece, paths render in one call, exactly as frame by frame."""

import bpy
import numpy as np
import pytest

from addon.core.kinematics.cell import Cell
from addon.core.errors import InputError
from addon.core.kinematics.euler import pose_from_xyz_yzz
from addon.core.config.rigs import load_robot
from addon.core.config.rigs import load_probe
from addon.core.kinematics.transforms import rot_z, trans
from addon.core.geometry.workpiece import builtin_workpiece
from addon.scene.cell import build_cell, remove_cell
from addon.core.config.render import RenderOptions
from addon.scene.units import from_blender


def world_vertices(obj):
    me = obj.data
    v = np.empty(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", v)
    v = v.reshape(-1, 3).astype(np.float64) * 1e3
    M = from_blender(obj.matrix_world)
    return v @ M[:3, :3].T + M[:3, 3]


def test_workpiece_turns_with_the_table(scene):
    wp = builtin_workpiece("step_block", pose=trans(20, -10, 0) @ rot_z(0.4))
    sc = build_cell(scene, Cell(load_robot("adept_viper_s650")), load_probe("default"), wp)
    for theta in (0.0, 0.7, -2.5, 3 * np.pi / 2):
        sc.pose(np.zeros(6), theta)
        got = world_vertices(sc.workpiece_object)
        T = sc.cell.table.table2base(theta)
        expect = np.asarray(wp.mesh.vertices) @ T[:3, :3].T + T[:3, 3]
        assert np.abs(got - expect).max() < 1e-3  # float32 vertices in metres
    # Keyframed table angles come back at frame_set.
    thetas = np.linspace(0, 2 * np.pi, 9)
    frames = sc.keyframe(np.zeros((9, 6)), thetas)
    for frame, theta in zip(frames, thetas):
        scene.frame_set(frame)
        assert sc.table.rotation_euler[2] == pytest.approx(theta, abs=1e-6)


def scanning_path(sc, n):
    """Probe 150 mm above the sphere's top, stepping across it, table turning."""
    qs, thetas, q = [], [], None
    for i in range(n):
        T = pose_from_xyz_yzz([-10.0 + 5 * i, 0.0, 60.0 + 150.0], [0.0, np.pi, 0.0])
        res = sc.cell.ik(T, q, relative_to="table", table_angle_rad=0.1 * i)
        assert res.success, res.message
        q = res.q
        qs.append(q)
        thetas.append(0.1 * i)
    return np.array(qs), np.array(thetas)


def test_one_render_call_gives_the_same_images_as_frame_by_frame(scene):
    sc = build_cell(scene, Cell(load_robot("adept_viper_s650")), load_probe("default"), builtin_workpiece("sphere"))
    qs, thetas = scanning_path(sc, 4)
    frames = sc.keyframe(qs, thetas)
    batch = sc.render(frames.start, frames.stop - 1)
    assert len(batch) == 4 and all(img.shape == (160, 160, 3) for pair in batch for img in pair)
    for i in (0, 3):
        single = sc.render(frames.start + i, frames.start + i)[0]
        for camera in (0, 1):
            np.testing.assert_array_equal(single[camera], batch[i][camera])
    # The line is on the sphere in every frame, and brightest pixels are red.
    for pair in batch:
        for img in pair:
            r, g = img[..., 0].max(), img[..., 1].max()
            assert r > 0.2 and g < 1e-6


def test_only_requested_cameras_render(scene):
    sc = build_cell(scene, Cell(load_robot("puma560")), load_probe("default"), builtin_workpiece("plane"))
    qs, thetas = scanning_path(sc, 1)
    sc.keyframe(qs, thetas)
    ((left, right),) = sc.render(1, 1, cameras=(1,))
    assert left is None and right.shape == (160, 160, 3)


def test_each_engine_refuses_the_other_engines_gaussian_laser(scene):
    sc = build_cell(scene, Cell(load_robot("ur5")), load_probe("default"))
    with pytest.raises(InputError, match="spot"):
        sc.render(1, 1, RenderOptions(engine="eevee"))
    sc = build_cell(scene, Cell(load_robot("ur5")), load_probe("default"), laser="spot")
    with pytest.raises(InputError, match="gobo"):
        sc.render(1, 1, RenderOptions(engine="cycles"))


def test_an_eevee_render_reports_the_opengl_device_it_ran_on(scene):
    # Eevee draws through OpenGL: on a GPU, or through Mesa's software rasteriser where there is
    # none (this CI machine). The report must say which, not "CPU" for an H100.
    import gpu

    sc = build_cell(scene, Cell(load_robot("ur5")), load_probe("default"), builtin_workpiece("plane"), laser="spot")
    qs, thetas = scanning_path(sc, 1)
    sc.keyframe(qs, thetas)
    sc.render(1, 1, RenderOptions(engine="eevee", samples=1), cameras=(0,))
    renderer = gpu.platform.renderer_get()
    assert renderer and renderer in sc.device_used
    software = gpu.platform.device_type_get() == "SOFTWARE"
    assert sc.device_used.startswith("CPU (software OpenGL" if software else "GPU (OpenGL"), sc.device_used


def test_rebuilding_replaces_the_cell(scene):
    import bpy

    build_cell(scene, Cell(load_robot("ur5")), load_probe("default"), builtin_workpiece("cylinder"))
    n_objects = len(bpy.data.objects)
    build_cell(scene, Cell(load_robot("ur5")), load_probe("default"), builtin_workpiece("cylinder"))
    assert len(bpy.data.objects) == n_objects
    remove_cell(scene)
    assert bpy.data.collections.get("Scanner Cell") is None
    assert len([o for o in bpy.data.objects if o.users]) == 0


@pytest.mark.parametrize("kwargs,fragment", [
    (dict(samples=0), "samples"),
    (dict(engine="luxcore"), "engine"),
    (dict(pixel_filter="SINC"), "pixel filter"),
    (dict(filter_width_px=0.0), "filter width"),
])
def test_bad_render_settings(kwargs, fragment):
    with pytest.raises(InputError, match=fragment):
        RenderOptions(**kwargs)


def test_the_scenes_own_objects_stay_out_of_probe_renders():
    """An artist's scene (a bright lamp, a prop) must not change what the probe measures."""
    from addon.core.config.scan import load_scan_config
    from addon.pipeline import run_scan
    from addon.scene.session import new_scene

    cfg = load_scan_config("step_block").with_overrides(frames=slice(0, 100, 25))
    clean = run_scan(cfg, None, write_outputs=False).cloud
    scene = new_scene()
    lamp = bpy.data.objects.new("Studio lamp", bpy.data.lights.new("Studio lamp", "POINT"))
    lamp.data.energy = 1000.0
    lamp.location = (0.0, 0.0, 1.0)
    scene.collection.objects.link(lamp)
    bpy.ops.mesh.primitive_cube_add(size=0.02, location=(0.0, 0.06, 0.01))  # beside the part, on the table
    prop = bpy.context.active_object
    cluttered = run_scan(cfg, None, scene, write_outputs=False).cloud
    np.testing.assert_array_equal(cluttered.points, clean.points)
    assert not lamp.hide_render and not prop.hide_render  # given back as they were


def test_eevees_first_render_call_is_one_frame(scene):
    # Eevee compiles its shaders on the first call and gives Python no chance to stop it
    # meanwhile: a Ctrl-C must not wait for a chunk sized by Cycles' speed.
    from addon.core.config.scan import load_scan_config
    from addon.pipeline import ScanRun

    cfg = load_scan_config("demo")
    assert ScanRun(cfg, scene)._chunk_size() > 1
    assert ScanRun(cfg.with_overrides(engine="eevee"), scene)._chunk_size() == 1


def test_a_ctrl_c_during_a_render_call_is_raised_once_the_call_is_over():
    """What Cycles would swallow inside its callbacks: the signal is recorded during the call,
    raised after it; the handler is Python's own again; a handler of the caller's own (the
    command line's) and a nested call are left alone; a failure after a Ctrl-C is its cause."""
    import os
    import signal

    from addon.scene.render import RAISED_AFTER_RENDER, ctrl_c_after_render

    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    got = []
    with pytest.raises(KeyboardInterrupt, match=RAISED_AFTER_RENDER):
        with ctrl_c_after_render():
            with ctrl_c_after_render():  # nested: the outer one holds the signal
                os.kill(os.getpid(), signal.SIGINT)
                os.kill(os.getpid(), signal.SIGINT)  # a second press is recorded too
            got.append("the call went on to its end")
    assert got and signal.getsignal(signal.SIGINT) is signal.default_int_handler
    with pytest.raises(KeyboardInterrupt) as caught:
        with ctrl_c_after_render():
            os.kill(os.getpid(), signal.SIGINT)
            raise RuntimeError("the render failed")
    assert isinstance(caught.value.__cause__, RuntimeError)
    with ctrl_c_after_render():  # no Ctrl-C: nothing raised
        pass
    asked = []
    old = signal.signal(signal.SIGINT, lambda signum, frame: asked.append(signum))
    try:
        with ctrl_c_after_render():  # the caller's own handler gets the signal at once
            os.kill(os.getpid(), signal.SIGINT)
        assert asked == [signal.SIGINT]
    finally:
        signal.signal(signal.SIGINT, old)


def test_a_ctrl_c_while_the_render_settings_are_applied_stops_the_call_once_it_is_over(scene, monkeypatch):
    """Applying the render settings frees Cycles' earlier engines, whose Python finaliser
    printed a KeyboardInterrupt landing there as "Exception ignored" and let a script go on:
    the deferral covers the settings and the restore as well as the render call."""
    import os
    import signal

    import addon.scene.cell as cell_module
    from addon.scene.render import RAISED_AFTER_RENDER

    sc = build_cell(scene, Cell(load_robot("puma560")), load_probe("default"), builtin_workpiece("plane"))
    qs, thetas = scanning_path(sc, 1)
    sc.keyframe(qs, thetas)
    real = cell_module.configure
    deferred = []

    def configure_and_press_ctrl_c(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGINT)  # lands where the engines are freed
        deferred.append(signal.getsignal(signal.SIGINT) is not signal.default_int_handler)
        return real(*args, **kwargs)

    monkeypatch.setattr(cell_module, "configure", configure_and_press_ctrl_c)
    with pytest.raises(KeyboardInterrupt, match=RAISED_AFTER_RENDER):
        sc.render(1, 1)
    assert deferred == [True] and signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_the_blender_cell_pages_example_runs_and_sees_the_laser_line():
    """docs/blender-cell.md's first example, as written, in a Python of its own."""
    import os
    import re
    import subprocess
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[2]
    code = re.search(r"```python\n(.*?)```", (repo / "docs" / "blender-cell.md").read_text(), re.S).group(1)
    code += "\nprint(len(images), len(images[0]), images[0][0].shape, float(images[0][0][..., 0].max()))\n"
    out = subprocess.run([sys.executable, "-c", code], cwd=repo, capture_output=True, text=True, timeout=600,
                         env={**os.environ, "PYTHONPATH": str(repo)})
    assert out.returncode == 0, out.stderr[-2000:]
    last = out.stdout.strip().splitlines()[-1]
    assert last.startswith("1 2 (160, 160, 3) "), last  # one frame, both cameras, the default sensor
    assert float(last.rsplit(" ", 1)[1]) > 0.1  # the laser line lights some pixels red


def test_looking_for_a_gpu_writes_nothing_to_standard_output(scene, capfd):
    """Cycles logs each GPU backend it cannot load ("CUEW initialization failed") to file
    descriptor 1: asked for CUDA on a machine without one, a --quiet scan's stdout, which should
    hold the summary alone, carried those lines (a hunt), one pair per farm worker."""
    from addon.scene.session import use_device

    capfd.readouterr()
    used = use_device(scene, "CUDA")
    out = capfd.readouterr().out
    assert out == "", out
    scene.cycles.device = "CPU"
    assert used == "CPU" or used.startswith("GPU (CUDA")


def test_a_script_with_its_stdout_closed_still_starts_blender():
    """A daemon's or cron job's script has no stdout: the start of Blender, whose log is kept
    off stdout, flushed a sys.stdout that is None (a review)."""
    import subprocess
    import sys
    from pathlib import Path

    code = "from addon.scene.session import new_scene; new_scene(); import sys; sys.stderr.write('started')"
    run = subprocess.run([sys.executable, "-c", code], cwd=Path(__file__).resolve().parents[2],
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, close_fds=True,
                         preexec_fn=lambda: __import__("os").close(1))
    assert run.returncode == 0 and run.stderr.endswith("started"), run.stderr[-800:]
