"""Render and measure: a few settings of the accuracy benchmark (python -m headless bench
accuracy) run in CI with bounds taken from the measured figures plus a stated margin, so
that a regression in accuracy fails the suite.

Measured on the CI machine (Cycles, CPU, 2026-11-21) -> bound:
- tilted plate, 20 frames: RMS 0.85 µm, max 2.9 µm -> RMS ≤ 2 µm, max ≤ 8 µm (about 2.5×)
- demo sphere, 20 frames: RMS 6.8 µm, p95 9.0 µm -> RMS ≤ 10 µm (the issue's goal), p95 ≤ 15 µm
- step block, 20 frames: RMS 3.8 µm, p95 10.4 µm -> RMS ≤ 10 µm, p95 ≤ 20 µm
- demo sphere on the 1280 x 1024 probe, 6 frames: RMS 1.4 µm -> ≤ 5 µm (the goal)
- the paper's Eq. 6 on the plate: RMS 33 µm, where the exact intersection gives 0.85 µm:
  the approximation must stay visible (≥ 10× the exact), or the comparison has broken
- the slit laser read with matched smoothing: RMS 257 µm on the plate -> ≤ 500 µm and
  points on most columns (its flat-topped profile limits it; see the README)
"""

from dataclasses import replace

import numpy as np
import pytest

from addon.core.config.rigs import load_probe
from addon.core.config.scan import load_scan_config
from addon.pipeline import run_scan


def measure(cfg):
    rep = run_scan(cfg, None, write_outputs=False).report
    assert np.isfinite(rep["error_um"]["rms_um"])
    return rep


@pytest.fixture(scope="module")
def plane():
    return load_scan_config("tilted_plane").with_overrides(frames=slice(None, None, 3))


def test_plate(plane):
    e = measure(plane)["error_um"]
    assert e["rms_um"] <= 2.0 and e["max_um"] <= 8.0, e


def test_sphere_meets_the_goal():
    e = measure(load_scan_config("demo").with_overrides(frames=slice(None, None, 9)))["error_um"]
    assert e["rms_um"] <= 10.0 and e["p95_um"] <= 15.0, e


def test_step_block():
    e = measure(load_scan_config("step_block").with_overrides(frames=slice(None, None, 5)))["error_um"]
    assert e["rms_um"] <= 10.0 and e["p95_um"] <= 20.0, e


def test_high_resolution_probe_meets_the_goal():
    cfg = replace(load_scan_config("demo"), probe=load_probe("hires")).with_overrides(frames=slice(None, None, 30))
    e = measure(cfg)["error_um"]
    assert e["rms_um"] <= 5.0, e


def test_the_papers_approximation_stays_visible(plane):
    exact = measure(plane)["error_um"]["rms_um"]
    paper = measure(replace(plane, triangulate_method="paper"))["error_um"]["rms_um"]
    assert paper >= 10 * exact and paper <= 100.0, (paper, exact)


def test_slit_laser_still_measures(plane):
    cfg = replace(plane, render=replace(plane.render, laser="slit")).with_overrides(frames=slice(None, None, 2))
    rep = measure(cfg)
    assert rep["error_um"]["rms_um"] <= 500.0 and rep["valid_fraction"] > 0.8, rep["error_um"]
