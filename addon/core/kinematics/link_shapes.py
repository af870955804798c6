"""The shapes of a robot's links when it has no meshes: cylinders along each DH link.

Link k (1..6) turns with joint k and is drawn as two cylinders, one along the
joint axis z_{k−1} for the offset d_k and one from there to the origin of frame k
along a_k, plus a thicker cylinder around joint k's axis (the joint housing). The
Blender rig draws exactly these, and the collision model uses them; radii scale
with the robot's largest DH length so a small arm gets slim links.

Everything is returned in the link's own DH frame k, which is rigid with the link.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .robot import N_JOINTS, Robot
from .transforms import rigid_inverse

LINK_RADIUS_SHARE = 0.05   # of the robot's largest DH length
JOINT_RADIUS_SHARE = 0.07
JOINT_LENGTH_FACTOR = 2.4  # the housing's length, in joint radii


@dataclass(frozen=True)
class Cylinder:
    """From p0 to p1 (mm, in the link's frame), of radius ``radius_mm``; ``kind`` "link" or "joint"."""

    p0: np.ndarray
    p1: np.ndarray
    radius_mm: float
    kind: str = "link"

    @property
    def length_mm(self) -> float:
        return float(np.linalg.norm(self.p1 - self.p0))


def link_radii_mm(robot: Robot) -> tuple[float, float]:
    """(link radius, joint-housing radius) in mm."""
    size = max(float(np.max(np.abs(np.r_[robot.a_mm, robot.d_mm]))), 1e-3)
    return LINK_RADIUS_SHARE * size, JOINT_RADIUS_SHARE * size


def link_cylinders(robot: Robot) -> list[list[Cylinder]]:
    """Per link k = 1..6 (index k − 1): its cylinders in DH frame k. Zero-length pieces are left out."""
    frames0 = robot.link_frames(np.zeros(N_JOINTS))
    r_link, r_joint = link_radii_mm(robot)
    out = []
    for k in range(N_JOINTS):
        o_prev, z_prev = frames0[k][:3, 3], frames0[k][:3, 2]
        elbow = o_prev + robot.d_mm[k] * z_prev
        to_link = rigid_inverse(frames0[k + 1])

        def local(p):
            return to_link[:3, :3] @ p + to_link[:3, 3]

        shapes = []
        for a, b in ((o_prev, elbow), (elbow, frames0[k + 1][:3, 3])):
            if np.linalg.norm(b - a) >= 1e-6:
                shapes.append(Cylinder(local(a), local(b), r_link))
        half = 0.5 * JOINT_LENGTH_FACTOR * r_joint
        shapes.append(Cylinder(local(o_prev - half * z_prev), local(o_prev + half * z_prev), r_joint, "joint"))
        out.append(shapes)
    return out


def link_mesh(robot: Robot, k: int, collision: bool = False):
    """Link k + 1's mesh (k = 0..5) in its DH frame, from the rig's files or a URDF's geometry
    (``collision``: the collision geometry where the rig has its own, else the visual one);
    None where the rig has none (then the link is drawn and checked as cylinders)."""
    entries = (robot.collision_meshes or robot.link_meshes) if collision else robot.link_meshes
    if not entries:
        return None
    return _load(*entries[k])


def base_mesh(robot: Robot, collision: bool = False):
    """The robot's fixed base (a pedestal) in DH frame 0 (``collision``: its collision geometry
    where the rig has its own, else the visual one); None where it has none."""
    entry = (robot.base_collision_mesh or robot.base_mesh) if collision else robot.base_mesh
    return _load(*entry) if entry else None


def _load(source, offset):
    import trimesh

    if isinstance(source, trimesh.Trimesh):
        mesh = source.copy()
    elif source:
        mesh = trimesh.load(source, force="mesh")
    else:
        return None
    mesh.apply_transform(offset)
    return mesh
