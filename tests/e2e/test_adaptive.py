"""The reference adaptive planner on the demo sphere: it chooses sweeps from what its rays have
taught it, given only a box around the part, and the cloud grows where the part is."""

import numpy as np

from addon import Scanner
from addon.adaptive import adaptive_scan


def test_the_planner_covers_the_sphere_from_a_box_alone():
    scanner = Scanner.from_config("demo")
    lo, hi = np.array([-36.0, -36.0, 0.0]), np.array([36.0, 36.0, 66.0])  # what a cell would be told
    seen = []
    steps = adaptive_scan(scanner, lo, hi, max_profiles=225, log=seen.append)
    assert 2 <= len(steps) <= 3 and sum(s.profiles for s in steps) <= 225
    assert steps[0].new_cells > steps[-1].new_cells > 0  # each sweep teaches, the first most
    assert len({(s.table_deg, s.tilt_deg) for s in steps}) == len(steps)  # never the same sweep twice
    r = scanner.result().report
    truth = scanner.config.workpiece.truth
    result = scanner.result()
    d = truth.distance(result.cloud.points[result.on_part])
    assert np.sqrt(np.mean(d ** 2)) * 1e3 < 15.0
    # Three tilted sweeps from three sides see more of the sphere than the demo's whole
    # 180-frame path does (27 % of it).
    assert r["coverage"] > 0.35 and r["coverage_measurable"] > 0.9
    assert any("sweep 1:" in line for line in seen)
