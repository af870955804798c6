"""The CAD-like parts of ``bench parts`` are what they claim: closed, on the table, part-sized."""

import numpy as np
import pytest

pytest.importorskip("manifold3d", reason="trimesh booleans need manifold3d (installed by the README's set-up)")

from headless.parts import cad_parts as _parts  # noqa: E402


def test_every_part_is_closed_standing_on_the_table_and_45_to_70_mm():
    parts = _parts()
    assert len(parts) >= 4
    for name, mesh in parts.items():
        assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0, name
        lo, hi = mesh.bounds
        assert abs(lo[2]) < 1e-9, name  # standing on the table top
        assert np.allclose((lo[:2] + hi[:2]) / 2, 0.0, atol=1e-9), name  # on the table's axis
        assert 45.0 <= (hi - lo).max() <= 70.0, (name, hi - lo)


def test_the_hole_and_the_pocket_are_cut():
    block = _parts()["block with hole and pocket"]
    solid = 60.0 * 40.0 * 30.0
    hole = np.pi * 7.0 ** 2 * 30.0
    pocket = 16.0 * 24.0 * 13.0  # the pocket box (z 2..16 about the block's centre) is 13 mm deep
    # A 96-sided hole is slightly smaller than the circle: allow its polygon's deficit.
    assert block.volume == pytest.approx(solid - hole - pocket, rel=2e-3)


def test_parts_readme_with_a_probe_file_is_refused_before_the_scans():
    """A probe given by its file has no docs section: the run scanned every part (minutes with
    the 1280-row probe) and only then failed to find one."""
    import argparse

    import pytest

    from addon.core.errors import InputError
    from headless.bench import parts

    args = argparse.Namespace(readme=True, probe="rigs/probes/hires.toml", only="", frames=60)
    with pytest.raises(InputError, match="no page .* has the section"):
        parts.run(args)
