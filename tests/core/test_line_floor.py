"""The line-width floor: what a perfect detector of this probe measures, from geometry alone."""

import numpy as np
import trimesh

from addon.core.config.rigs import load_probe
from addon.core.geometry.footprint import SurfaceCaster
from addon.core.geometry.line_floor import line_width_floor
from addon.core.kinematics.path import DOWN, probe_orientation
from addon.core.kinematics.transforms import make_pose


def _down_at(height):
    """The probe straight above the origin, ``height`` mm up, its laser plane x = 0."""
    return make_pose(probe_orientation(DOWN, (0.0, 1.0, 0.0)), [0.0, 0.0, height])[None]


def _floor(mesh, height, ys, z, camera=3):
    probe = load_probe("default")
    pts = np.column_stack([np.zeros(len(ys)), ys, np.full(len(ys), z)])
    return line_width_floor(probe, _down_at(height), pts, np.zeros(len(ys), int), np.full(len(ys), camera),
                            SurfaceCaster([mesh]))


def test_a_flat_face_square_to_the_beam_is_measured_where_it_is():
    plate = trimesh.creation.box(extents=[80.0, 80.0, 10.0])  # top at z = 5
    ys = np.linspace(-20.0, 20.0, 9)
    for camera in (1, 2, 3):
        F = _floor(plate, 165.0, ys, 5.0, camera)
        assert np.isfinite(F).all()
        # On the face: the strip is symmetric about the laser plane up to perspective.
        assert np.max(np.abs(F[:, 2] - 5.0)) < 0.004, F[:, 2] - 5.0
        assert np.max(np.abs(F[:, 1] - ys)) < 0.01


def test_an_open_sheet_seen_from_behind_has_the_floor_of_its_front():
    """An open mesh is lit and seen from whichever side the laser meets, as Cycles and the
    ray caster shade it: a sheet wound to face down, scanned from above, has the same floor as
    one facing up (it had none: no light reached its back)."""
    up = trimesh.Trimesh([[-40, -40, 5], [40, -40, 5], [40, 40, 5], [-40, 40, 5]], [[0, 1, 2], [0, 2, 3]])
    down = trimesh.Trimesh(up.vertices, up.faces[:, ::-1])
    assert up.face_normals[0, 2] > 0 > down.face_normals[0, 2]
    ys = np.linspace(-20.0, 20.0, 9)
    for camera in (1, 2, 3):
        front, back = _floor(up, 165.0, ys, 5.0, camera), _floor(down, 165.0, ys, 5.0, camera)
        assert np.isfinite(back).all(), back
        assert np.allclose(front, back, atol=1e-9)
        assert np.max(np.abs(back[:, 2] - 5.0)) < 0.004


def test_a_step_inside_the_strip_moves_or_rejects_the_point():
    # Two levels meet along x = 0.25 mm, a little under one beam σ beside the laser plane:
    # part of the strip falls 10 mm lower. Far from the step the face reads true.
    high = trimesh.creation.box(extents=[40.0, 80.0, 20.0])
    high.apply_translation([-20.0 + 0.25, 0.0, 0.0])   # top at z = 10, for x < 0.25
    low = trimesh.creation.box(extents=[40.0, 80.0, 0.1])
    low.apply_translation([20.0 + 0.25, 0.0, -0.05])   # top at z = 0, for x > 0.25
    step = trimesh.util.concatenate([high, low])
    ys = np.linspace(-10.0, 10.0, 5)
    F = _floor(step, 170.0, ys, 10.0, 1)
    off = np.where(np.isfinite(F[:, 2]), np.abs(F[:, 2] - 10.0), np.inf)
    assert np.all(off > 0.005), off  # biased by more than 5 µm, or rejected (no finite floor)
    far = trimesh.creation.box(extents=[40.0, 80.0, 20.0])
    far.apply_translation([-20.0 + 5.0, 0.0, 0.0])     # the same step 5 mm away
    F = _floor(far, 170.0, ys, 10.0, 1)
    assert np.max(np.abs(F[:, 2] - 10.0)) < 0.004


def test_coverage_ceiling_is_whole_on_a_plate_and_lower_across_ridges():
    """A sweep over a flat plate: every measurable spot gets a floor on the face (ceiling 1).
    Over a row of sharp ridges along the line (a saw-tooth across it, crests every 2 mm), the
    strip bends across the line where it straddles a crest or a trough: the lines there are
    off by more than 50 µm, those on the flat flanks are not, so the ceiling lies between
    0 and 1, and rises as the allowed error does."""
    from shapely.geometry import Polygon

    from addon.core.geometry.line_floor import coverage_ceiling

    probe = load_probe("default")
    poses = np.concatenate([make_pose(probe_orientation(DOWN, (0.0, 1.0, 0.0)), [x, 0.0, 165.0])[None]
                            for x in np.arange(-10.0, 10.0, 0.25)])
    plate = trimesh.creation.box(extents=[60.0, 60.0, 10.0])
    assert coverage_ceiling(probe, poses, SurfaceCaster([plate]), plate, 65.0, 0.05, 1.0) > 0.99
    # Ridges along y, the line's direction: z = 5 + 0.6·(saw-tooth in x), 2 mm period.
    xs = np.arange(-30.0, 30.01, 1.0)
    zs = 5.0 + np.where(np.arange(len(xs)) % 2 == 0, 0.0, 0.6)
    profile = np.column_stack([xs, zs])
    ridges = trimesh.creation.extrude_polygon(Polygon(np.vstack([profile, [[30.0, -5.0], [-30.0, -5.0]]])), 60.0)
    ridges.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    ridges.apply_translation([0.0, 30.0, 0.0])
    # Coverage within 0.3 mm of a point (the lines are 0.25 mm apart): a crest's bad lines leave a gap.
    tight = coverage_ceiling(probe, poses, SurfaceCaster([ridges]), ridges, 65.0, 0.05, 0.3)
    loose = coverage_ceiling(probe, poses, SurfaceCaster([ridges]), ridges, 65.0, 0.5, 0.3)
    assert 0.1 < tight < 0.9 and loose > tight + 0.05, (tight, loose)


def test_a_line_wide_on_the_sensor_still_has_a_floor():
    """The 1280-row probe with a 2.4 mm line images the strip so wide that the 41 rays lay more
    than a pixel apart on the sensor: no pixel lay between two of them, and every floor was NaN
    (a bench printed '+nan' and carried on). Those points are cast again, denser: on a flat
    plate the floor lies on the plate (perspective moves it a micrometre or so)."""
    from dataclasses import replace

    plate = trimesh.creation.box(extents=[200.0, 200.0, 10.0])  # its top at z = 5
    surfaces = SurfaceCaster([plate])
    ys = np.linspace(-20.0, 20.0, 5)
    points = np.column_stack([np.zeros(5), ys, np.full(5, 5.0)])
    for width in (2.4, 4.8):
        probe = replace(load_probe("hires"), line_width_mm=width)
        for height in (165.0, 250.0):
            pose = make_pose(probe_orientation(DOWN, (0.0, 1.0, 0.0)), [0.0, 0.0, height])[None]
            floor = line_width_floor(probe, pose, points, np.zeros(5, int), np.full(5, 1), surfaces)
            assert np.isfinite(floor).all(), (width, height)
            assert np.abs(floor[:, 2] - 5.0).max() < 0.002, (width, height, floor[:, 2])
