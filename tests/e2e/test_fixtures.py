"""Fixtures on the table are rendered with the part: they hide it, shadow it and give points of
their own, counted apart from the part's. Ground truth: the box's own distance function."""

from dataclasses import replace

import numpy as np
import pytest
import trimesh

pytest.importorskip("bpy", reason="scans render with bpy (installed by the README's set-up)")

from addon import Scanner  # noqa: E402
from addon.core.config.scan import load_scan_config  # noqa: E402
from addon.core.safety import Fixture  # noqa: E402

CENTRE, SIZE = np.array([45.0, 0.0, 30.0]), np.array([20.0, 60.0, 60.0])  # a block beside the demo's sphere


def box_distance(points):
    """Unsigned distance (mm) of points (n, 3) to the block's surface, from its own geometry."""
    q = np.abs(points - CENTRE) - SIZE / 2
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
    inside = np.minimum(q.max(axis=1), 0.0)
    return np.abs(outside + inside)


def demo(engine: str, fixtures=(), frames=None):
    cfg = load_scan_config("demo")
    cfg = replace(cfg, render=replace(cfg.render, engine=engine), fixtures=fixtures)
    if frames is not None:
        cfg = replace(cfg, waypoints=cfg.waypoints.select(frames))
    scanner = Scanner(config=cfg)
    scanner.run()
    return scanner.result()


def block():
    mesh = trimesh.creation.box(SIZE)
    mesh.apply_translation(CENTRE)
    return (Fixture("fixture block", mesh, "table"),)


@pytest.mark.parametrize("engine, frames", [("raycast", None), ("cycles", np.arange(0, 180, 4))])
def test_a_table_fixture_is_rendered_hides_what_lies_under_it_and_its_points_are_counted_apart(engine, frames):
    bare, with_block = demo(engine, frames=frames), demo(engine, block(), frames=frames)
    r = with_block.report
    on_block = box_distance(with_block.cloud.points) < 0.2
    assert r["points_on_fixtures"] > 100 and r["points_on_fixtures"] == pytest.approx(on_block.sum(), abs=5)
    assert not any("not rendered" in w for w in r["warnings"])
    # No point of the table top where the block stands: it covers that table.
    P = with_block.cloud.points
    under = (np.abs(P[:, 0] - CENTRE[0]) < SIZE[0] / 2 - 1) & (np.abs(P[:, 1]) < SIZE[1] / 2 - 1) & (P[:, 2] < 1)
    Q = bare.cloud.points
    bare_under = (np.abs(Q[:, 0] - CENTRE[0]) < SIZE[0] / 2 - 1) & (np.abs(Q[:, 1]) < SIZE[1] / 2 - 1) & (Q[:, 2] < 1)
    assert bare_under.sum() > 100 and under.sum() == 0
    # The part's figures leave the block's points out: its error stays what it was without the block.
    assert r["error_um"]["rms_um"] < bare.report["error_um"]["rms_um"] + 1.0
    assert r["error_um"]["max_um"] < 200  # none of the block's points (5 mm and more from the sphere) is the part's


def test_a_jaw_pressed_against_the_part_takes_none_of_the_parts_points_and_gives_it_none_of_its_own():
    """A clamp jaw pressed 0.5 mm into the sphere's side (raycast): the split by nearest surface
    sends no point lying on the sphere to the jaw and no point lying on the jaw to the part,
    judged by the sphere's and the box's own distance functions."""
    centre, size = np.array([39.5, 0.0, 30.0]), np.array([20.0, 20.0, 20.0])
    jaw = trimesh.creation.box(size)
    jaw.apply_translation(centre)
    result = demo("raycast", (Fixture("fixture jaw", jaw, "table"),))
    P = result.cloud.points
    to_sphere = np.abs(np.linalg.norm(P - [0.0, 0.0, 30.0], axis=1) - 30.0)
    q = np.abs(P - centre) - size / 2
    to_jaw = np.abs(np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0))
    on_fixture = ~result.on_part & (P[:, 2] > 0.5)  # not the part's and above the table top
    assert result.report["points_on_fixtures"] == on_fixture.sum() > 300
    assert not (on_fixture & (to_sphere < 0.02)).any() and not (result.on_part & (to_jaw < 0.02)).any()
    assert result.report["error_um"]["rms_um"] < 9.0
    # Each point's error is against what it counts as: the jaw's points against the box.
    np.testing.assert_allclose(result.error_um[result.on_fixture], to_jaw[result.on_fixture] * 1e3, atol=0.01)
