"""Clouds in the table frame, PLY round trips, analytic ground truth, error statistics, coverage."""

import math
import os

import numpy as np
import pytest
import trimesh

from addon.core import files
from addon.core.geometry.cloud import Cloud, CloudAccumulator, load_ply, save_ply
from addon.core.errors import InputError, ScannerError
from addon.core.geometry.metrics import coverage, distances, error_stats, evaluate
from addon.core.geometry.shapes import Cylinder, PlanePatch, Sphere
from addon.core.kinematics.transforms import rot_x, rot_z, trans
from addon.core.optics.triangulate import Profile


def profile(points, camera=1):
    n = len(points)
    return Profile(np.asarray(points, float), np.arange(n, dtype=float), np.full(n, camera, np.uint8),
                   np.full(n, 0.5), np.full(n, 0.01), {})


def test_accumulator_moves_profiles_into_the_table_frame():
    acc = CloudAccumulator()
    T0 = trans(10, 0, 0)
    T1 = rot_z(math.pi / 2) @ trans(0, 0, 5)
    acc.add(profile([[0, 0, 100.0], [0, 1, 100.0]]), T0, frame=0)
    acc.add(profile([[0, 0, 100.0]], camera=3), T1, frame=7)
    cloud = acc.cloud()
    np.testing.assert_allclose(cloud.points, [[10, 0, 100], [10, 1, 100], [0, 0, 105]], atol=1e-12)
    np.testing.assert_array_equal(cloud.frame, [0, 0, 7])
    np.testing.assert_array_equal(cloud.camera, [1, 1, 3])
    assert len(CloudAccumulator().cloud()) == 0


def test_ply_round_trip_keeps_attributes(tmp_path):
    rng = np.random.default_rng(0)
    cloud = Cloud(rng.uniform(-300, 300, (1000, 3)), rng.integers(0, 500, 1000), rng.integers(1, 4, 1000),
                  rng.uniform(0, 0.2, 1000))
    path = save_ply(cloud, tmp_path / "out" / "cloud.ply")
    assert path.read_bytes().startswith(b"ply\nformat binary_little_endian")
    back = load_ply(path)
    assert len(back) == 1000
    np.testing.assert_allclose(back.points, cloud.points, atol=1e-4)  # float32 in the file
    np.testing.assert_array_equal(back.frame, cloud.frame)
    np.testing.assert_array_equal(back.camera, cloud.camera)
    np.testing.assert_allclose(back.quality, cloud.quality, rtol=1e-7)
    assert not [p for p in path.parent.iterdir() if p.name != "cloud.ply"]  # no temporary left over


def test_an_empty_cloud_reads_back_empty(tmp_path):
    # (a scan that measured nothing writes one; trimesh reads it as an empty Scene, and
    # load_ply raised AttributeError)
    back = load_ply(save_ply(Cloud.empty(), tmp_path / "cloud.ply"))
    assert len(back) == 0 and back.points.shape == (0, 3)


def test_failed_write_leaves_no_file(tmp_path, monkeypatch):
    target = tmp_path / "cloud.ply"

    def boom(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(files.os, "replace", boom)
    with pytest.raises(OSError):
        save_ply(Cloud(np.zeros((3, 3)), [0, 0, 0], [1, 1, 1], [0, 0, 0]), target)
    assert list(tmp_path.iterdir()) == []


def test_loading_bad_files(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_ply(tmp_path / "missing.ply")
    junk = tmp_path / "junk.ply"
    junk.write_bytes(b"this is not a ply file at all")
    with pytest.raises(ScannerError, match="junk.ply"):
        load_ply(junk)


def test_analytic_distances_are_exact():
    sphere = Sphere(trans(10, 0, 30), radius_mm=25)
    assert sphere.signed_distance([[10, 0, 30 + 27.0], [10, 20, 30]]).tolist() == pytest.approx([2.0, -5.0])
    plane = PlanePatch(trans(0, 0, 5) @ rot_x(math.pi / 2), width_mm=40, height_mm=20)
    # The patch lies in the world XZ plane at y = 0 (after the 90° tilt), spanning x ∈ ±20, z ∈ 5 ± 10.
    assert plane.signed_distance([[3, -2.5, 7]])[0] == pytest.approx(2.5)  # local +Z is world −Y
    assert plane.distance([[25, 0, 5]])[0] == pytest.approx(5.0)  # beyond the edge
    cyl = Cylinder(radius_mm=20, height_mm=60)
    d = cyl.signed_distance([[0, 0, 30], [25, 0, 30], [0, 0, 70], [25, 0, 70], [19, 0, 59.5]])
    np.testing.assert_allclose(d, [-20, 5, 10, math.hypot(5, 10), -0.5])


def test_error_statistics_of_known_offsets():
    rng = np.random.default_rng(1)
    dirs = rng.normal(size=(2000, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    offsets = np.where(np.arange(2000) % 2 == 0, 0.004, -0.002)  # ±µm-scale errors
    sphere = Sphere(radius_mm=30.0)
    stats = evaluate(dirs * (30.0 + offsets[:, None]), sphere)
    assert stats.n == 2000
    assert stats.rms_um == pytest.approx(math.sqrt((16 + 4) / 2), rel=1e-6)
    assert stats.mean_um == pytest.approx(3.0, rel=1e-6)
    assert stats.max_um == pytest.approx(4.0, rel=1e-6)
    assert stats.p95_um == pytest.approx(4.0, rel=1e-6)
    assert stats.bias_um == pytest.approx(1.0, rel=1e-6)
    assert error_stats([]).n == 0


def test_mesh_distances_agree_with_analytic_on_flat_faces():
    plane = PlanePatch(rot_z(0.3) @ trans(0, 0, 12), width_mm=50, height_mm=50)
    rng = np.random.default_rng(2)
    P = np.column_stack([rng.uniform(-20, 20, 300), rng.uniform(-20, 20, 300), rng.uniform(-1, 1, 300)])
    P = P @ rot_z(0.3)[:3, :3].T + [0, 0, 12]
    d_mesh, signed = distances(P, plane.mesh())
    assert signed is None
    np.testing.assert_allclose(d_mesh, plane.distance(P), atol=1e-9)


def test_coverage_of_half_a_plane():
    plane = PlanePatch(width_mm=100, height_mm=100)
    x, y = np.meshgrid(np.arange(-50, 0.01, 0.5), np.arange(-50, 50.01, 0.5))
    half = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    assert coverage(half, plane, tolerance_mm=1.0) == pytest.approx(0.5, abs=0.03)
    assert coverage(np.zeros((0, 3)), plane, tolerance_mm=1.0) == 0.0
    with pytest.raises(InputError, match="tolerance"):
        coverage(half, plane, tolerance_mm=0)


def test_bad_ground_truth():
    with pytest.raises(InputError, match="no faces"):
        distances(np.zeros((1, 3)), trimesh.Trimesh(np.zeros((3, 3)), np.zeros((0, 3), int)))
    with pytest.raises(InputError, match="radius"):
        Sphere(radius_mm=-1.0)
    with pytest.raises(InputError):
        Cylinder(radius_mm=float("nan"))


def test_written_files_get_the_usual_permissions(tmp_path):
    path = files.write_bytes_atomic(tmp_path / "x.bin", b"data")
    mask = os.umask(0)
    os.umask(mask)
    assert (path.stat().st_mode & 0o777) == (0o666 & ~mask)


def _box_distance(P, half):
    """Signed distance to an axis-aligned box centred at the origin, written out (positive outside)."""
    q = np.abs(P) - half
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
    inside = np.minimum(np.max(q, axis=1), 0.0)
    return outside + inside


def test_mesh_distances_are_exact_and_signed_on_a_closed_mesh():
    import trimesh

    from addon.core.geometry.metrics import mesh_distances

    half = np.array([20.0, 15.0, 10.0])
    box = trimesh.creation.box(extents=2 * half)
    rng = np.random.default_rng(4)
    P = rng.uniform(-35, 35, size=(3000, 3))
    d, s = mesh_distances(P, box)
    truth = _box_distance(P, half)
    np.testing.assert_allclose(s, truth, atol=1e-9)
    np.testing.assert_allclose(d, np.abs(truth), atol=1e-9)


def test_an_open_mesh_gives_unsigned_distances_and_the_fallback_agrees(monkeypatch):
    import sys

    import trimesh

    from addon.core.geometry.metrics import mesh_distances

    half = np.array([20.0, 15.0, 10.0])
    box = trimesh.creation.box(extents=2 * half)
    open_box = trimesh.Trimesh(box.vertices, box.faces[:-2])  # one face of the box missing
    P = np.random.default_rng(5).uniform(-35, 35, size=(400, 3))
    d, s = mesh_distances(P, open_box)
    assert s is None and np.all(d >= 0)
    monkeypatch.setitem(sys.modules, "igl", None)  # as in a Blender without a libigl wheel
    d_fallback, s_fallback = mesh_distances(P, box)
    np.testing.assert_allclose(d_fallback, np.abs(_box_distance(P, half)), atol=1e-9)
    assert s_fallback is None


def test_a_mesh_workpiece_reports_a_bias_not_nan():
    import trimesh

    from addon.core.geometry.metrics import distances, error_stats

    sphere = trimesh.creation.icosphere(subdivisions=4, radius=30.0)
    P = sphere.vertices * 1.001  # 30 µm outside the vertices (which lie on the mesh)
    d, s = distances(P, sphere)
    stats = error_stats(d, s)
    assert np.isfinite(stats.bias_um) and stats.bias_um > 0


def test_coverage_of_the_measurable_surface_counts_only_what_the_laser_reaches():
    import trimesh

    from addon.core.geometry.metrics import coverage_of_measurable

    square = trimesh.Trimesh([[-50, -50, 0], [50, -50, 0], [50, 50, 0], [-50, 50, 0]], [[0, 1, 2], [0, 2, 3]])
    g = np.arange(-50, 50.01, 0.25)
    X, Y = np.meshgrid(g, g)
    grid = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    reachable = grid[grid[:, 0] < 0]        # the laser reaches the left half
    cloud = grid[grid[:, 0] < -25]          # the scan covered the left quarter
    cov, share = coverage_of_measurable(cloud, square, reachable, tolerance_mm=1.0, samples=40000)
    # Within 1 mm of the left half: 51 mm of 100; of that, within 1 mm of the quarter: 26 of 51.
    assert share == pytest.approx(0.51, abs=0.01)
    assert cov == pytest.approx(26 / 51, abs=0.01)
    assert coverage_of_measurable(cloud, square, np.zeros((0, 3)), 1.0) == (0.0, 0.0)


def test_a_point_beside_a_sharp_edge_measures_its_own_face_not_the_one_beyond():
    import trimesh

    from addon.core.geometry.metrics import coverage, coverage_of_measurable

    box = trimesh.creation.box(extents=(40.0, 40.0, 40.0))  # top at z = 20
    g = np.arange(-19.9, 19.91, 0.25)
    X, Y = np.meshgrid(g, g)
    top = np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, 20.0)])  # the laser reaches the top to 0.1 mm from its rim
    cov, share = coverage_of_measurable(top, box, top, tolerance_mm=1.0, samples=60000)
    # Only the top is measurable: 1/6 of the box, not the 1 mm bands of the four sides under its rim (+10 %).
    assert share == pytest.approx(1 / 6, abs=0.006)
    assert cov == pytest.approx(1.0, abs=1e-9)
    # The same points cover the top and nothing of the sides.
    assert coverage(top, box, tolerance_mm=1.0, samples=60000) == pytest.approx(1 / 6, abs=0.006)
    # A point on a side face, 0.5 mm under the rim, covers that side's band and not the top.
    side = np.column_stack([g, np.full(g.size, 20.0), np.full(g.size, 19.5)])
    assert coverage(side, box, tolerance_mm=1.0, samples=60000) == pytest.approx(1.5 / 240, abs=0.002)


def test_the_reports_outliers_and_share_within_twice_sigma_come_from_each_points_distance():
    """Points on a sphere on the table at known radial offsets with known stated σ: the report
    counts those beyond 0.2 mm and the share within 2σ as the offsets say."""
    from dataclasses import replace

    from addon.core.config.scan import load_scan_config
    from addon.core.scan.outputs import measure_against_truth

    config = load_scan_config("demo")  # a 30 mm sphere on the table
    rng = np.random.default_rng(2)
    dirs = rng.normal(size=(1000, 3))
    dirs[:, 2] = np.abs(dirs[:, 2]) + 0.2  # the upper half, off the table
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    centre = np.array([0.0, 0.0, 30.0])
    offsets = np.full(1000, 0.010)  # 10 µm off ...
    offsets[:7] = 0.25  # ... but 7 points 0.25 mm off
    sigma = np.where(np.arange(1000) < 100, 0.004, 0.006)  # 2σ = 8 µm for 100 points: they miss it
    cloud = Cloud(centre + dirs * (30.0 + offsets[:, None]), np.zeros(1000), np.ones(1000), sigma)
    entries = measure_against_truth(cloud, replace(config, fixtures=()))[0]
    assert entries["points_on_part"] == 1000
    assert entries["outliers"] == 7
    assert entries["within_2_sigma"] == pytest.approx(0.9, abs=1e-9)  # 900 points with 2σ = 12 ≥ 10 µm
