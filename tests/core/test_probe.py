"""Probe geometry: Eq. 7 against brute force, camera placement, projection, validation."""

import math

import numpy as np
import pytest

from addon.core.errors import ConfigError, InputError
from addon.core.optics.probe import Probe, angles_from_range
from addon.core.config.rigs import load_probe


def ray_hits(probe: Probe, camera: int, px: np.ndarray, py: np.ndarray):
    """Laser-plane points of paper pixel coordinates, from the geometry of Fig. 3 written out here.

    Camera centre (±a, 0, b); optical axis at φ from +Z towards the plane; p_y runs
    towards the far end of the range, p_x along +Y for both cameras (camera 1's image
    columns run the other way, so there p_x = −(u − c_x)).
    """
    s = 1.0 if camera == 0 else -1.0
    c = np.array([s * probe.a_mm, 0.0, probe.b_mm])
    axis = np.array([-s * math.sin(probe.phi_rad), 0.0, math.cos(probe.phi_rad)])
    far = np.array([s * math.cos(probe.phi_rad), 0.0, math.sin(probe.phi_rad)])
    along = np.array([0.0, 1.0, 0.0])
    d = probe.f_px * axis + py[:, None] * far + px[:, None] * along
    t = -c[0] / d[:, 0]
    return c + t[:, None] * d


def test_default_probe_matches_the_paper_range():
    p = load_probe("default")
    assert math.degrees(p.phi_rad) == pytest.approx(27.05, abs=0.005)
    assert math.degrees(p.gamma_rad) == pytest.approx(13.55, abs=0.005)
    assert p.z_range_mm == pytest.approx((70.0, 250.0), abs=1e-9)
    assert (p.rows_px, p.cols_px) == (160, 160)
    hires = load_probe("hires")
    assert (hires.rows_px, hires.cols_px) == (1280, 1024)
    assert hires.phi_rad == p.phi_rad and hires.gamma_rad == p.gamma_rad and hires.a_mm == p.a_mm


def test_intrinsics_follow_the_pixel_convention():
    p = load_probe("default")
    f = 160 / (2 * math.tan(p.gamma_rad))
    np.testing.assert_allclose(p.K, [[f, 0, 79.5], [0, f, 79.5], [0, 0, 1]])
    h = load_probe("hires")
    assert h.principal_point == (511.5, 639.5)


@pytest.mark.parametrize("name", ["default", "hires"])
def test_eq7_matches_brute_force_over_the_sensor(name):
    p = load_probe(name)
    H, W = p.rows_px, p.cols_px
    # Every pixel centre plus the sensor's outer edges.
    rows = np.r_[-0.5, np.arange(H), H - 0.5]
    cols = np.r_[-0.5, np.arange(W), W - 0.5]
    u, v = np.meshgrid(cols, rows)
    px, py = (u - p.principal_point[0]).ravel(), (p.principal_point[1] - v).ravel()
    for camera in (0, 1):
        P = ray_hits(p, camera, px if camera == 0 else -px, py)
        assert P[:, 2].min() == pytest.approx(p.z_range_mm[0], rel=1e-12)
        assert P[:, 2].max() == pytest.approx(p.z_range_mm[1], rel=1e-12)
        near = np.isclose(v.ravel(), H - 0.5)
        far = np.isclose(v.ravel(), -0.5)
        L_min, L_max = p.line_lengths_mm()
        assert np.ptp(P[near, 1]) == pytest.approx(L_min, rel=1e-12)
        assert np.ptp(P[far, 1]) == pytest.approx(L_max, rel=1e-12)
    # Eq. 7's y values are those of Eq. 6's approximate P_Y (f instead of √(f² + p_y²)).
    psi_near, psi_far = p.phi_rad + p.gamma_rad, p.phi_rad - p.gamma_rad
    half_w = W / 2
    paper_near = 2 * p.a_mm * half_w / (p.f_px * math.sin(psi_near))
    paper_far = 2 * p.a_mm * half_w / (p.f_px * math.sin(psi_far))
    assert p.paper_line_lengths_mm() == pytest.approx((paper_near, paper_far), rel=1e-12)
    if W == H:  # exact lengths are shorter by cos γ
        ratio = np.array(p.line_lengths_mm()) / np.array(p.paper_line_lengths_mm())
        np.testing.assert_allclose(ratio, math.cos(p.gamma_rad), rtol=1e-12)


def test_cameras_placed_as_in_fig3():
    p = load_probe("default")
    for camera, side in ((0, 1.0), (1, -1.0)):
        T = p.cam2probe(camera)
        np.testing.assert_allclose(T[:3, 3], [side * 60.0, 0, 0])
        R = T[:3, :3]
        assert np.linalg.det(R) == pytest.approx(1.0)
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-15)
        axis = R[:, 2]
        assert math.degrees(math.acos(axis[2])) == pytest.approx(math.degrees(p.phi_rad))
        assert np.sign(axis[0]) == -side  # looking towards the laser plane
    # Mirror images of each other about the laser plane.
    M = np.diag([-1.0, 1.0, 1.0])
    np.testing.assert_allclose(M @ p.cam2probe(0)[:3, 2], p.cam2probe(1)[:3, 2], atol=1e-15)


def test_projection_of_known_points():
    p = load_probe("default")
    for camera in (0, 1):
        uv = p.project(np.array([[0, 0, 70.0], [0, 0, 250.0]]), camera)
        np.testing.assert_allclose(uv, [[79.5, 159.5], [79.5, -0.5]], atol=1e-9)
    # Along the line: +Y images to the right in camera 0, to the left in camera 1.
    assert p.project([0, 10, 150.0], 0)[0] > 79.5 > p.project([0, 10, 150.0], 1)[0]
    # Not visible: beyond the range, far off to the side, behind the camera.
    pts = np.array([[0, 0, 300.0], [0, 200, 150.0], [200, 0, -50.0]])
    assert np.isnan(p.project(pts, 0)).all()


def test_projection_agrees_with_ray_construction():
    p = load_probe("hires")
    rng = np.random.default_rng(5)
    px = rng.uniform(-500, 500, 200)
    py = rng.uniform(-600, 600, 200)
    for camera, sign in ((0, 1.0), (1, -1.0)):
        P = ray_hits(p, camera, px, py)
        uv = p.project(P, camera)
        np.testing.assert_allclose(uv[:, 0] - p.principal_point[0], sign * px, atol=1e-9)
        np.testing.assert_allclose(p.principal_point[1] - uv[:, 1], py, atol=1e-9)


def test_angles_from_range_inverts_eq7():
    phi, gamma = angles_from_range(60.0, 5.0, 80.0, 300.0)
    p = Probe("t", 60.0, 5.0, phi, gamma, 100, 100)
    assert p.z_range_mm == pytest.approx((80.0, 300.0))


@pytest.mark.parametrize(
    "kwargs,fragment",
    [
        (dict(phi_rad=math.radians(10), gamma_rad=math.radians(13)), "φ − γ"),
        (dict(phi_rad=math.radians(80), gamma_rad=math.radians(13)), r"φ \+ γ"),
        (dict(a_mm=0.0), "a > 0"),
        (dict(a_mm=-5.0), "a > 0"),
        (dict(rows_px=0), "rows_px"),
        (dict(rows_px=3), r"rows_px must be a whole number of pixels in \[4, "),  # Blender renders 4 at least
        (dict(cols_px=2.5), "cols_px"),
        (dict(gamma_rad=0.0), "half field of view"),
        (dict(line_width_mm=0.0), "line width"),
        (dict(fan_rad=math.radians(200)), "fan"),
        (dict(a_mm=float("nan")), "finite"),
        (dict(mount=np.diag([1.0, 1, 2, 1])), "mount"),
    ],
)
def test_invalid_probe_geometry_is_refused(kwargs, fragment):
    base = dict(name="t", a_mm=60.0, b_mm=0.0, phi_rad=math.radians(27), gamma_rad=math.radians(13),
                rows_px=160, cols_px=160)
    with pytest.raises(InputError, match=fragment):
        Probe(**{**base, **kwargs})


@pytest.mark.parametrize(
    "camera_table,fragment",
    [
        ("a_mm = 60\nrange_mm = [250, 70]\nrows_px = 160\ncols_px = 160", "z_max > z_min"),
        ("a_mm = 60\nphi_deg = 10\ngamma_deg = 13\nrows_px = 160\ncols_px = 160", "φ − γ"),
        ("a_mm = 60\nrange_mm = [70, 250]\nphi_deg = 27\nrows_px = 160\ncols_px = 160", "either range_mm"),
        ("a_mm = 60\nrange_mm = [70, 250]\nrows_px = 0\ncols_px = 160", "rows_px"),
        ("a_mm = -1\nrange_mm = [70, 250]\nrows_px = 16\ncols_px = 16", "camera.a_mm"),
        ("a_mm = 60\nrange_mm = [70, 250]\nrows_px = 16\ncols_px = 16\nfocus = 3", "unknown key camera.focus"),
    ],
)
def test_bad_probe_files(tmp_path, camera_table, fragment):
    path = tmp_path / "probe.toml"
    path.write_text(f'name = "p"\n[camera]\n{camera_table}\n')
    with pytest.raises(ConfigError, match=fragment) as info:
        load_probe(str(path))
    assert str(path) in str(info.value)


def test_a_line_narrower_than_a_pixel_is_warned_of_and_its_width_follows_the_optics():
    """The line's image width scales with the line's own width and with the sensor's rows over
    the same optics; under a pixel (FWHM) the scan says its σ does not hold. The default probe
    (1.04-1.43 px) and the 1280-row one are not warned of."""
    from dataclasses import replace

    from addon.core.config.scan import load_scan_config
    from addon.core.scan.plan import line_widths_px, narrow_line_warning

    probe = load_probe("default")
    base = np.array(line_widths_px(probe))
    assert 1.0 < base.min() < base.max() < 1.5 and narrow_line_warning(probe) is None
    assert narrow_line_warning(load_probe("hires")) is None
    thin = replace(probe, line_width_mm=0.6 * probe.line_width_mm)
    np.testing.assert_allclose(line_widths_px(thin), 0.6 * base, rtol=1e-9)
    said = narrow_line_warning(thin)
    assert said and f"{0.6 * base.min():.2f}-{0.6 * base.max():.2f} px wide" in said and "160-row" in said
    tall = load_scan_config("demo").with_overrides(resolution=(160, 320)).probe  # the same optics, twice the rows
    np.testing.assert_allclose(line_widths_px(tall), 2.0 * base, rtol=1e-6)


def test_a_line_wider_than_the_detector_takes_is_warned_of_before_it_is_refused():
    """Wider than max_width_px on a surface seen square on: warned (tilted surfaces still
    narrow it enough); over three times that: refused before anything renders."""
    from dataclasses import replace

    from addon.core.config.scan import load_scan_config
    from addon.core.scan.plan import WIDE_MARGIN, blind_settings, line_widths_px, wide_line_warning

    cfg = load_scan_config("demo")
    top = cfg.detect_params.max_width_px
    base = np.array(line_widths_px(cfg.probe))
    assert wide_line_warning(cfg) is None and blind_settings(cfg) is None
    k = 1.5 * top / base.min()  # the narrowest 1.5 times what the detector takes
    wide = replace(cfg, probe=replace(cfg.probe, line_width_mm=k * cfg.probe.line_width_mm))
    said = wide_line_warning(wide)
    assert said and f"max_width_px {top:g}" in said and blind_settings(wide) is None
    k = 1.01 * WIDE_MARGIN * top / base.min()
    wider = replace(cfg, probe=replace(cfg.probe, line_width_mm=k * cfg.probe.line_width_mm))
    assert "over 3 times what the detector takes" in blind_settings(wider)


def test_a_probe_rig_whose_whole_view_grazes_the_laser_plane_is_refused(tmp_path):
    """φ + γ under the 2° the triangulation takes: every point would be dropped as grazing, and
    the scan blamed its path (a 0.5 mm baseline). Refused where the rig is read; a Probe made
    through the API may still lower the limit (triangulate_profile's min_angle_deg)."""
    from addon.core.config.rigs import load_probe, probe_toml
    from addon.core.errors import ConfigError
    from addon.core.optics.probe import angles_from_range

    phi, gamma = angles_from_range(0.5, 0.0, 70.0, 250.0)
    probe = Probe("tiny", 0.5, 0.0, phi, gamma, 100, 100)  # the API takes it
    path = tmp_path / "tiny.toml"
    path.write_text(probe_toml(probe), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"tiny.toml.*φ \+ γ = 0.4.*less than 2°.*grazing"):
        load_probe(path)
