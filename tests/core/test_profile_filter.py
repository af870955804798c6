"""The profile filter: incidence read off the profile, steep points and run ends dropped."""

import numpy as np
import pytest

from addon.core.errors import InputError
from addon.core.optics.profile_filter import ProfileFilter, filter_profile, incidence_deg
from addon.core.optics.triangulate import Profile


def profile(points, col=None):
    n = len(points)
    col = np.arange(n, dtype=float) if col is None else np.asarray(col, float)
    return Profile(np.asarray(points, float), col, np.ones(n, np.uint8), np.full(n, 0.5), np.full(n, 0.01), {})


def circle_profile(R=30.0, height=150.0, n=121):
    """A cylinder's cross-section in the laser plane (x = 0): the laser at the origin looks
    down +z at a circle of radius R centred at depth height + R."""
    t = np.linspace(-1.2, 1.2, n)  # incidence up to about 75°
    y, z = R * np.sin(t), height + R - R * np.cos(t)
    return np.column_stack([np.zeros(n), y, z])


def test_incidence_matches_the_geometry():
    P = circle_profile()
    inc, jump = incidence_deg(P, np.arange(len(P), dtype=float))
    centre = np.array([0.0, 0.0, 180.0])
    normal = (P - centre) / 30.0  # outward
    ray = P / np.linalg.norm(P, axis=1)[:, None]
    truth = np.degrees(np.arccos(np.clip(-(normal * ray).sum(1), -1, 1)))
    assert not jump.any()
    # Central differences on a circle sampled this finely: within a few hundredths of a degree.
    np.testing.assert_allclose(inc[1:-1], truth[1:-1], atol=0.05)


def test_steep_points_and_run_ends_are_dropped_and_counted():
    P = circle_profile()
    inc, _ = incidence_deg(P, np.arange(len(P), dtype=float))
    out = filter_profile(profile(P), ProfileFilter(max_incidence_deg=60.0, edge_px=0))
    assert len(out) == int(np.sum(inc <= 60.0)) and out.masked["steep"] == int(np.sum(inc > 60.0))
    # A step in the middle (a 5 mm jump) splits the run: two ends more on each side of it.
    flat = np.column_stack([np.zeros(40), np.linspace(-10, 10, 40), np.full(40, 150.0)])
    flat[20:, 2] += 5.0
    out = filter_profile(profile(flat), ProfileFilter(edge_px=2))
    assert len(out) == 40 - 8 and out.masked["edge"] == 8
    kept = set(np.round(out.col).astype(int))
    assert kept == set(range(2, 18)) | set(range(22, 38))


def test_missing_columns_break_runs_and_lone_points_go():
    flat = np.column_stack([np.zeros(12), np.linspace(-5, 5, 12), np.full(12, 150.0)])
    cols = [0, 1, 2, 3, 4, 5, 7, 8, 9, 10, 11, 20]  # a gap after 5, and a lone point at 20
    flat[-1, 1] = 12.0
    out = filter_profile(profile(flat, cols), ProfileFilter(max_incidence_deg=80.0, edge_px=1))
    assert sorted(np.round(out.col).astype(int)) == [1, 2, 3, 4, 8, 9, 10]
    assert out.masked["steep"] == 1  # the lone point: no slope to judge it by


def test_off_filter_changes_nothing_and_bad_settings_are_refused():
    p = profile(circle_profile())
    assert filter_profile(p, ProfileFilter()) is p
    for kw in (dict(max_incidence_deg=0.0), dict(max_incidence_deg=95.0), dict(edge_px=-1), dict(edge_px=1.5)):
        with pytest.raises(InputError):
            ProfileFilter(**kw)


def test_points_less_certain_than_the_limit_are_dropped_and_counted():
    from addon.core.optics.profile_filter import ProfileFilter, drop_uncertain
    from addon.core.optics.triangulate import Profile

    sigma = np.array([0.001, 0.2, 0.01, 0.06, 0.05])
    p = Profile(np.zeros((5, 3)), np.arange(5.0), np.ones(5, np.uint8), np.ones(5), sigma, {"uncertain": 1})
    out = drop_uncertain(p, ProfileFilter(max_sigma_mm=0.05))
    np.testing.assert_array_equal(out.sigma_mm, [0.001, 0.01, 0.05])
    assert out.masked["uncertain"] == 3
    assert len(drop_uncertain(p, ProfileFilter())) == 5  # off by default
    with pytest.raises(InputError):
        ProfileFilter(max_sigma_mm=0.0)
