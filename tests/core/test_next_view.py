"""Next-best-view candidates and their gain, on the known-space model (no mesh, no Blender)."""

import numpy as np
import pytest

from addon.core.config.scan import load_scan_config
from addon.core.geometry.known_space import KnownSpace
from addon.core.scan import next_view


def setup():
    cfg = load_scan_config("demo")
    lo, hi = np.array([-36.0, -36.0, 0.0]), np.array([36.0, 36.0, 66.0])
    return cfg, lo, hi, KnownSpace(lo - 6, hi + 6, 2.0)


def test_candidates_look_at_the_box_from_the_robots_side_within_the_probes_range():
    cfg, lo, hi, _ = setup()
    cands = next_view.candidates(cfg.cell, cfg.probe, lo, hi)
    views = 1 + 2 * (len(next_view.TILTS_DEG) - 1)
    swept = 1 + 2 * sum(0 < t <= next_view.MAX_SWEEP_TILT_DEG for t in next_view.TILTS_DEG)
    assert sum(c.kind == "sweep" for c in cands) == next_view.TABLE_STEPS * swept
    assert sum(c.kind == "turn" for c in cands) == views
    # A turn near the horizon (the sides, what hangs over them); no sweep that steep.
    assert max(abs(c.tilt_deg) for c in cands if c.kind == "turn") >= 60
    assert max(abs(c.tilt_deg) for c in cands if c.kind == "sweep") <= next_view.MAX_SWEEP_TILT_DEG
    z0, z1 = cfg.probe.z_range_mm
    centre = 0.5 * (lo + hi)
    for c in cands:
        P = c.waypoints().probe2table
        assert len(P) == c.frames
        beam = P[:, :3, 2]
        assert np.allclose(np.linalg.norm(beam, axis=1), 1.0) and (beam[:, 2] < 0).all()
        # Every frame's beam passes within the box's reach of its axis at mid-range.
        aim = P[:, :3, 3] + 0.5 * (z0 + z1) * beam
        assert (np.linalg.norm(aim[:, :2] - centre[:2], axis=1) < 0.5 * np.linalg.norm(hi - lo)).all()
        assert (aim[:, 2] > lo[2] - 1.0).all() and (aim[:, 2] < hi[2] + 1.0).all()
        if c.kind == "turn":  # the probe stands still in the world while the table turns
            assert np.ptp(c.waypoints().table_rad) > np.radians(350)


def sweep_from_above(cfg, lo, hi):
    return [c for c in next_view.candidates(cfg.cell, cfg.probe, lo, hi)
            if c.kind == "sweep" and c.tilt_deg == 0 and c.table_deg == 0][0]


def test_gain_falls_where_the_model_already_knows_the_surface():
    cfg, lo, hi, space = setup()
    poses = sweep_from_above(cfg, lo, hi).waypoints().probe2table
    before = next_view.gain(space, cfg.probe, poses)
    assert before > 100
    # Teach the model a flat top at z = 66 seen from those very poses: little stays unknown there.
    g = np.arange(-48.0, 48.01, 1.0)  # the whole top of the model's box
    x, y = np.meshgrid(g, g)
    space.add_points(poses[len(poses) // 2, :3, 3], np.column_stack([x.ravel(), y.ravel(), np.full(x.size, 66.5)]))
    after = next_view.gain(space, cfg.probe, poses)
    assert after < 0.1 * before


def test_cells_a_scanned_view_was_promised_and_did_not_teach_count_no_more():
    # The cells a view's fans first meet, unknown and in range, are what it promises; those
    # marked as missed (an earlier view promised them and they stayed unknown) do not count.
    cfg, lo, hi, space = setup()
    top = sweep_from_above(cfg, lo, hi)
    poses = top.waypoints().probe2table
    cells = next_view.new_cells(space, cfg.probe, poses)
    assert len(cells) == next_view.gain(space, cfg.probe, poses) > 100
    inside = (cells >= 0).all() and (cells < np.array(space.shape)).all()
    assert inside and len(np.unique(cells, axis=0)) == len(cells)
    missed = np.zeros(space.shape, bool)
    half = cells[::2]
    missed[half[:, 0], half[:, 1], half[:, 2]] = True
    assert next_view.gain(space, cfg.probe, poses, missed) == len(cells) - len(half)
    ranked = {c.key: c.gain for c in next_view.rank(space, cfg.probe, [top], 0.0, None, missed)}
    plain = {c.key: c.gain for c in next_view.rank(space, cfg.probe, [top], 0.0, None)}
    assert ranked[top.key] < plain[top.key]


def test_ranking_prefers_gain_per_second_and_drops_empty_views():
    cfg, lo, hi, space = setup()
    cands = next_view.candidates(cfg.cell, cfg.probe, lo, hi)
    ranked = next_view.rank(space, cfg.probe, cands, 0.0, None)
    assert ranked and all(c.gain > 0 for c in ranked)
    u = [c.utility for c in ranked]
    assert u == sorted(u, reverse=True)
    # Turning the table costs time: half a turn adds 180° at the table's speed.
    c = ranked[0]
    here = next_view.rank(space, cfg.probe, [c], c.table_deg, None)[0]
    there = next_view.rank(space, cfg.probe, [c], c.table_deg + 180.0, None)[0]
    assert there.gain == here.gain
    assert there.seconds - here.seconds == pytest.approx(180.0 / next_view.TABLE_DEG_PER_S)


def test_a_table_turn_lays_its_profiles_the_spacing_apart_at_the_radius_asked():
    for radius in (5.0, 20.0, 31.4, 51.0, 400.0):
        n = next_view.turn_frames(radius)
        assert 8 <= n <= next_view.MAX_TURN_FRAMES
        step = 2 * np.pi * radius / n  # arc between neighbouring profiles at that radius
        assert step <= next_view.TURN_SPACING_MM + 1e-9 or n == next_view.MAX_TURN_FRAMES
        assert n == 8 or 2 * np.pi * radius / (n - 1) > next_view.TURN_SPACING_MM  # no more than needed
    assert next_view.turn_frames(20.0, spacing_mm=1.0) > next_view.turn_frames(20.0)  # denser asked, more profiles


def test_a_resampled_turn_keeps_the_probe_where_it_stands_in_the_world():
    cfg, lo, hi, _ = setup()
    turn = [c for c in next_view.candidates(cfg.cell, cfg.probe, lo, hi) if c.kind == "turn" and c.tilt_deg == 45][0]
    fewer = next_view.resampled_turn(turn, 40, cfg.cell.table)
    assert fewer.frames == 40 and fewer.key == turn.key
    wp, old = fewer.waypoints(), turn.waypoints()
    assert wp.table_rad[0] == pytest.approx(old.table_rad[0])
    steps = np.diff(wp.table_rad)
    assert np.allclose(steps, 2 * np.pi / 40)  # a full circle, end left out
    # Probe pose in the robot's base frame: the same for every frame, and the turn's own.
    world = cfg.cell.table.table2base(wp.table_rad) @ wp.probe2table
    world_old = cfg.cell.table.table2base(old.table_rad[:1]) @ old.probe2table[:1]
    assert np.allclose(world, world_old[0], atol=1e-9)
    with pytest.raises(ValueError, match="only a table turn"):
        next_view.resampled_turn(sweep_from_above(cfg, lo, hi), 40, cfg.cell.table)


def test_rank_takes_the_probes_position_and_says_so_when_given_a_pose():
    from addon.core.errors import InputError

    cfg, lo, hi, space = setup()
    top = sweep_from_above(cfg, lo, hi)
    start = top.waypoints().probe2table[0]
    near = next_view.rank(space, cfg.probe, [top], 0.0, start[:3, 3])
    far = next_view.rank(space, cfg.probe, [top], 0.0, start[:3, 3] + [0.0, 0.0, 500.0])
    assert near[0].gain == far[0].gain > 0 and far[0].seconds > near[0].seconds  # travel costs time
    for wrong, said in ((start, "a 4x4 pose's position is pose[:3, 3]"), ([0.0, np.nan, 1.0], "must be finite")):
        with pytest.raises(InputError, match=said.replace("[", r"\[").replace("]", r"\]")):
            next_view.rank(space, cfg.probe, [top], 0.0, wrong)


def test_a_table_turns_twin_is_the_same_turn_half_a_circle_on():
    """Every table turn's twin (Candidate.twin_key: the turn from the other side of the part),
    both laid out with the same even number of profiles: each of the twin's probe poses is one
    of the turn's own turned half a circle about the table's axis (the table frame's z), so it
    meets the part as the turn did. A sweep is its own twin."""
    cfg, lo, hi, _ = setup()
    cands = next_view.candidates(cfg.cell, cfg.probe, lo, hi)
    turns = {c.key: c for c in cands if c.kind == "turn"}
    half_turn = np.diag([-1.0, -1.0, 1.0, 1.0])
    assert any(c.twin_key != c.key for c in turns.values())
    for c in turns.values():
        twin = turns[c.twin_key]
        assert twin.twin_key == c.key
        own = half_turn @ next_view.resampled_turn(c, 40, cfg.cell.table).waypoints().probe2table
        other = next_view.resampled_turn(twin, 40, cfg.cell.table).waypoints().probe2table
        nearest = np.abs(own[:, None] - other[None]).max(axis=(2, 3)).min(axis=1)
        assert nearest.max() < 1e-9
    assert all(c.twin_key == c.key for c in cands if c.kind == "sweep")


def test_views_of_a_box_reaching_under_the_table_aim_above_the_table_top():
    """A box told to reach 100 mm under the table aimed its steep views at a share of its whole
    height, into the table (the sphere's coverage fell from 64 to 54 % on the same budget): the
    part stands on the table top, so they aim as for the box that starts there."""
    cfg = load_scan_config("demo")
    hi = np.array([36.0, 36.0, 66.0])
    on_table = next_view.candidates(cfg.cell, cfg.probe, np.array([-36.0, -36.0, 0.0]), hi)
    reaching = next_view.candidates(cfg.cell, cfg.probe, np.array([-36.0, -36.0, -100.0]), hi)
    assert [c.describe() for c in on_table] == [c.describe() for c in reaching]
    for a, b in zip(on_table, reaching):
        np.testing.assert_allclose(a.wp.probe2table, b.wp.probe2table, atol=1e-9)
