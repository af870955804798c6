"""The bundled robots' optional link meshes follow their DH frames, and a rig whose optional
meshes are not installed falls back to procedural links.

Ground truth: the DH table's joint axes. Joint k's axis (DH frame k − 1's z) and joint
k + 1's (frame k's z) must both run through link k's mesh, at any joint vector: a mesh
placed in the wrong frame, turned or shifted, misses one of them by tens of mm.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

igl = pytest.importorskip("igl", reason="installed by the README's set-up")

from addon.core.config.rigs import load_robot
from headless.robot_meshes import MESH_SETS, install

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("mesh_set", MESH_SETS, ids=[m.rig for m in MESH_SETS])
def test_each_link_mesh_holds_its_joint_axes(mesh_set, tmp_path):
    base, *paths = install(mesh_set, tmp_path)
    robot = load_robot(mesh_set.rig)
    pedestal = trimesh.load(base, force="mesh")  # the fixed base holds joint 1's axis
    pedestal.apply_transform(robot.base)
    points = robot.base[:3, 3] + np.linspace(-1000.0, 1000.0, 2001)[:, None] * robot.base[:3, 2]
    assert igl.signed_distance(points, pedestal.vertices, pedestal.faces.astype(np.int64))[0].min() < 3.0
    along = np.linspace(-1000.0, 1000.0, 2001)  # mm along each axis, 1 mm apart
    for q in [np.zeros(6), *robot.random_q(3, np.random.default_rng(7))]:
        frames = robot.link_frames(q)
        for k, path in enumerate(paths, start=1):
            mesh = trimesh.load(path, force="mesh")
            mesh.apply_transform(frames[k])
            for axis_frame in (k - 1, k):
                F = frames[axis_frame]
                points = F[:3, 3] + along[:, None] * F[:3, 2]
                outside = igl.signed_distance(points, mesh.vertices, mesh.faces.astype(np.int64))[0]
                assert outside.min() < 3.0, (mesh_set.rig, k, axis_frame, outside.min())  # < 0: inside


def test_optional_meshes_not_installed_give_procedural_links(tmp_path):
    text = (REPO / "rigs" / "robots" / "puma560.toml").read_text()
    rig = tmp_path / "puma.toml"
    rig.write_text(text.replace("../../.cache/robot-meshes/puma560/", str(tmp_path / "nowhere") + "/"))
    assert load_robot(rig).link_meshes == ()
    rig.write_text(text.replace("../../.cache/robot-meshes/puma560/", str(tmp_path / "nowhere") + "/")
                   .replace("meshes_optional = true", "meshes_optional = false"))
    with pytest.raises(Exception, match="no such file"):
        load_robot(rig)
