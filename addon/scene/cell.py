"""The scanning cell in Blender, built from the core models.

Collections: ``Robot`` (armature, links, probe housing: never seen by the probe
cameras, hidden from their renders), ``Probe`` (the probe frame, its two cameras
and the laser) and ``Table`` (turntable and workpiece). The probe frame is an
empty parented to the last bone through the tool transform T_L^6 (the probe's
mount, which becomes the robot's tool).
"""

from __future__ import annotations

import json
from contextlib import contextmanager
from dataclasses import dataclass, field, replace

import bpy
import numpy as np
import trimesh
from mathutils import Matrix

from ..core.kinematics.cell import Cell
from ..core.errors import InputError
from ..core.kinematics.transforms import rigid_inverse
from ..core.optics.probe import Probe
from ..core.geometry.workpiece import Workpiece
from . import rig
from .animation import (ARTIST_ACTION_KEY, SCAN_MOTION_KEY, keyframe_values, mark_scan_motion,
                        set_aside_own_motion)
from .cameras import add_probe_cameras, camera_to_world_cv
from .laser import add_laser
from .materials import diffuse
from .meshes import mesh_object
from .ownership import built_role, mark, own_objects, recorded_objects, register_built, role_of
from ..core.config.render import RenderOptions, laser_engine_mismatch
from .render import EXPOSURE_KEY_FRAMES, configure, ctrl_c_after_render, opengl_device, render_animation
from .turntable import add_fixture, add_turntable, add_workpiece, set_table_angle
from .units import from_blender, points_to_blender


RESULTS = "Scan results"


CELL_NAME = "Scanner Cell"


BUILT_FROM_KEY = "scanner_built_from"  # on the cell's collection: what it was built from (built_from)
_SAMPLE_JOINTS = np.array([[0.0] * 6, [0.3, -0.4, 0.5, -0.6, 0.7, -0.8]])


def built_from(robot, probe: Probe, workpiece: Workpiece | None, table=None) -> dict:
    """What tells one cell from another, as plain values: the robot's name and its flange
    at two joint vectors (a robot file edited under the same name differs), the probe's
    optics, sensor, line and mount, the part's source and size, the table's place (Eq. 4's
    a_R and d_R). The panel compares the cell it describes with the one in the scene before
    it moves or renders that one."""
    flange = np.array([robot.link_frames(q)[-1] for q in _SAMPLE_JOINTS])  # without the tool: the probe's part
    out = {"robot": robot.name, "robot_poses": flange,
           "table": None if table is None else [table.a_mm, table.d_mm],
           "probe": [probe.name, probe.a_mm, probe.b_mm, probe.phi_rad, probe.gamma_rad, probe.rows_px,
                     probe.cols_px, probe.line_width_mm, probe.mount],
           "workpiece": None if workpiece is None else [workpiece.source, workpiece.mesh.bounds]}
    return json.loads(json.dumps(_six_figures(out)))  # as it reads back from the file: lists, floats


def _six_figures(value):
    """Numbers to six significant figures, arrays as lists, within dicts and lists: the panel's
    fields hold single precision, so a probe read from its rig file and the same probe through
    the fields differ in the eighth figure."""
    if isinstance(value, dict):
        return {k: _six_figures(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return _six_figures(value.tolist())
    if isinstance(value, (list, tuple)):
        return [_six_figures(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(f"{float(value):.6g}") + 0.0  # (+ 0.0: no -0.0)
    return value


def in_scene(root: bpy.types.Collection, scene: bpy.types.Scene) -> bool:
    """Is the cell's collection in ``scene``, at its top or filed in one of its collections?"""
    return root in scene.collection.children_recursive


def cell_object(name: str, cell_name: str = CELL_NAME, scene=None):
    """The built cell's object that is ``name`` ("Robot", "Turntable", ...: its role, whatever
    Blender named it), or None; with ``scene``, None too where the cell is not in that scene
    (a file holds one cell: Build Cell in another scene takes it there)."""
    root = bpy.data.collections.get(cell_name)
    if root is None or (scene is not None and not in_scene(root, scene)):
        return None
    return next((o for o in own_objects(root) if role_of(o) == name), None)


@dataclass
class SceneCell:
    """Handles on the Blender objects of a built cell, and the core models behind them."""

    scene: bpy.types.Scene
    cell: Cell
    probe: Probe
    workpiece: Workpiece | None
    laser_model: str
    root: bpy.types.Collection
    robot_collection: bpy.types.Collection
    robot: bpy.types.Object
    probe_frame: bpy.types.Object
    cameras: list
    laser: list
    table: bpy.types.Object
    workpiece_object: bpy.types.Object | None
    extras: dict = field(default_factory=dict)
    device_used: str | None = None  # the render device of the last render ("CPU", "GPU (OPTIX: ...)")

    @classmethod
    def attach(cls, scene, cell: Cell, probe: Probe, workpiece: Workpiece | None, name: str = "Scanner Cell"
               ) -> "SceneCell | None":
        """Handles on a cell built earlier (e.g. by the panel before a file save), or None."""
        root = bpy.data.collections.get(name)
        if root is None or not in_scene(root, scene):
            return None
        objs = {role_of(o): o for o in own_objects(root)}
        robot_col = root.children.get("Robot")
        need = ("Robot", "Probe frame", "ProbeCam_L", "ProbeCam_R", "Laser", "Turntable")
        if robot_col is None or any(k not in objs for k in need):
            return None
        wp = next((o for n, o in objs.items() if n.startswith("Workpiece ") and "twin" not in n), None)
        model = objs["Laser"].get("laser_model", "slit" if "Laser slit" in objs else "gobo")
        laser = [objs["Laser"]] + [objs[n] for n in sorted(objs) if n.startswith("Laser ")]
        cell = replace(cell, robot=cell.robot.with_tool(probe.mount))
        return cls(scene, cell, probe, workpiece, model, root, robot_col,
                   objs["Robot"], objs["Probe frame"], [objs["ProbeCam_L"], objs["ProbeCam_R"]], laser,
                   objs["Turntable"], wp)

    def alive(self) -> bool:
        """Whether Blender still holds every object this handle names: another cell built in the
        same session (a second Scanner, the panel's Build Cell) removes this one's."""
        held = [self.root, self.robot_collection, self.robot, self.probe_frame, self.table, *self.cameras,
                *self.laser, *([] if self.workpiece_object is None else [self.workpiece_object])]
        try:
            for item in held:
                item.name  # noqa: B018 - raises ReferenceError once Blender has removed it
        except ReferenceError:
            return False
        return True

    # -- posing -------------------------------------------------------------------
    def pose(self, q, table_angle_rad: float = 0.0) -> None:
        """Set joints q (6,) rad and the table angle; the scene is updated."""
        q = self.cell.robot.check_q(q)
        set_table_angle(self.table, table_angle_rad)
        rig.set_joints(self.robot, q)

    def keyframe(self, qs, table_angles_rad=None, first_frame: int = 1, segments=None, path_frames=None) -> range:
        """Keyframe a path: qs (n, 6) rad and table angles (n,) at frames first..first+n−1.
        ``segments`` (n,): each frame's path entry (default one entry); ``path_frames`` (n,): its
        number in the whole path (default consecutive), where only some frames are scanned
        (``--frames 0:60:10``). Motion blur takes the probe's motion from both: within its own
        path entry, per frame of the whole path."""
        qs = self.cell.robot.check_q(qs)
        if qs.ndim != 2:
            raise InputError("keyframe needs joint vectors of shape (n, 6)")
        n = len(qs)
        thetas = np.zeros(n) if table_angles_rad is None else np.asarray(table_angles_rad, dtype=np.float64)
        if thetas.shape != (n,) or not np.all(np.isfinite(thetas)):
            raise InputError(f"table angles must be {n} finite numbers (radians)")
        frames = np.arange(first_frame, first_frame + n)
        for obj in (self.robot, self.table):
            set_aside_own_motion(obj)  # an artist's animation, given back by drop_scan_motion
        for k in range(6):
            keyframe_values(self.robot, f'["{rig.joint_property(k + 1)}"]', frames, qs[:, k])
        keyframe_values(self.table, "rotation_euler", frames, thetas, index=2)
        for obj in (self.robot, self.table):
            mark_scan_motion(obj)
        # The probe's world pose per frame, for renders that leave the rig out.
        segments = np.zeros(n, dtype=int) if segments is None else np.asarray(segments).reshape(n)
        path_frames = np.arange(n) if path_frames is None else np.asarray(path_frames, dtype=np.float64).reshape(n)
        self.extras["path"] = (int(first_frame), self.cell.robot.fk(qs), thetas.copy(), segments, path_frames)
        return range(first_frame, first_frame + n)

    # -- what Blender has -----------------------------------------------------------
    def probe_to_world_mm(self) -> np.ndarray:
        return from_blender(self.probe_frame.matrix_world)

    def camera_to_world_mm(self, camera: int) -> np.ndarray:
        return camera_to_world_cv(self.cameras[camera])

    def dh_frames_mm(self) -> np.ndarray:
        return rig.dh_frames(self.robot, self.cell.robot)

    # -- rendering ----------------------------------------------------------------
    def results_collection(self) -> bpy.types.Collection:
        """Where scan results (clouds) go: shown in the scene, never in the probe cameras' images."""
        col = self.root.children.get(RESULTS)
        if col is None:
            col = _child_collection(self.root, RESULTS)
        return col

    def render(self, first: int, last: int, settings: RenderOptions | None = None, cameras=(0, 1),
               out_dir=None, rows: tuple[int, int] | None = None, leave_out_robot: bool = True,
               move_table: bool | None = None) -> list[list[np.ndarray | None]]:
        """Probe images for frames first..last in one render call ([frame][camera], float32 (H, W, 3)).

        ``rows`` = (r0, r1) renders and returns only those rows. The robot never
        appears in the probe images, so it is left out (unless ``leave_out_robot``
        is False): when the frames were
        keyframed with :meth:`keyframe`, the probe frame follows its own keyframed
        world pose and the rig is not evaluated at all.
        """
        settings = settings or RenderOptions()
        if settings.engine == "raycast":  # the raycast engine computes Cycles' image: in Blender, that is Cycles
            settings = replace(settings, engine="cycles")
        mismatch = laser_engine_mismatch(settings.engine, self.laser_model)
        if mismatch:
            raise InputError(f"this cell's laser: {mismatch}")
        # The render settings' updates free Cycles' earlier engines, whose Python finaliser
        # would swallow a Ctrl-C landing in it: the deferral holds from here to the restore.
        with ctrl_c_after_render():
            self.device_used = configure(self.scene, self.probe, settings, self.cameras[0])
            with self._only_the_cell():
                if not leave_out_robot:  # for comparison: the rig evaluated and rendered with everything else
                    images = render_animation(self.scene, first, last, cameras, out_dir, rows)
                else:
                    if move_table is None:  # Cycles does not motion-blur lights: with motion blur, move the part
                        move_table = settings.motion_blur_shutter > 0
                    with self._without_rig(first, last, move_table):
                        images = render_animation(self.scene, first, last, cameras, out_dir, rows)
        if settings.engine == "eevee":  # its OpenGL device is known once it has rendered
            self.device_used = opengl_device() or self.device_used
        return images

    @contextmanager
    def _only_the_cell(self):
        """Probe renders see the cell and nothing else: the scene's own objects (an artist's
        lights, props, an imported cloud) are hidden from rendering meanwhile. The room's
        light, when wanted, is the render settings' ambient."""
        results = self.root.children.get(RESULTS)
        mine = {o.name for o in self.root.all_objects}
        if results is not None:
            mine -= {o.name for o in results.all_objects}
        hidden = [o for o in self.scene.objects if o.name not in mine and not o.hide_render]
        for o in hidden:
            o.hide_render = True
        try:
            yield
        finally:
            for o in hidden:
                o.hide_render = False

    @contextmanager
    def _without_rig(self, first: int, last: int, move_table: bool = False):
        """Leave the robot out of probe renders.

        When the frames were keyframed with :meth:`keyframe`, the table and the
        workpiece are held still at the world origin and the probe (cameras and
        laser) moves by its pose in the table frame instead: the images depend only
        on relative poses, and Cycles rebuilds the acceleration structure of every
        mesh that moves, each frame, so moving the probe is far cheaper than turning
        a dense workpiece. The rig is excluded from the view layer, not evaluated.
        Otherwise the rig stays evaluated but is not rendered. With ``move_table`` the
        probe stays at the origin and the table moves by the inverse pose instead (for
        motion blur: Cycles blurs moving objects and cameras, but not moving lights).
        """
        path = self.extras.get("path")
        if path is None or not (path[0] <= first and last < path[0] + len(path[1])):
            self.robot_collection.hide_render = True
            try:
                yield
            finally:
                self.robot_collection.hide_render = False
            return
        start, probe2base, thetas, segments, path_frames = path
        frames = np.arange(start, start + len(probe2base))
        probe2table = self.cell.table.base2table(thetas) @ probe2base  # Eq. 8
        quats = np.array([Matrix(T[:3, :3].tolist()).to_quaternion()[:] for T in probe2table])
        pf, table = self.probe_frame, self.table
        saved_pf = (pf.parent, pf.parent_type, pf.parent_bone, pf.matrix_parent_inverse.copy(), pf.matrix_basis.copy(),
                    pf.rotation_mode)
        saved_table = (table.animation_data.action if table.animation_data else None, table.matrix_basis.copy())
        layer = _layer_collection(self.scene.view_layers[0].layer_collection, self.robot_collection)
        if table.animation_data:
            table.animation_data.action = None
        table.matrix_basis.identity()
        pf.parent = None
        pf_action = pf.animation_data.action if pf.animation_data else None  # an artist's, set aside
        if pf_action is not None:
            pf.animation_data.action = None
        moving, poses = (table, rigid_inverse(probe2table)) if move_table else (pf, probe2table)
        if move_table:
            pf.matrix_basis.identity()
            quats = np.array([Matrix(T[:3, :3].tolist()).to_quaternion()[:] for T in poses])
        saved_mode = moving.rotation_mode
        moving.rotation_mode = "QUATERNION"
        values = np.column_stack([points_to_blender(poses[:, :3, 3]), quats])
        keys = frames.astype(np.float64)
        if move_table:  # motion blur: the motion during each frame's exposure, none across a jump
            keys, values = exposure_keys(keys, values, segments, path_frames)
        for i in range(3):
            keyframe_values(moving, "location", keys, values[:, i], index=i)
        for i in range(4):
            keyframe_values(moving, "rotation_quaternion", keys, values[:, 3 + i], index=i)
        layer.exclude = True
        try:
            yield
        finally:
            layer.exclude = False
            if move_table:
                temp = table.animation_data.action
                table.animation_data.action = None
                if temp is not None and temp is not saved_table[0]:
                    bpy.data.actions.remove(temp)
            temp = pf.animation_data.action if pf.animation_data else None
            pf.animation_data_clear()
            if temp is not None and temp is not pf_action and temp.users == 0:  # the motion keyed for this render
                bpy.data.actions.remove(temp)
            if pf_action is not None:
                pf.animation_data_create().action = pf_action
            moving.rotation_mode = saved_mode
            pf.rotation_mode = saved_pf[5]
            pf.parent, pf.parent_type, pf.parent_bone = saved_pf[0], saved_pf[1], saved_pf[2]
            pf.matrix_parent_inverse, pf.matrix_basis = saved_pf[3], saved_pf[4]
            if saved_table[0] is not None:
                table.animation_data.action = saved_table[0]
            table.matrix_basis = saved_table[1]
            bpy.context.view_layer.update()


def exposure_keys(frames: np.ndarray, values: np.ndarray, segments: np.ndarray, path_frames: np.ndarray):
    """Keys (times (3n,), values (3n, 7): location m, quaternion) that move the probe during
    each frame's exposure as it moves along the path there, and nowhere else: each frame
    keyed at its own pose and EXPOSURE_KEY_FRAMES either side, along its motion per frame of
    the whole path (from the neighbours in its own path entry; one side's where the other is
    another entry's or missing; none for a frame alone in its entry). Keyed only at the
    frames themselves, the shutter of an entry's last frame swept the probe halfway to the
    next entry's first pose (hundreds of µm on the tilted plate), and with every tenth frame
    scanned it swept ten frames' motion."""
    n = len(frames)
    values = np.array(values, dtype=np.float64)
    q = values[:, 3:]
    for i in range(1, n):  # q and −q are one turn: keep neighbours on one side for the straight line
        if segments[i] == segments[i - 1] and np.dot(q[i], q[i - 1]) < 0:
            q[i] = -q[i]
    ahead = np.zeros_like(values)  # motion per frame of the path after each frame
    behind = np.zeros_like(values)  # ... and before it
    same = segments[1:] == segments[:-1]
    step = np.diff(path_frames)[:, None]
    rate = np.where(same[:, None] & (step > 0), np.diff(values, axis=0) / np.where(step > 0, step, 1.0), 0.0)
    ahead[:-1], behind[1:] = rate, rate
    has_ahead = np.zeros(n, bool)
    has_behind = np.zeros(n, bool)
    has_ahead[:-1], has_behind[1:] = same, same
    ahead[~has_ahead & has_behind] = behind[~has_ahead & has_behind]
    behind[~has_behind & has_ahead] = ahead[~has_behind & has_ahead]
    h = EXPOSURE_KEY_FRAMES
    times = np.column_stack([frames - h, frames, frames + h]).ravel()
    keyed = np.stack([values - h * behind, values, values + h * ahead], axis=1).reshape(3 * n, -1)
    return times, keyed


def _layer_collection(layer, collection):
    """The view layer's entry for ``collection`` (searched depth first)."""
    if layer.collection == collection:
        return layer
    for child in layer.children:
        found = _layer_collection(child, collection)
        if found is not None:
            return found
    return None


def _child_collection(parent: bpy.types.Collection, name: str) -> bpy.types.Collection:
    col = bpy.data.collections.new(name)
    parent.children.link(col)
    return col


def remove_cell(scene: bpy.types.Scene, name: str = "Scanner Cell") -> None:
    """Delete a previously built cell: its collections, the objects it made and their data
    (meshes, lights, cameras, armatures, materials, actions) that nothing else uses. An object
    of the artist's filed in the cell's collections is kept, linked to the scene."""
    root = bpy.data.collections.get(name)
    if root is None:
        return
    collections = [root, *root.children_recursive]
    own = own_objects(root)
    own_names = {o.name for o in own}
    # The artist's objects filed with the cell stay in the scene that held it (Build Cell in
    # another scene takes the cell there, not their objects out of theirs).
    home = next((s for s in bpy.data.scenes if in_scene(root, s)), scene)
    for col in collections:
        for obj in list(col.objects):
            if obj.name not in own_names:
                col.objects.unlink(obj)
                if not obj.users_collection:
                    home.collection.objects.link(obj)
    # The cell's objects the artist deleted: their record kept them from being freed.
    own += [o for o in (recorded_objects(root) or []) if not o.users_collection and o not in own]
    data = []
    for obj in own:
        data += [obj.data] if obj.data is not None else []
        data += [slot.material for slot in obj.material_slots if slot.material is not None]
        if obj.animation_data is not None and obj.animation_data.action is not None:
            data.append(obj.animation_data.action)
    bpy.data.batch_remove(own)
    data += [m for d in data if isinstance(d, bpy.types.Mesh) for m in d.materials if m is not None]
    # Each scan or build left about fifteen meshes, two cameras and a light behind without users.
    unused = {d.name_full: d for d in data if d.users == 0 and not d.use_fake_user}
    if unused:
        bpy.data.batch_remove(list(unused.values()))
    for col in reversed(collections):
        bpy.data.collections.remove(col)


def _children_kept(root: bpy.types.Collection) -> list:
    """The artist's objects parented to one of the cell's: (object, the parent's role, parent
    type, parent bone, world matrix, pose in the parent's frame), to put back on the rebuilt
    cell where they were on their parent."""
    own_names = {o.name for o in own_objects(root)}
    made = own_names | {o.name for o in recorded_objects(root) or []}  # (the cell's that the artist deleted too)
    return [(o, role_of(o.parent), o.parent_type, o.parent_bone, o.matrix_world.copy(),
             _parent_frame(o).inverted() @ o.matrix_world)
            for o in bpy.data.objects if o.name not in made and o.parent is not None
            and o.parent.name in own_names]


def _parent_frame(obj):
    """The world frame ``obj`` hangs from: its parent's, or its parent bone's as posed now."""
    parent = obj.parent
    if obj.parent_type == "BONE" and parent.pose is not None and obj.parent_bone in parent.pose.bones:
        return parent.matrix_world @ parent.pose.bones[obj.parent_bone].matrix
    return parent.matrix_world.copy()


def _own_motions(root: bpy.types.Collection) -> dict:
    """{role: action} of the cell's objects that hold an action of their own (an artist's
    animation, also one a scan set aside), not a scan's motion: the rebuilt cell's objects
    of the same roles get them back."""
    out = {}
    for obj in own_objects(root):
        action = obj.get(ARTIST_ACTION_KEY)
        if action is None and obj.animation_data is not None:
            action = obj.animation_data.action
        if action is not None and not action.get(SCAN_MOTION_KEY):
            out[role_of(obj)] = action
    return out


def _put_back(kept: list, root: bpy.types.Collection) -> None:
    """Parent each of :func:`_children_kept`'s objects to the rebuilt cell's object of the same
    role, where it was on the old one: a prop on the turntable stays on the same spot of the
    table, which the rebuilt table (at 0°, or the panel's angle once set again) carries round.
    Where the rebuilt cell has no such object it is unparented, where it was in the world."""
    roles = {role_of(o): o for o in own_objects(root)}
    for obj, role, parent_type, bone, world, on_parent in kept:
        parent = roles.get(role)
        obj.parent = parent
        if parent is None:
            obj.matrix_world = world
            continue
        obj.parent_type = parent_type
        if parent_type == "BONE":
            obj.parent_bone = bone
        obj.matrix_world = _parent_frame(obj) @ on_parent


def add_probe(collection, probe: Probe, laser: str = "gobo", laser_power_w: float | None = None,
              housing_collection=None):
    """The probe frame (an empty at the world origin until parented), its cameras, laser and housing.

    Returns (probe_frame, [camera 0, camera 1], [laser objects]).
    """
    probe_frame = bpy.data.objects.new("Probe frame", None)
    probe_frame.empty_display_type = "ARROWS"
    probe_frame.empty_display_size = 0.03
    collection.objects.link(probe_frame)
    _, extents, centre = probe.body_boxes()[0]  # behind the cameras and the laser (z < 0)
    housing = trimesh.creation.box(extents)
    housing.apply_translation(centre)
    body = mesh_object("Probe housing", housing, housing_collection or collection,
                       diffuse("Probe housing", (0.08, 0.08, 0.1)))
    body.parent = probe_frame
    body.matrix_parent_inverse.identity()
    cams = add_probe_cameras(collection, probe, probe_frame)
    lasers = add_laser(collection, probe, probe_frame, laser, laser_power_w)
    return probe_frame, cams, lasers


def _check_robot_meshes(robot) -> None:
    """Every link and base mesh of ``robot`` reads as a mesh with faces; InputError naming the
    file otherwise."""
    import trimesh

    from ..core.errors import InputError
    from ..core.kinematics.link_shapes import base_mesh, link_mesh

    def named(entry) -> str:
        return entry[0] if entry and isinstance(entry[0], str) else "its own geometry"

    entries = [(f"link {k + 1}", named(robot.link_meshes[k] if robot.link_meshes else ()),
                lambda k=k: link_mesh(robot, k)) for k in range(6)]
    entries.append(("base", named(robot.base_mesh), lambda: base_mesh(robot)))
    for what, source, load in entries:
        try:
            mesh = load()
        except Exception as exc:  # trimesh raises many kinds for a file that is gone or not a mesh
            raise InputError(f"the {what} mesh of {robot.name} ({source}) cannot be read now "
                             f"({type(exc).__name__}: {exc}); the cell is left as it was") from None
        if mesh is not None and (not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0):
            raise InputError(f"the {what} mesh of {robot.name} ({source}) has no faces now; the cell is left as "
                             f"it was")


def surface_key(material: str, roughness: float) -> list:
    """The workpiece's surface as the cell records it: a roughness counts only for the
    surfaces that have one."""
    return [material, round(float(roughness), 6) if material == "glossy" else None]


def build_cell(scene: bpy.types.Scene, cell: Cell, probe: Probe, workpiece: Workpiece | None = None,
               laser: str = "gobo", laser_power_w: float | None = None, name: str = "Scanner Cell",
               material: str = "grey", roughness: float = 0.2, fixtures=()) -> SceneCell:
    """Build (or rebuild) the cell in ``scene``. The probe's mount becomes the robot's tool;
    ``fixtures`` (the table's: ``core.safety.Fixture``) turn with the table. The artist's
    objects parented to the cell's stay where they were, on the new cell's. What can fail is
    checked before the old cell goes (a link mesh changed on disk since the rig was read, a
    roughness that is not a number): a failed build left half a cell."""
    _check_robot_meshes(cell.robot)
    if workpiece is not None:
        from .materials import surface

        surface(material, roughness)
    old_root = bpy.data.collections.get(name)
    kept = [] if old_root is None else _children_kept(old_root)
    motions = {} if old_root is None else _own_motions(old_root)
    for action in motions.values():
        action.use_fake_user = True  # through the removal, which drops what nothing uses
    # Where the artist filed the cell in this scene (under a collection of theirs): the new one goes there too.
    homes = [] if old_root is None else [c for c in (scene.collection, *scene.collection.children_recursive)
                                         if c != old_root and old_root.name in c.children]
    remove_cell(scene, name)
    names_before = set(bpy.data.objects.keys())
    cell = replace(cell, robot=cell.robot.with_tool(probe.mount))
    root = bpy.data.collections.new(name)
    for home in homes or [scene.collection]:
        home.children.link(root)
    robot_col = _child_collection(root, "Robot")
    probe_col = _child_collection(root, "Probe")
    table_col = _child_collection(root, "Table")

    arm = rig.build_robot(robot_col, cell.robot)
    probe_frame, cams, lasers = add_probe(probe_col, probe, laser, laser_power_w, housing_collection=robot_col)
    rig.parent_to_bone(probe_frame, arm, rig.bone_name(6), cell.robot.fk(np.zeros(6)))

    table = add_turntable(table_col, cell.table)
    wp = add_workpiece(table_col, workpiece, table, material, roughness) if workpiece is not None else None
    for fixture in fixtures:
        add_fixture(table_col, fixture, table)
    for obj in root.all_objects:
        mark(obj, built_role(obj.name, names_before))
    register_built(root)
    # (and how it looks: a Material or Laser changed after the build went unnoticed, and the
    # views rendered the old ones)
    root[BUILT_FROM_KEY] = json.dumps({**built_from(cell.robot, probe, workpiece, cell.table),
                                       "surface": surface_key(material, roughness), "laser": laser})
    bpy.context.view_layer.update()
    if kept or motions:
        roles = {role_of(o): o for o in own_objects(root)}
        for role, action in motions.items():
            action.use_fake_user = False
            if role in roles:
                roles[role].animation_data_create().action = action
        _put_back(kept, root)
        bpy.context.view_layer.update()
    return SceneCell(scene, cell, probe, workpiece, laser, root, robot_col, arm, probe_frame, cams, lasers,
                     table, wp)
