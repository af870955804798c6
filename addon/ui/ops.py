"""Operators behind the Scanner panel. Each can be called from scripts and tests through bpy.ops.

Heavy imports (the pipeline, OpenCV, trimesh) happen inside ``execute``; errors
the user can fix are reported in the status bar, and nothing changes then.
"""

from __future__ import annotations

import json
import os

import bpy
import numpy as np
from bpy.props import FloatProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ExportHelper

from ..core.config.scan import MAX_PROFILES
from ..core.errors import InputError, ScannerError
from ..core.geometry.workpiece import lift_text
from ..scene import rig
from ..scene.animation import drop_scan_motion
from ..scene.render_state import RenderState, kept_render_settings
from . import models


# The modal scan under way, if any: while it runs, the operators that would change the cell
# or start other work are greyed out (they would pull the scene from under it).
_SCAN_RUNNING = [False]


def idle() -> bool:
    """No modal scan is running (see _SCAN_RUNNING)."""
    return not _SCAN_RUNNING[0]


def _cell_built(context, operator=None) -> bool:
    """Whether the cell is built in this scene; where not, ``operator``'s poll says so."""
    built = models.find_robot(context.scene) is not None
    if not built and operator is not None:
        elsewhere = bpy.data.collections.get(models.CELL_NAME) is not None
        operator.poll_message_set("The cell is built in another scene: Build Cell here takes it here" if elsewhere
                                  else "Build the cell first")
    return built


class SCANNER_OT_build_cell(bpy.types.Operator):
    """Build (or rebuild) the scanning cell from the chosen robot, probe and workpiece"""

    bl_idname = "scanner.build_cell"
    bl_label = "Build Cell"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return idle()  # not while a scan runs

    def execute(self, context):
        from ..scene.cell import build_cell

        s = context.scene.scanner
        try:
            models.check_table_angle(s)
            part, lift = models.placed_workpiece(s)
            sc = build_cell(context.scene, models.cell_from(s), models.probe_from(s), part,
                            s.laser, name=models.CELL_NAME, material=s.material, roughness=s.roughness)
        except ScannerError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        # Zeros where the limits allow them (a rig whose limits exclude 0 stood outside them, and
        # Go refused to start), as the Scanner's start joints are clipped.
        sc.pose(np.clip(np.zeros(6), sc.cell.robot.q_min_rad, sc.cell.robot.q_max_rad), s.table_angle)
        part = s.workpiece if s.workpiece != models.FILE else bpy.path.basename(s.workpiece_file)
        moved = lift_text(lift)
        rested = "" if moved is None else f" (put on the table: {moved})"
        self.report({"INFO"}, f"Built the cell: {sc.cell.robot.name}, {sc.probe.name}, {part}{rested}")
        return {"FINISHED"}


class SCANNER_OT_load_probe(bpy.types.Operator):
    """Copy the chosen probe rig's optics (a, b, phi, gamma, sensor) into the fields below"""

    bl_idname = "scanner.load_probe"
    bl_label = "Load from Rig"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return idle()  # not while a scan runs

    def execute(self, context):
        s = context.scene.scanner
        try:
            models.show_probe_optics(s, models.chosen_probe_rig(s))
        except ScannerError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        return {"FINISHED"}


class SCANNER_OT_go(bpy.types.Operator):
    """Move the robot so the tool reaches the Cartesian target (inverse kinematics); nothing moves if it cannot or if the move would collide"""

    bl_idname = "scanner.go"
    bl_label = "Go"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return idle() and _cell_built(context, cls)

    def execute(self, context):
        from ..core.kinematics.euler import pose_from_xyz_yzz
        from ..core.kinematics.transforms import rigid_inverse
        from ..scene import rig

        s = context.scene.scanner
        robot_obj = models.find_robot(context.scene)
        try:
            models.check_table_angle(s)  # (NaN from a script: a traceback in the collision check)
            mismatch = models.cell_mismatch(context)
            if mismatch is not None:  # the IK and the checks would be the panel's robot's, the arm another's
                raise InputError(models.stale_cell_message(mismatch))
            moved = models.placement_mismatch(context)
            if moved is not None:
                raise InputError(f"{moved[:1].upper()}{moved[1:]}: Go works where the cell puts them; put it back "
                                 f"(undo, or Build Cell)")
            cell = models.cell_from(s)
            probe = models.probe_from(s)
            robot = cell.robot.with_tool(probe.mount)
            outside = robot.limit_violations(rig.get_joints(robot_obj))
            if outside:  # set from a script (the sliders keep the limits): no motion starts there
                raise InputError(f"the robot stands outside its joint limits ({'; '.join(outside)}): set the joints "
                                 f"within them first (the Joints sliders)")
            target = pose_from_xyz_yzz(np.array(s.target_location), np.array(s.target_rotation))
            tool = pose_from_xyz_yzz(np.array(s.tool_location), np.array(s.tool_rotation))
            probe_target = target @ rigid_inverse(tool)  # the tool point sits at `tool` in the probe frame
            from ..core.kinematics.cell import Cell

            res = Cell(robot, cell.table).ik(probe_target, rig.get_joints(robot_obj), relative_to=s.target_frame,
                                             table_angle_rad=s.table_angle)
        except ScannerError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        if not res.success:
            self.report({"ERROR"}, f"Unreachable, the robot stays put: {res.message}")
            return {"CANCELLED"}
        try:
            found = models.collision_model(s).check(np.asarray(res.q)[None, :], np.array([s.table_angle]),
                                                    q_start=rig.get_joints(robot_obj), table_start=s.table_angle)
        except ScannerError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        if not found.ok:
            self.report({"ERROR"}, f"Colliding, the robot stays put: {found.message()}")
            return {"CANCELLED"}
        rig.set_joints(robot_obj, res.q)
        self.report({"INFO"}, "Reached: joints " + ", ".join(robot.joint_text(j, v, ".1f") for j, v in enumerate(res.q)))
        return {"FINISHED"}


class SCANNER_OT_render_views(bpy.types.Operator):
    """Render what the two probe cameras see now and show the images (as in the paper's Fig. 4(c))"""

    bl_idname = "scanner.render_views"
    bl_label = "Render Probe Views"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        return idle() and _cell_built(context, cls)

    def execute(self, context):
        from ..core.config.render import with_sensor
        from ..core.config.render import RenderOptions

        s = context.scene.scanner
        try:
            mismatch = models.cell_mismatch(context)
            if mismatch is not None:
                raise InputError(models.stale_cell_message(mismatch))
            sc = models.scene_cell(context)
            if sc is None:
                gone = models.missing_cell_objects(context)
                raise InputError(f"The built cell lacks {', '.join(gone)} (deleted?): press Build Cell to build it "
                                 f"again" if gone else "Build the cell first (the probe settings may be invalid)")
            models.check_table_angle(s)
            hidden = models.hidden_from_render(context, [*sc.laser, sc.table, sc.workpiece_object])
            if hidden is not None:
                raise InputError(f"{hidden[:1].upper()}{hidden[1:]}: the probe views would not show what a scan "
                                 f"sees; show it for renders")
        except ScannerError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        frame = context.scene.frame_current
        engine = "eevee" if sc.laser_model == "spot" else "cycles"  # the spots are Eevee's line
        try:
            sensor = models.sensor_from(s)
            settings = with_sensor(RenderOptions(engine=engine, ambient=s.ambient, samples=4, filter_width_px=1.0),
                                   sensor)
            with kept_render_settings(context.scene):  # the scene's own render settings come back
                images = sc.render(frame, frame, settings)[0]
            if sensor.changes_images:
                images = [sensor.apply(img, sc.probe, camera, frame) for camera, img in enumerate(images)]
        except ScannerError as exc:  # the sensor's or the light's settings (a focus inside the lens, ...)
            self.report({"ERROR"}, f"Sensor realism: {exc}")
            return {"CANCELLED"}
        for camera, img in enumerate(images):
            name = f"Probe camera {camera}"
            H, W = img.shape[:2]
            target = bpy.data.images.get(name)
            if target is None or tuple(target.size) != (W, H):
                if target is not None:
                    bpy.data.images.remove(target)
                target = bpy.data.images.new(name, W, H, alpha=False, float_buffer=True)
            rgba = np.dstack([img, np.ones((H, W), np.float32)])[::-1]  # Blender rows run bottom-up
            target.pixels.foreach_set(rgba.ravel())
            target.update()
            # Kept with the .blend: a rendered image has no user (it would be dropped on save)
            # and no file (its pixels would be lost); packed, it is saved as EXR inside the file.
            target.use_fake_user = True
            target.pack()
        for area in (context.screen.areas if context.screen else []):
            if area.type == "IMAGE_EDITOR":
                area.spaces.active.image = bpy.data.images["Probe camera 0"]
                break
        self.report({"INFO"}, "Rendered 'Probe camera 0' and 'Probe camera 1' (see the Image Editor)")
        return {"FINISHED"}


def _message(exc: Exception) -> str:
    """One line for the status bar: the project's own errors as they are (a budget too small
    for any view naming the panel's field), others with their kind."""
    from ..adaptive import BudgetBelowView

    if isinstance(exc, BudgetBelowView):
        return (f"Adaptive scan: the budget of {exc.budget} profiles is below the smallest view's {exc.smallest}; "
                f"raise Profile Budget to at least {exc.smallest} (nothing was scanned)")
    return str(exc) if isinstance(exc, ScannerError) else f"{type(exc).__name__}: {exc}"


def _panel_config(context, config: str, path_required: bool = True):
    """A scan config: the operator's own (a name or a .toml path), else the panel's choice
    (``path_required=False``: the adaptive scan's, which ignores [[path]])."""
    from ..core.config.scan import load_scan_config

    s = context.scene.scanner
    if config:
        source = bpy.path.abspath(config) if config.endswith(".toml") else config
    elif s.scan_config == models.CELL:
        return _cell_config(s)
    else:
        source = models.chosen_file(s.scan_file, "scan") if s.scan_config == models.FILE else s.scan_config
    return load_scan_config(source, path_required=path_required)


def _cell_config(s):
    """The Cell panel's own cell as a scan config: its robot, probe (with the edited optics),
    workpiece (with its scale), material and laser, the path laid out for the part from its bounding
    box at the middle of the probe's range (core.kinematics.path.around_part), less the frames
    that would see nothing in range; the rest as the demo config has it."""
    from dataclasses import replace

    from ..core.config.scan import load_scan_config
    from ..core.kinematics.path import around_part
    from ..core.scan.plan import frames_in_range

    base = load_scan_config("demo")
    robot, probe, wp = models.robot_from(s), models.probe_from(s), models.workpiece_from(s)
    table = models.cell_from(s).table
    # The cell's own laser (the spots are Eevee's line); the Scan box's engine may still change it.
    render = replace(base.render, laser=s.laser, engine="eevee" if s.laser == "spot" else base.render.engine)
    return frames_in_range(replace(
        base, name=f"The cell built here, {wp.name}", source="", robot=robot, table=table, probe=probe, workpiece=wp,
        material=s.material, roughness=s.roughness, fixtures=(), render=render,
        q_start=base.start_joints_for(robot, table),
        waypoints=around_part(wp.mesh, table, standoff_mm=0.5 * sum(probe.z_range_mm))))


def _with_engine(context, cfg, engine: str):
    """The config rendered with the operator's ``engine``, else the Scan box's where it names
    one; one line where that engine cannot render this scan."""
    from ..core.config.render import ENGINES

    engine = engine.strip() or context.scene.scanner.scan_engine
    if engine == "CONFIG":
        return cfg
    if engine.lower() not in ENGINES:
        raise InputError(f"engine {engine!r} is not one of: {', '.join(ENGINES)} (empty: the Scan box's choice)")
    engine = engine.lower()
    try:
        return cfg.with_overrides(engine=engine)
    except InputError as exc:
        why = str(exc).removeprefix(f"--engine {engine}: ").removeprefix("--engine ")
        raise InputError(f"Engine {engine}: {why}") from None


def _report_warnings(op, report: dict) -> str:
    """Each of a scan's warnings as a warning report of ``op`` (the Info editor lists them);
    a note for its summary line saying how many there were."""
    warnings = report.get("warnings", [])
    for w in warnings:
        op.report({"WARNING"}, w)
    if not warnings:
        return ""
    return f" ({len(warnings)} warning{'s' if len(warnings) != 1 else ''}: see the Info editor or report.json)"


def _check_blend_relative(path: str, what: str, kind: str) -> None:
    """Refuse a path relative (//...) to a .blend never saved: it would land wherever Blender
    was started."""
    if path.startswith("//") and not bpy.data.filepath:
        raise InputError(f"the {what} {path} is relative to the .blend file, which is not saved yet: "
                         f"save it first, or give an absolute {kind}")


def _checked_output(folder: str, config_name: str, inputs=()):
    """The output folder a scan will write into, refused before any rendering where it cannot
    be written, or where it is relative (//...) to a .blend never saved (it would land
    wherever Blender was started)."""
    from ..core.files import check_output_folder
    from ..core.scan.outputs import OUTPUT_FILES

    _check_blend_relative(folder, "output folder", "folder")
    return check_output_folder(models.output_dir(folder, config_name), OUTPUT_FILES.values(), inputs=inputs)


def _error_text(e: dict) -> str:
    """The part's error for a message: RMS in µm, or why there is none."""
    return f"RMS {e['rms_um']:.1f} µm" if e.get("n") else "no point on the part (no error to give)"


def _colour_text() -> str:
    """The imported cloud's colour scale for a message ("" where it shows no error)."""
    from ..scene.cloud_object import error_scale_um

    top = error_scale_um(models.cell_object(models.CLOUD_NAME))
    return "" if top is None else (f"; colours from 0 µm (blue) to {top:.1f} µm (red), seen in the viewport's "
                                   f"Material Preview or Rendered shading")


class _SteppedScan:
    """What Scan and Adaptive Scan share: the work runs as a generator of chunks (about a
    second each); from the panel (invoke) a timer advances it, Blender stays responsive, the
    status bar and the progress bar follow it and Esc cancels; from a script (execute) it runs
    to its end. Either way the scene's render settings come back however it ends, and nothing
    is written or imported unless it finishes. Subclasses give ``_open`` (the scanner and its
    generator; raises on a refusal before anything renders), ``_progress_of`` (a yielded value
    as (done, total)) and ``_finish`` (results, cloud, message)."""

    _timer = None
    _scanner = None
    _steps = None
    _progress = (0, 0)
    _state = None
    _what = "Scanning"

    @classmethod
    def poll(cls, context):
        return idle()  # not while another scan runs

    def _start(self, context):
        self._completing = False
        self._state = RenderState(context.scene)  # put back when the work ends, however it ends
        robot = models.find_robot(context.scene)
        try:  # the pose to put back afterwards (none where a joint's property was deleted)
            self._pose = None if robot is None else (robot.get("robot_name"), rig.get_joints(robot).copy())
        except InputError:
            self._pose = None
        s = context.scene.scanner
        # A cell built here that the scan's config will stand in for: the message says so.
        self._swapped = robot is not None and (bool(getattr(self, "config", "")) or s.scan_config != models.CELL)
        self._built_before = _built_from_of_scene(context.scene) if self._swapped else None
        # Calibrate keeps the scan cloud through its rebuild (a scan replaces it with its own).
        from ..scene.cell import cell_object
        from ..scene.cloud_object import CLOUD_ROLE

        self._cloud_before = (self._swapped and isinstance(self, SCANNER_OT_calibrate)
                              and cell_object(CLOUD_ROLE, scene=context.scene) is not None)
        try:
            models.check_table_angle(s)
            self._scanner, self._steps = self._open(context)
            self._progress = self._progress_of(next(self._steps))  # plans (a refusal raises here)
            self._value = None
        except StopIteration as done:  # all done in one go
            self._value, self._steps = done.value, None
        except BaseException:
            self._scanner = self._steps = None
            self._restore()
            raise

    def _step(self) -> bool:
        """The next chunk; True when the work is done."""
        if self._steps is None:
            return True
        try:
            self._progress = self._progress_of(next(self._steps))
        except StopIteration as done:
            self._value = done.value
            return True
        return False

    _pose = None
    _swapped = False

    def _restore(self):
        state, self._state = self._state, None
        if state is not None:
            state.restore()
        self._put_back_pose()

    def _put_back_pose(self):
        """The robot's joints and the table's angle as the panel had them before the scan (the
        scan's own cell, where it built one, takes them too when its robot is the same): the
        Joints and Table boxes keep saying what the scene shows."""
        pose, self._pose = self._pose, None
        context = bpy.context
        robot = models.find_robot(context.scene)
        if robot is not None:
            drop_scan_motion(robot)  # the scan's keyframed motion would pull it back
        if pose is not None and robot is not None and robot.get("robot_name") == pose[0]:
            rig.set_joints(robot, pose[1])
        table = models.cell_object("Turntable")
        if table is not None:
            drop_scan_motion(table)  # (an artist's own animation of it comes back)
            table.rotation_euler[2] = context.scene.scanner.table_angle

    def _complete(self, context):
        scanner, self._scanner, self._steps = self._scanner, None, None
        self._completing = True  # (writing its files: a stop now may leave them written)
        try:
            return self._finish(context, scanner, self._value)
        finally:
            self._restore()

    def execute(self, context):
        try:
            self._start(context)
            while not self._step():
                pass
            return self._complete(context)
        except Exception as exc:  # any failure: the scene comes back as it was, and the user is told
            self._scanner = self._steps = None
            self._restore()
            self.report({"ERROR"}, _message(exc))
            return {"CANCELLED"}
        except KeyboardInterrupt:  # Ctrl-C (a script's, or the command line's stop): said, not a traceback
            self._scanner = self._steps = None
            self._restore()
            said = ("its files may have been written before the stop" if getattr(self, "_completing", False)
                    else "nothing was kept")
            self.report({"ERROR"}, f"{self.bl_label} stopped (Ctrl-C); {said}")
            return {"CANCELLED"}

    def invoke(self, context, event):
        try:
            self._start(context)
        except Exception as exc:
            self.report({"ERROR"}, _message(exc))
            return {"CANCELLED"}
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.01, window=context.window)
        wm.progress_begin(0, max(self._progress[1], 1))
        wm.modal_handler_add(self)
        _SCAN_RUNNING[0] = True
        models.status(context, f"{self._what}... (Esc to cancel)")
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC" and event.value == "PRESS":
            self._stop(context)
            self._scanner = self._steps = None  # partial results are discarded: nothing was written or imported
            self.report({"WARNING"}, f"{self.bl_label} cancelled; nothing was kept")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        try:
            done = self._step()
            context.window_manager.progress_update(self._progress[0])
            models.status(context, f"{self._what}: {self._progress[0]}/{self._progress[1]} {self._unit} "
                                   f"(Esc to cancel)")
            if not done:
                return {"RUNNING_MODAL"}
            self._stop(context)
            return self._complete(context)
        except Exception as exc:  # any failure: timer, progress bar and scene settings are put back
            self._stop(context)
            self._scanner = self._steps = None
            self.report({"ERROR"}, _message(exc))
            return {"CANCELLED"}
        except BaseException:
            self._stop(context)
            self._scanner = self._steps = None
            raise

    def cancel(self, context):
        """Blender ends the modal operator itself (a file opened, its window closed)."""
        self._stop(context)
        self._scanner = self._steps = None

    def _stop(self, context):
        _SCAN_RUNNING[0] = False
        wm = context.window_manager
        try:
            if self._timer is not None:
                wm.event_timer_remove(self._timer)
                self._timer = None
            wm.progress_end()
            models.status(context, None)
        finally:
            self._restore()


def _import_result(context, scanner, result) -> None:
    """The scan's cloud into the scene (in place of the last one), where the panel asks for it."""
    from ..scene.cloud_object import import_cloud

    old = models.cell_object(models.CLOUD_NAME)
    if old is not None:
        mesh = old.data
        bpy.data.objects.remove(old, do_unlink=True)
        if mesh is not None and mesh.users == 0:
            bpy.data.meshes.remove(mesh)
    if context.scene.scanner.import_cloud and scanner.scene_cell is not None:
        from ..scene.ownership import register_made

        sc = scanner.scene_cell
        cloud = import_cloud(sc.results_collection(), result.cloud, sc.table, result.error_um, name=models.CLOUD_NAME,
                             on_part=result.on_part, on_fixture=result.on_fixture)
        register_made(sc.root, cloud)  # the cell's (a copy the artist makes of it is theirs)


def _engine_property():
    """An operator's render engine, empty for the Scan box's (SKIP_SAVE: see SCANNER_OT_scan)."""
    return StringProperty(name="Engine", default="", options={"SKIP_SAVE"},
                          description="cycles, eevee or raycast (empty: the panel's choice)")


def _output_property(what: str):
    """An operator's output folder for ``what``, empty for the panel's; //-relative to the saved
    .blend file allowed (_checked_output resolves it)."""
    return StringProperty(name="Output", default="", subtype="DIR_PATH",
                          options={"SKIP_SAVE", "PATH_SUPPORTS_BLEND_RELATIVE"},
                          description=f"Folder for {what} (empty: the panel's)")


def _with_panel_sensor(context, cfg, config_given: str):
    """``cfg`` with the probe panel's sensor, material and light where the Scan box's Sensor
    says "From the probe panel" and no config was given to the operator itself."""
    s = context.scene.scanner
    if s.scan_sensor == "PANEL" and not config_given:
        return cfg.with_realism(models.sensor_from(s), s.material, s.roughness, s.ambient)
    return cfg


def _built_from_of_scene(scene) -> dict | None:
    """What the cell in ``scene`` was built from (scene.cell.built_from), None where none is."""
    from ..scene.cell import BUILT_FROM_KEY, CELL_NAME, in_scene

    root = bpy.data.collections.get(CELL_NAME)
    if root is None or not in_scene(root, scene) or BUILT_FROM_KEY not in root:
        return None
    return json.loads(root[BUILT_FROM_KEY])


def _swapped_text(op, report: dict, config=None) -> str:
    """The message's note where the scan took the config's cell in place of a different
    Scanner Cell (not where the cell there was that config's own: a scan of a config left its
    cell, and every later scan of it said it had been swapped in)."""
    if not op._swapped:
        return ""
    before, cfg = getattr(op, "_built_before", None), config
    if before is not None and cfg is not None:
        from ..scene.cell import built_from

        now = built_from(cfg.robot, cfg.probe, cfg.workpiece, cfg.table)
        if all(before.get(k) == now[k] for k in ("robot", "robot_poses", "probe", "workpiece", "table")):
            return ""
    kept = " (the scan cloud there is the earlier cell's)" if getattr(op, "_cloud_before", False) else ""
    return (f"; the cell is the scan config's ({report['config']['name']}){kept}: choose The Cell Built Here to scan "
            f"the Scanner Cell's own")


class SCANNER_OT_scan(_SteppedScan, bpy.types.Operator):
    """Run the chosen scan: render, detect, triangulate, and bring the cloud into the scene (Esc cancels)"""

    bl_idname = "scanner.scan"
    bl_label = "Scan"
    bl_options = {"REGISTER", "UNDO"}
    _unit = "frames"

    # The operator carries its parameters, so that a script can call
    # bpy.ops.scanner.scan(config="step_block", frames="0:100:20", output_dir="/tmp/scans")
    # without touching the panel; an empty value takes the panel's setting. SKIP_SAVE: each
    # press of a panel button starts from the Scan box, not from the last call's values.
    config: StringProperty(name="Config", default="", options={"SKIP_SAVE"},
                           description="Scan config: a bundled name or a .toml path (empty: the panel's choice)")
    frames: StringProperty(name="Frames", default="", options={"SKIP_SAVE"},
                           description="Part of the path, as A:B or A:B:STEP (empty: the panel's, else all)")
    engine: _engine_property()
    output_dir: _output_property("cloud.ply, report.json, preview.png")

    def _config(self, context):
        from ..core.config.scan import parse_frames

        s = context.scene.scanner
        cfg = _panel_config(context, self.config).with_overrides(frames=parse_frames(self.frames or s.scan_frames))
        return _with_engine(context, _with_panel_sensor(context, cfg, self.config), self.engine)

    def _open(self, context):
        from ..scanner import Scanner

        config = self._config(context)
        self._folder = _checked_output(self.output_dir or context.scene.scanner.output_dir, config.name,
                                       config.input_files())
        scanner = Scanner(config=config, scene=context.scene)
        return scanner, scanner.run_steps()

    @staticmethod
    def _progress_of(value):
        return value  # (frames done, frames in all)

    def _finish(self, context, scanner, _):
        result = scanner.result(self._folder)
        if not result.report["points"]:  # nothing to bring in
            codes = ", ".join(f"{k.lower()} {v}" for k, v in sorted(result.report["column_codes"].items())
                              if k != "OK" and v)
            # (A scan that built its cell afresh took the old cell's cloud with it.)
            kept = ("the scene's cloud is left as it was" if models.cell_object(models.CLOUD_NAME) is not None
                    else "no cloud is brought in")
            self.report({"WARNING"}, f"Scanned 0 points: no sensor column gave one ({codes or 'no columns'}); {kept}; "
                                     f"files in {result.files['cloud'].parent}")
            return {"FINISHED"}
        _import_result(context, scanner, result)
        warned = _report_warnings(self, result.report)
        self.report({"INFO"}, f"Scanned {result.report['points']} points, {_error_text(result.report['error_um'])}; "
                              f"files in {result.files['cloud'].parent}{_colour_text()}{warned}"
                              f"{_swapped_text(self, result.report, scanner.config)}")
        return {"FINISHED"}


class SCANNER_OT_export_ply(bpy.types.Operator, ExportHelper):
    """Save the scanned cloud (table frame, mm, with frame, camera and quality per point) as binary PLY"""

    bl_idname = "scanner.export_ply"
    bl_label = "Export PLY"
    filename_ext = ".ply"
    filter_glob: StringProperty(default="*.ply", options={"HIDDEN"})

    @classmethod
    def poll(cls, context):
        if models.cell_object(models.CLOUD_NAME, scene=context.scene) is None:  # this scene's, not another's
            cls.poll_message_set("There is no scanned cloud in the scene: Scan first")
            return False
        return True

    def execute(self, context):
        from ..core.geometry.cloud import save_ply
        from ..scene.cloud_object import cloud_from_object

        given = models.panel_path(self.filepath)
        target = bpy.path.ensure_ext(given, ".ply")
        folder = os.path.dirname(target) or "."
        try:
            if not self.filepath.strip():
                raise InputError("export needs a file name, and none was given")
            _check_blend_relative(self.filepath, "file", "path")
            if os.path.isdir(given):
                raise InputError(f"export needs a file name, got the folder {given}")
            if not os.path.isdir(folder):  # a file dialog's export goes into a folder that is there
                raise InputError(f"{folder} is a file, not a folder" if os.path.exists(folder) else
                                 f"the folder {folder} does not exist (create it first)")
            cloud = cloud_from_object(models.cell_object(models.CLOUD_NAME, scene=context.scene))
            path = save_ply(cloud, target)
        except (ScannerError, OSError) as exc:
            # The file's name, never the temporary one it is written to first.
            text = _message(exc) if isinstance(exc, ScannerError) else f"{target}: {exc.strerror or exc}"
            self.report({"ERROR"}, f"Export PLY: {text} (nothing written)")
            return {"CANCELLED"}
        self.report({"INFO"}, f"Wrote {len(cloud)} points to {path}")
        return {"FINISHED"}


class SCANNER_OT_calibrate(_SteppedScan, bpy.types.Operator):
    """Calibrate the probe of the chosen scan config from rendered ChArUco boards and laser lines; writes probe.toml, calibration.json and calibration.png (builds the chosen config's cell, keeping the scan cloud; Esc cancels)"""

    bl_idname = "scanner.calibrate"
    bl_label = "Calibrate Probe"
    bl_options = {"REGISTER"}
    _what = "Calibrating"
    _unit = "images"

    config: StringProperty(name="Config", default="", options={"SKIP_SAVE"},
                           description="Scan config whose cell and probe are calibrated (empty: the panel's choice)")
    views: IntProperty(name="Board Poses", default=20, min=4, max=1000,
                       description="Poses from which the robot shows the board to the probe")
    output_dir: _output_property("the calibration's files")

    def _open(self, context):
        from ..calibrate import calibrate_steps

        # The sensor and material a scan from the panel would have: the images are calibrated on
        # as they will be scanned with, and the cell is the one a scan builds.
        cfg = _with_panel_sensor(context, _panel_config(context, self.config), self.config)
        # Checked as a scan's folder is (a //-folder of a .blend never saved wrote into
        # wherever Blender was started)
        self._folder = _checked_output(self.output_dir or context.scene.scanner.output_dir, f"{cfg.name} calibration")
        self._cfg = cfg
        return None, calibrate_steps(cfg, self._folder, views=self.views, scene=context.scene)

    @staticmethod
    def _progress_of(value):
        return value  # (images rendered, images in all)

    def _finish(self, context, _, run):
        c0, c1 = run.summary["camera0"], run.summary["camera1"]
        err = run.summary["triangulation_error"]["all"]["rms_mm"] * 1e3
        self.report({"INFO"}, f"Calibrated from {run.summary['views']} poses: reprojection "
                              f"{c0['reprojection_error_px']:.3f}/{c1['reprojection_error_px']:.3f} px, "
                              f"{err:.0f} µm RMS on the laser plane; files in {self._folder}"
                              f"{_swapped_text(self, {'config': {'name': self._cfg.name}}, self._cfg)}")
        return {"FINISHED"}


class SCANNER_OT_adaptive(_SteppedScan, bpy.types.Operator):
    """Scan the chosen config's part adaptively: the next-best-view planner, told only the part's bounding box, picks sweep after sweep; writes what a scan writes and brings the cloud in (Esc cancels)"""

    bl_idname = "scanner.adaptive"
    bl_label = "Adaptive Scan"
    bl_options = {"REGISTER", "UNDO"}
    _what = "Adaptive scan"
    _unit = "profiles of the budget"

    config: StringProperty(name="Config", default="", options={"SKIP_SAVE"},
                           description="Scan config (its [[path]] is ignored; empty: the panel's choice)")
    max_profiles: IntProperty(name="Profile Budget", default=0, min=0, max=MAX_PROFILES, options={"SKIP_SAVE"},
                              description="Profiles the planner may take (0: the panel's, else the config's "
                                          "[adaptive] budget)")
    target_coverage: FloatProperty(name="Target Coverage", default=0.0, min=0.0, max=1.0, subtype="FACTOR",
                                   description="Stop once the planner's own coverage estimate reaches this share "
                                               "(0: the config's [adaptive] target, else none)")
    engine: _engine_property()
    output_dir: _output_property("cloud.ply, report.json, preview.png")

    def _open(self, context):
        from ..scanner import Scanner

        s = context.scene.scanner
        given = _panel_config(context, self.config, path_required=False)  # the planner ignores [[path]]
        cfg = _with_engine(context, _with_panel_sensor(context, given, self.config), self.engine)
        self._budget = self.max_profiles or s.adaptive_budget or cfg.adaptive.max_profiles
        self._folder = _checked_output(self.output_dir or context.scene.scanner.output_dir, f"{cfg.name} adaptive",
                                       cfg.input_files())
        scanner = Scanner(config=cfg, scene=context.scene)
        return scanner, scanner.adaptive_steps(max_profiles=self._budget,
                                               target_coverage=self.target_coverage or None)

    def _progress_of(self, taken):
        return taken, self._budget

    def _finish(self, context, scanner, steps):
        if not steps:  # (a budget below every view is refused before: _message)
            self.report({"WARNING"}, f"Adaptive scan: no reachable sweep fits the budget of {self._budget} profiles "
                                     f"and promises enough new surface; nothing was scanned")
            return {"CANCELLED"}
        result = scanner.result(self._folder)
        _import_result(context, scanner, result)
        r = result.report
        views = f"{len(steps)} view{'s' if len(steps) != 1 else ''}"
        warned = _report_warnings(self, r)
        self.report({"INFO"}, f"Adaptive scan: {views}, {r['frames']} profiles, {r['points']} points, "
                              f"{_error_text(r['error_um'])}; files in {result.files['cloud'].parent}{_colour_text()}"
                              f"{warned}{_swapped_text(self, r, scanner.config)}")
        return {"FINISHED"}


CLASSES = (SCANNER_OT_build_cell, SCANNER_OT_load_probe, SCANNER_OT_go, SCANNER_OT_render_views, SCANNER_OT_scan,
           SCANNER_OT_adaptive, SCANNER_OT_calibrate, SCANNER_OT_export_ply)
