"""The robot as an armature rig built from its DH table.

One bone per joint. Bone k rests at DH frame k−1 (at q = 0) turned by R_X(+90°),
so the bone's local Y axis is the joint axis z_{k−1}; each bone is parented to the
previous one. A joint is a pose rotation about the bone's local Y only (X and Z
locked; rotation order YXZ keeps Y out of the middle of the Euler order, where it
would fold at ±90°), clamped by a Limit Rotation constraint with the rig's limits.

Joint angles are custom properties ``q1`` … ``q6`` (radians, shown in degrees) on
the armature object; a driver copies each into its bone's Y rotation, so setting
or keyframing the properties poses the rig. DH frame k is recovered from a posed
bone as ``bone.matrix · R_X(90°)⁻¹ · A_k(0)`` (see :func:`dh_frames`).

Link geometry: procedural cylinders along each link's d and a offsets, or the
rig's per-link meshes, each parented to its bone.
"""

from __future__ import annotations

import math

import bpy
import numpy as np
import trimesh

from ..core.kinematics.link_shapes import base_mesh, link_cylinders, link_mesh
from ..core.kinematics.robot import N_JOINTS, Robot
from ..core.kinematics.transforms import rigid_inverse, rot_x
from ..core.geometry.workpiece import check_mesh
from .materials import diffuse
from .meshes import mesh_object
from .units import M_PER_MM, from_blender, to_blender

BONE_TO_DH = rot_x(-math.pi / 2)  # R_X(90°)⁻¹: bone frame -> DH frame k−1 (rotation part)


def joint_property(k: int) -> str:
    """Name of the custom property holding joint k's angle (k = 1..6)."""
    return f"q{k}"


def bone_name(k: int) -> str:
    return f"J{k}"


def build_robot(collection: bpy.types.Collection, robot: Robot, name: str = "Robot") -> bpy.types.Object:
    """Armature object with bones, constraints, joint properties, drivers and link geometry."""
    arm = bpy.data.armatures.new(f"{name}Armature")
    arm.display_type = "STICK"
    obj = bpy.data.objects.new(name, arm)
    collection.objects.link(obj)
    obj.matrix_world = to_blender(robot.base)
    obj["robot_name"] = robot.name

    frames0 = robot.link_frames(np.zeros(N_JOINTS))
    base_inv = rigid_inverse(robot.base)
    size = bone_length_mm(robot)
    view_layer = bpy.context.view_layer
    previous_active = view_layer.objects.active
    view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode="EDIT")
    parent = None
    for k in range(N_JOINTS):
        eb = arm.edit_bones.new(bone_name(k + 1))
        eb.head = (0.0, 0.0, 0.0)
        eb.tail = (0.0, size * M_PER_MM, 0.0)
        eb.matrix = to_blender(base_inv @ frames0[k] @ rot_x(math.pi / 2))
        if parent is not None:
            eb.parent = parent
            eb.use_connect = False
        parent = eb
    bpy.ops.object.mode_set(mode="OBJECT")
    view_layer.objects.active = previous_active

    for k in range(N_JOINTS):
        pb = obj.pose.bones[bone_name(k + 1)]
        pb.rotation_mode = "YXZ"
        slides = robot.prismatic[k]  # the bone moves along its y axis (DH z) instead of turning
        pb.lock_rotation = (True, slides, True)
        pb.lock_location = (True, not slides, True)
        pb.lock_scale = (True, True, True)
        lo, hi = float(robot.q_min_rad[k]), float(robot.q_max_rad[k])
        prop = joint_property(k + 1)
        obj[prop] = 0.0
        if slides:
            limit = pb.constraints.new("LIMIT_LOCATION")
            limit.owner_space = "LOCAL"
            limit.use_min_y, limit.use_max_y = True, True
            limit.min_y, limit.max_y = lo * M_PER_MM, hi * M_PER_MM
            obj.id_properties_ui(prop).update(min=lo, max=hi, description=f"Joint {k + 1} travel (DH q{k + 1}, mm)")
            driver = pb.driver_add("location", 1).driver
            driver.type = "SCRIPTED"  # mm to metres by Blender's own expression evaluator (no script runs)
            driver.expression = f"q * {M_PER_MM!r}"
        else:
            limit = pb.constraints.new("LIMIT_ROTATION")
            limit.owner_space = "LOCAL"
            limit.euler_order = "YXZ"
            limit.use_limit_y = True
            limit.min_y, limit.max_y = lo, hi
            obj.id_properties_ui(prop).update(subtype="ANGLE", min=lo, max=hi,
                                              description=f"Joint {k + 1} angle (DH q{k + 1}, offset excluded)")
            driver = pb.driver_add("rotation_euler", 1).driver
            driver.type = "AVERAGE"  # the value of its one variable: no Python expression needed
        var = driver.variables.new()
        var.name = "q"
        var.type = "SINGLE_PROP"
        var.targets[0].id = obj
        var.targets[0].data_path = f'["{prop}"]'
    bpy.context.view_layer.update()
    _add_link_geometry(collection, obj, robot, frames0)
    return obj


def bone_length_mm(robot: Robot) -> float:
    return 0.12 * max(float(np.max(np.abs(np.r_[robot.a_mm, robot.d_mm]))), 1e-3)


def set_joints(obj: bpy.types.Object, q) -> None:
    """Pose the rig: joint values q (6,), rad (mm for a sliding joint). Updates the view layer."""
    q = np.asarray(q, dtype=np.float64)
    for k in range(N_JOINTS):
        obj[joint_property(k + 1)] = float(q[k])
    obj.update_tag()
    bpy.context.view_layer.update()


def get_joints(obj: bpy.types.Object) -> np.ndarray:
    """The rig's joint values q (6,); InputError where a joint's property was deleted or set to
    something that is not a number (one click in Object Properties > Custom Properties: Go
    and Scan gave KeyError tracebacks)."""
    out = []
    for k in range(N_JOINTS):
        name = joint_property(k + 1)
        value = obj.get(name)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            from ..core.errors import InputError

            raise InputError(f"the robot {obj.name!r} has no joint value {name} (its custom property is "
                             f"{'missing' if value is None else repr(value)}): press Build Cell again")
        out.append(float(value))
    return np.array(out, dtype=np.float64)


def dh_frames(obj: bpy.types.Object, robot: Robot) -> np.ndarray:
    """(7, 4, 4) mm: DH frames 0..6 in the world as Blender evaluates the posed rig."""
    A0 = robot.link_transforms(np.zeros(N_JOINTS))
    world = from_blender(obj.matrix_world)
    out = [world]
    for k in range(N_JOINTS):
        pb = obj.pose.bones[bone_name(k + 1)]
        out.append(world @ from_blender(pb.matrix) @ BONE_TO_DH @ A0[k])
    return np.array(out)


def parent_to_bone(child: bpy.types.Object, armature: bpy.types.Object, bone: str, world_mm: np.ndarray) -> None:
    """Parent ``child`` to a bone, keeping its world pose ``world_mm`` at the current pose."""
    child.parent = armature
    child.parent_type = "BONE"
    child.parent_bone = bone
    bpy.context.view_layer.update()
    child.matrix_world = to_blender(world_mm)


def _segment(p0, p1, radius) -> trimesh.Trimesh | None:
    if np.linalg.norm(np.subtract(p1, p0)) < 1e-6:
        return None
    return trimesh.creation.cylinder(radius=radius, segment=np.array([p0, p1]), sections=24)


def _add_link_geometry(collection, obj, robot: Robot, frames0: np.ndarray) -> None:
    """Procedural links (or the rig's meshes), parented to their bones at q = 0: the cylinders
    of :func:`link_cylinders`, which the collision model uses too."""
    shapes = link_cylinders(robot)
    paint = diffuse("Robot paint", (0.85, 0.45, 0.1))
    joints = diffuse("Robot joints", (0.2, 0.2, 0.22))
    pedestal = base_mesh(robot)
    if pedestal is not None:
        pedestal = check_mesh(pedestal, f"the base of {robot.name}")
        pedestal.apply_transform(frames0[0])
        part = mesh_object("Base", pedestal, collection, joints)
        part.parent = obj
        part.matrix_parent_inverse = obj.matrix_world.inverted()
    for k in range(N_JOINTS):
        bone = bone_name(k + 1)
        mesh = link_mesh(robot, k)
        if mesh is not None:
            mesh = check_mesh(mesh, f"link {k + 1} of {robot.name}")
            mesh.apply_transform(frames0[k + 1])
            part = mesh_object(f"Link{k + 1}", mesh, collection, paint)
            parent_to_bone(part, obj, bone, np.eye(4))
            continue
        F = frames0[k + 1]

        def world(p):
            return F[:3, :3] @ p + F[:3, 3]

        pieces = [_segment(world(c.p0), world(c.p1), c.radius_mm) for c in shapes[k] if c.kind == "link"]
        if pieces:
            part = mesh_object(f"Link{k + 1}", trimesh.util.concatenate(pieces), collection, paint)
            parent_to_bone(part, obj, bone, np.eye(4))
        for c in shapes[k]:
            if c.kind == "joint":
                part = mesh_object(f"Joint{k + 1}", _segment(world(c.p0), world(c.p1), c.radius_mm), collection, joints)
                parent_to_bone(part, obj, bone, np.eye(4))
