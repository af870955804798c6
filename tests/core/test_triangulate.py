"""Triangulation: exact round trips, the paper's formula and its predicted error, masking, fusion."""

import math

import numpy as np
import pytest

from addon.core.optics.detect import LineCode, LineDetection
from addon.core.errors import InputError
from addon.core.optics.probe import Probe
from addon.core.config.rigs import load_probe
from addon.core.optics.triangulate import fuse_profiles, triangulate, triangulate_profile


def detection(probe, u, v, code=None):
    """A LineDetection at given (possibly fractional) pixel positions."""
    u = np.asarray(u, float)
    code = np.zeros(len(u), np.uint8) if code is None else code
    return LineDetection(u, np.asarray(v, float), np.ones(len(u)), np.ones(len(u)), code, "given",
                         (probe.rows_px, probe.cols_px))


def laser_plane_curve(kind, n=400):
    """Points on the laser plane (X = 0) that lie on a known surface."""
    y = np.linspace(-60, 60, n)
    if kind == "plane":  # z = 140 + 0.3 y (a plane tilted about X)
        return np.column_stack([np.zeros(n), y, 140 + 0.3 * y])
    if kind == "far plane":
        return np.column_stack([np.zeros(n), y, np.full(n, 230.0)])
    # Sphere of radius 40 centred at (5, 3, 180): its cut by X = 0 is a circle.
    r = math.sqrt(40 ** 2 - 5 ** 2)
    t = np.linspace(-math.pi, 0, n)
    return np.column_stack([np.zeros(n), 3 + r * np.cos(t), 180 + r * np.sin(t)])


@pytest.mark.parametrize("name", ["default", "hires"])
@pytest.mark.parametrize("kind", ["plane", "far plane", "sphere"])
def test_project_then_triangulate_reproduces_points(name, kind):
    probe = load_probe(name)
    P = laser_plane_curve(kind)
    for camera in (0, 1):
        uv = probe.project(P, camera)
        seen = np.isfinite(uv).all(axis=1)
        assert seen.sum() > 50
        prof = triangulate_profile(probe, detection(probe, uv[seen, 0], uv[seen, 1]), camera)
        assert len(prof) == seen.sum()
        np.testing.assert_allclose(prof.points, P[seen], atol=1e-9)
        np.testing.assert_array_equal(triangulate(probe, detection(probe, uv[seen, 0], uv[seen, 1]), camera),
                                      prof.points)


def test_paper_and_exact_agree_on_the_centre_row_and_differ_by_the_predicted_factor():
    probe = load_probe("default")
    cx, cy = probe.principal_point
    u = np.linspace(0, probe.cols_px - 1, 50)
    for camera in (0, 1):
        for v in (cy, 0.0, 40.0, 120.0, probe.rows_px - 1.0):
            line = detection(probe, u, np.full(len(u), v))
            exact = triangulate_profile(probe, line, camera, "exact").points
            paper = triangulate_profile(probe, line, camera, "paper").points
            np.testing.assert_allclose(paper[:, 2], exact[:, 2], rtol=1e-12)  # P_Z is exact in Eq. 6
            factor = math.sqrt(1 + ((cy - v) / probe.f_px) ** 2)
            np.testing.assert_allclose(paper[:, 1], exact[:, 1] * factor, rtol=1e-12, atol=1e-12)
            if v == cy:
                np.testing.assert_allclose(paper, exact, atol=1e-12)
    # At the top and bottom rows the paper's P_Y is 1/cos γ too long (to within the half pixel).
    top = math.sqrt(1 + (cy / probe.f_px) ** 2)
    assert top == pytest.approx(1 / math.cos(probe.gamma_rad), rel=0.01)


def test_sensitivity_and_angle_match_the_analytic_derivative():
    probe = load_probe("default")
    cx, cy = probe.principal_point
    v = np.linspace(0, probe.rows_px - 1, 30)
    prof = triangulate_profile(probe, detection(probe, np.full(30, cx), v), 0)
    py = cy - v
    psi = probe.phi_rad - np.arctan(py / probe.f_px)
    # On the centre column P_Y = 0, so only Z moves: dZ/dp_y = a·f / (sin²ψ·(f² + p_y²)).
    dz = probe.a_mm * probe.f_px / (np.sin(psi) ** 2 * (probe.f_px ** 2 + py ** 2))
    np.testing.assert_allclose(prof.sigma_mm, 0.1 * dz, rtol=1e-4)
    np.testing.assert_allclose(prof.angle_rad, psi, rtol=1e-12)


def test_grazing_rays_are_masked_never_huge():
    # φ − γ = 0.5°: the sensor's far rows meet the laser plane almost edge-on.
    probe = Probe("grazing", 60.0, 0.0, math.radians(10.5), math.radians(10.0), 200, 50)
    v = np.linspace(-0.5, 199.5, 400)
    for method in ("exact", "paper"):
        prof = triangulate_profile(probe, detection(probe, np.full(400, 24.5), v), 0, method)
        assert prof.masked["grazing"] > 0
        assert np.isfinite(prof.points).all()
        assert np.all(np.degrees(prof.angle_rad) >= 2.0)
        assert prof.points[:, 2].max() < 60.0 / math.tan(math.radians(2.0)) * 1.001
        assert len(prof) + prof.masked["grazing"] == 400


def test_out_of_range_and_undetected_columns_are_masked_and_counted():
    probe = load_probe("default")
    code = np.array([0, 0, 0, LineCode.NO_LINE, LineCode.AMBIGUOUS], np.uint8)
    line = detection(probe, [10, 20, 30, 40, 50], [-0.7, 80.0, 159.8, 80.0, 80.0], code)
    for method in ("exact", "paper"):
        prof = triangulate_profile(probe, line, 0, method)
        assert len(prof) == 1
        assert prof.masked == {"no_detection": 2, "grazing": 0, "out_of_range": 2}


def test_inputs_are_checked():
    probe = load_probe("default")
    line = detection(probe, [1.0], [2.0])
    with pytest.raises(InputError, match="camera"):
        triangulate(probe, line, camera=2)
    with pytest.raises(InputError, match="not one of"):
        triangulate(probe, line, method="magic")
    other = LineDetection(np.zeros(1), np.zeros(1), np.ones(1), np.ones(1), np.zeros(1, np.uint8), "x", (10, 10))
    with pytest.raises(InputError, match="sensor"):
        triangulate(probe, other)


def both_cameras(probe, P):
    profs = []
    for camera in (0, 1):
        uv = probe.project(P, camera)
        seen = np.isfinite(uv).all(axis=1)
        profs.append(triangulate_profile(probe, detection(probe, uv[seen, 0], uv[seen, 1]), camera))
    return profs


def test_fusion_combines_where_both_see_and_fills_in_where_one_is_occluded():
    probe = load_probe("default")
    P = laser_plane_curve("plane", 300)
    p0, p1 = both_cameras(probe, P)
    fused = fuse_profiles(p0, p1)
    z_true = 140 + 0.3 * fused.points[:, 1]
    np.testing.assert_allclose(fused.points[:, 2], z_true, atol=1e-9)
    assert np.mean(fused.camera == 3) > 0.9
    # Fused points are more certain than either camera alone.
    assert np.median(fused.sigma_mm[fused.camera == 3]) < min(np.median(p0.sigma_mm), np.median(p1.sigma_mm))
    # Occlude camera 0 for Y in [−10, 10]: camera 1 fills the gap.
    hole = (p0.points[:, 1] > -10) & (p0.points[:, 1] < 10)
    fused = fuse_profiles(p0.take(~hole), p1)
    in_gap = (fused.points[:, 1] > -9) & (fused.points[:, 1] < 9)
    assert in_gap.sum() > 10 and np.all(fused.camera[in_gap] == 2)
    np.testing.assert_allclose(fused.points[:, 2], 140 + 0.3 * fused.points[:, 1], atol=1e-9)


def test_fusion_drops_both_cameras_where_they_disagree():
    probe = load_probe("default")
    p0, p1 = both_cameras(probe, laser_plane_curve("plane", 300))
    bad = (p1.points[:, 1] > 0) & (p1.points[:, 1] < 15)
    p1.points[bad, 2] += 3.0  # camera 1 sees a reflection there
    fused = fuse_profiles(p0, p1)
    assert fused.masked["camera_conflict"] >= bad.sum()
    # Nothing off the plane survives, neither camera's point is kept in the conflict, and
    # the rest is fused.
    np.testing.assert_allclose(fused.points[:, 2], 140 + 0.3 * fused.points[:, 1], atol=1e-6)
    inside = (fused.points[:, 1] > 1) & (fused.points[:, 1] < 14)
    assert not inside.any()
    assert np.mean(fused.camera == 3) > 0.8


def test_fusion_with_an_empty_side():
    probe = load_probe("default")
    p0, p1 = both_cameras(probe, laser_plane_curve("plane", 100))
    empty = p1.take(np.zeros(len(p1), bool))
    out = fuse_profiles(p0, empty)
    assert len(out) == len(p0) and np.all(out.camera == 1)


@pytest.mark.parametrize("fuse", [True, False])
def test_a_frame_counts_both_cameras_dropped_columns_fused_or_not(fuse):
    """With fusion off both cameras' points stand side by side; the columns either camera
    dropped are counted all the same (camera 1's were lost unfused)."""
    from dataclasses import replace

    from addon.core.config.scan import load_scan_config
    from addon.core.scan.frames import frame_profile

    from addon.core.optics.profile_filter import ProfileFilter

    # (The filter off: these sparse columns, 5 px apart, would read as a steep surface.)
    config = replace(load_scan_config("demo"), fuse=fuse, profile_filter=ProfileFilter())
    probe = config.probe
    P = laser_plane_curve("plane", 60)
    lines, seen = [], []
    for camera, missing in ((0, 3), (1, 5)):
        uv = probe.project(P, camera)
        uv = uv[np.isfinite(uv).all(axis=1)]
        seen.append(len(uv))
        code = np.zeros(len(uv), np.uint8)
        code[:missing] = LineCode.NO_LINE
        lines.append(detection(probe, uv[:, 0], uv[:, 1], code))
    prof = frame_profile(probe, lines, config)
    assert prof.masked["no_detection"] == 3 + 5
    if not fuse:
        assert np.sum(prof.camera == 1) == seen[0] - 3 and np.sum(prof.camera == 2) == seen[1] - 5
    np.testing.assert_allclose(prof.points[:, 2], 140 + 0.3 * prof.points[:, 1], atol=1e-6)
