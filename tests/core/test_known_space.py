"""The known-space model: what rays to measured points teach, against analytic geometry."""

import numpy as np
import pytest

from addon.core.errors import InputError
from addon.core.geometry.known_space import FREE, SURFACE, UNKNOWN, KnownSpace


def plane_scan():
    """A plane z = 0.25 mm seen from 100 mm above the origin, points every 0.5 mm over ±15 mm."""
    space = KnownSpace([-20, -20, -10], [20, 20, 30], 1.0)
    g = np.arange(-15.0, 15.01, 0.5)
    x, y = np.meshgrid(g, g)
    points = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, 0.25)])
    space.add_points([0.0, 0.0, 100.0], points)
    return space


def state_at(space, p):
    idx, inside = space.cell_of(np.array([p], dtype=float))
    assert inside[0]
    return space.state[tuple(idx[0])]


def test_rays_carve_free_space_down_to_the_surface_and_leave_what_is_behind_unknown():
    space = plane_scan()
    assert state_at(space, [0, 0, 0.5]) == SURFACE
    assert state_at(space, [14.9, -14.9, 0.5]) == SURFACE
    for z in (1.5, 10.5, 29.5):
        assert state_at(space, [0, 0, z]) == FREE
    assert state_at(space, [0, 0, -0.5]) == UNKNOWN
    assert state_at(space, [0, 0, -9.5]) == UNKNOWN
    # The cone of rays from (0, 0, 100) to the ±15 mm square: at z = 20 it spans ±12 mm.
    assert state_at(space, [11.5, 0, 20.5]) == FREE
    assert state_at(space, [19.5, 0, 20.5]) == UNKNOWN
    counts = space.counts()
    assert counts["surface"] == 31 * 31 and sum(counts.values()) == 40 * 40 * 40


def test_first_hits_see_the_surface_from_above_and_the_unknown_from_the_side():
    space = plane_scan()
    d, what = space.first_hits([0.0, 0.0, 100.0], [[0, 0, -1.0], [0.1, 0.05, -1.0]], 250.0)
    assert what.tolist() == [SURFACE, SURFACE]
    assert d[0] == pytest.approx(99.0, abs=0.5 + 1e-9)  # the surface cell's top is z = 1
    # From the side, below the plane: the grid's unknown begins at its face x = 20.
    d, what = space.first_hits([30.0, 0.3, -5.0], [[-1.0, 0, 0]], 250.0)
    assert what[0] == UNKNOWN and d[0] == pytest.approx(10.0, abs=0.5 + 1e-9)
    # Out of range, or missing the grid: nothing.
    d, what = space.first_hits([0.0, 0.0, 100.0], [[0, 0, -1.0], [0, 0, 1.0]], 50.0)
    assert np.isinf(d).all() and what.tolist() == [FREE, FREE]


def test_the_frontier_is_unknown_next_to_free_and_not_behind_the_surface():
    space = plane_scan()
    frontier = {tuple(i) for i in space.frontier()}
    below = tuple(space.cell_of(np.array([[0, 0, -0.5]]))[0][0])
    assert below not in frontier  # next to surface only
    side = tuple(space.cell_of(np.array([[19.5, 0, 20.5]]))[0][0])
    inward = tuple(space.cell_of(np.array([[12.5, 0, 20.5]]))[0][0])
    assert space.state[inward] == FREE or inward in frontier
    assert all(space.state[c] == UNKNOWN for c in frontier)
    assert side not in frontier or space.state[side] == UNKNOWN
    assert len(frontier) > 0


def test_a_sphere_seen_from_six_sides_keeps_its_inside_unknown():
    space = KnownSpace([-30, -30, -30], [30, 30, 30], 1.0)
    rng = np.random.default_rng(0)
    for axis in np.vstack([np.eye(3), -np.eye(3)]):
        origin = 200.0 * axis
        d = rng.normal(size=(20000, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        d = d[d @ axis > 0.3]  # the side that faces the origin
        space.add_points(origin, 10.0 * d)
    assert state_at(space, [0.5, 0.5, 0.5]) == UNKNOWN
    assert state_at(space, [5.5, 0.5, 0.5]) == UNKNOWN
    assert state_at(space, [14.5, 0.5, 0.5]) == FREE
    surface = space.centres(np.argwhere(space.state == SURFACE))
    r = np.linalg.norm(surface, axis=1)
    assert r.min() > 10.0 - np.sqrt(3) and r.max() < 10.0 + np.sqrt(3)  # every surface cell holds the sphere


def test_bad_boxes_and_non_finite_points():
    with pytest.raises(InputError):
        KnownSpace([0, 0, 0], [0, 1, 1], 1.0)
    with pytest.raises(InputError):
        KnownSpace([0, 0, 0], [1, 1, 1], np.nan)
    with pytest.raises(InputError, match="too many"):
        KnownSpace([0, 0, 0], [1e4, 1e4, 1e4], 0.1)
    # a box so large that its cell count would wrap an integer, and cells that are no number
    with pytest.raises(InputError, match="too many"):
        KnownSpace([0, 0, 0], [1e20, 1e20, 1e20], 2.0)
    for cell in ("2", None, True):
        with pytest.raises(InputError, match="positive number of mm"):
            KnownSpace([0, 0, 0], [1, 1, 1], cell)
    space = KnownSpace([0, 0, 0], [10, 10, 10], 1.0)
    assert space.add_points([5, 5, 50], [[np.nan, 5, 5]]) == 0
    assert space.counts()["unknown"] == 1000



def sphere_seen_from(directions, cap: float) -> KnownSpace:
    """A sphere of radius 10 mm at the origin scanned from 200 mm along each direction, the
    points on the cap that faces it (directions · normal > cap)."""
    space = KnownSpace([-30, -30, -30], [30, 30, 30], 1.0)
    rng = np.random.default_rng(0)
    for axis in np.asarray(directions, dtype=float):
        axis = axis / np.linalg.norm(axis)
        d = rng.normal(size=(20000, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        space.add_points(200.0 * axis, 10.0 * d[d @ axis > cap])
    return space


def test_the_coverage_estimate_grows_as_the_views_close_in_around_the_part():
    import itertools

    box = ([-13.0] * 3, [13.0] * 3)
    assert KnownSpace([-30] * 3, [30] * 3, 1.0).coverage_estimate(*box) == 0.0
    one = sphere_seen_from([[0, 0, 1]], 0.3).coverage_estimate(*box)
    six = sphere_seen_from(np.vstack([np.eye(3), -np.eye(3)]), 0.3).coverage_estimate(*box)
    around = [v for v in itertools.product([-1, 0, 1], repeat=3) if any(v)]
    all_round = sphere_seen_from(around, 0.0).coverage_estimate(*box)
    # From one side, 35 % of the sphere is seen: the rim of the rays' cone is its whole frontier.
    assert 0.2 < one < 0.75
    # Seen whole from six sides, the box's corners that no ray crossed still count as unseen;
    # from 26 directions nothing unknown borders free space inside the box.
    assert one < six < all_round and all_round >= 0.95
    # Only the box counts: outside it the unknown space around the scan is not the part's.
    assert sphere_seen_from([[0, 0, 1]], 0.3).coverage_estimate([-30.0] * 3, [30.0] * 3) < one


def test_a_plate_thinner_than_a_cell_and_a_half_still_has_a_coverage_estimate():
    """The estimate leaves out the box's bottom layer (the table top the part stands on); a
    part thinner than that layer and a half kept no layer at all and read 0 whatever was seen.
    A 2.5 mm plate on the table seen from above: its top layer counts."""
    space = KnownSpace([-26.0, -26.0, -6.0], [26.0, 26.0, 8.5], 2.0)
    g = np.arange(-19.75, 19.76, 0.5)
    x, y = np.meshgrid(g, g)
    top = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, 2.5)])
    space.add_points([0.0, 0.0, 150.0], top)
    estimate = space.coverage_estimate([-20.0, -20.0, 0.0], [20.0, 20.0, 2.5])
    assert estimate > 0.5, estimate
