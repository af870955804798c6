"""Every row of the accuracy benchmark's table builds a valid scan config on every scene (a
row of 16 samples was refused once the Cycles box rule came in: the bench stopped before its
first render, and only a run of it would have told)."""

import pytest

from addon.core.config.scan import load_scan_config
from headless.bench.accuracy import SCENES, factors, variant


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_every_row_of_the_accuracy_table_builds_a_config(scene):
    base = load_scan_config(SCENES[scene])
    for factor, rows in factors().items():
        for setting, changes in rows:
            cfg = variant(base, changes)
            if "samples" in changes:
                assert cfg.render.samples == changes["samples"], (factor, setting)
            if "filter_width_px" in changes:
                assert cfg.render.filter_width_px == changes["filter_width_px"], (factor, setting)
