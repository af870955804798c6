"""The surface across the laser lines, from neighbouring profiles: curvature and incidence with
known answers on a cylinder and a tilted plane."""

import numpy as np

from addon.core.geometry.surface_fit import across_line, local_surfaces


def _probe_pose(origin, beam, across):
    """A probe pose (4, 4): x = ``across`` (the laser plane's normal), z = ``beam``."""
    z = np.asarray(beam, float) / np.linalg.norm(beam)
    x = np.asarray(across, float) - np.dot(across, z) * z
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = origin
    return T


def _lines_on_a_cylinder(radius, frames=15, step_mm=1.0, along=np.linspace(-6, 6, 25)):
    """Laser lines along a cylinder's axis (y), one per frame, stepping across it (x): the
    curvature 1/R lies across the lines."""
    pts, frame, poses = [], [], []
    for f in range(frames):
        x = (f - frames // 2) * step_mm
        z = np.sqrt(radius ** 2 - x ** 2)
        pts.append(np.column_stack([np.full(len(along), x), along, np.full(len(along), z)]))
        frame.append(np.full(len(along), f))
        poses.append(_probe_pose([x, 0.0, z + 160.0], [0, 0, -1], [1, 0, 0]))
    return np.vstack(pts), np.concatenate(frame), np.array(poses)


def test_sigma_across_the_line_is_the_beam_on_the_cylinders_curvature():
    radius, width, mid = 25.0, 1.2, 160.0
    P, frame, poses = _lines_on_a_cylinder(radius)
    steep, sigma = across_line(P, frame, poses, width, mid, 65.0)
    centre = np.abs(P[:, 0]) < 1.5
    beam = width / 4.0  # at 160 mm, the mid-range
    expected = 0.5 * (1.0 / radius) * beam ** 2
    assert not steep.any()
    np.testing.assert_allclose(np.median(sigma[centre]), expected, rtol=0.1)


def test_lines_on_a_plane_need_no_more_sigma_and_a_steep_plane_is_found():
    along = np.linspace(-6, 6, 25)
    for tilt_deg, steep_expected in ((30.0, False), (75.0, True)):
        t = np.radians(tilt_deg)
        pts, frame, poses = [], [], []
        for f in range(15):
            x = (f - 7) * 0.3  # lines about 1 mm apart on the surface even at 75°
            pts.append(np.column_stack([np.full(25, x), along, np.full(25, np.tan(t) * x)]))
            frame.append(np.full(25, f))
            poses.append(_probe_pose([x, 0.0, np.tan(t) * x + 160.0], [0, 0, -1], [1, 0, 0]))
        P, fr = np.vstack(pts), np.concatenate(frame)
        steep, sigma = across_line(P, fr, np.array(poses), 1.2, 160.0, 65.0)
        inner = (np.abs(P[:, 0]) < 1.2) & (np.abs(P[:, 1]) < 4)
        assert np.all(steep[inner] == steep_expected), tilt_deg
        assert np.max(sigma[inner]) < 1e-6


def test_a_single_line_fixes_no_surface():
    P = np.column_stack([np.zeros(60), np.linspace(-15, 15, 60), np.zeros(60)])
    ok, *_ = local_surfaces(P, np.zeros(60, int))
    assert not ok.any()
