"""The spot-light laser (Eevee's line): its profile against the exact Gaussian, and what the detector reads on it."""

import math

import numpy as np
import pytest

from addon.core.optics.detect import DetectParams, detect_line
from addon.core.optics.laser_profile import SPOT_COMPONENTS, spot_line_profile, spot_mask, spot_squeezes

H = 40


def _column_image(profile, sigma_px: float, centres) -> np.ndarray:
    """Grey image, one column per centre: ``profile`` (a function of offset / σ) point-sampled at pixel centres."""
    rows = np.arange(H, dtype=np.float64)[:, None]
    return (0.5 * profile((rows - np.asarray(centres)[None, :]) / sigma_px)).astype(np.float64)


def test_the_sum_of_spots_is_the_gaussian_line_within_a_few_thousandths():
    v = np.linspace(-3, 3, 1201)
    gauss = np.exp(-v * v / 2)
    p = spot_line_profile(v)
    assert p[600] == pytest.approx(1.0, abs=1e-5)  # the peak: the power calibration holds
    assert np.allclose(p, p[::-1])  # symmetric about the laser plane
    rel = np.abs(p / gauss - 1)
    assert rel[np.abs(v) <= 2.5].max() < 0.0015
    assert rel.max() < 0.003
    assert sum(c[0] for c in SPOT_COMPONENTS) == pytest.approx(1.0, abs=1e-5)
    # Along the line the shape holds: at the camera's edge of view (17°) and the fan's end (30°).
    for along_deg, bound in ((17, 0.004), (30, 0.007)):
        q = spot_line_profile(v, math.radians(along_deg))
        assert np.abs(q / q[600] / gauss - 1)[np.abs(v) <= 2.5].max() < bound, along_deg


def test_one_squeezed_spot_is_flat_topped_so_the_fit_misreads_it():
    # The reason for the sum: smoothstep has no slope at its top, so one spot's profile has no v² term.
    alpha = math.radians(70.0)
    edge = 3.0

    def one(v):
        return spot_mask(v / edge * math.tan(alpha), alpha)

    v = 1e-2
    assert 1 - one(np.array(v)) < 1e-6  # the Gaussian would be 5e-5 down here
    centres = 20 + np.linspace(0, 1, 51, endpoint=False)
    line = detect_line(_column_image(one, 0.55 * 1.6, centres), "gauss", DetectParams(smoothing_px=0))
    assert np.abs(line.row - centres).max() > 0.01


@pytest.mark.parametrize("sigma_px", [0.45, 0.55, 0.8, 1.1, 1.5, 2.0])
def test_the_detector_reads_the_spot_line_where_it_is(sigma_px):
    centres = 20 + np.linspace(0, 1, 101, endpoint=False)
    line = detect_line(_column_image(spot_line_profile, sigma_px, centres), "gauss", DetectParams(smoothing_px=0))
    assert line.valid.all()
    assert np.abs(line.row - centres).max() < 0.003, sigma_px
    # Its stated σ stays small: the width the three samples show hardly changes with the phase.
    assert np.median(line.sigma_px) < (0.1 if sigma_px < 0.5 else 0.02), sigma_px


def test_squeezes_put_each_components_edge_at_its_width():
    sigma = 1.2 / 4 / 160  # the default probe's line: 1/e² width 1.2 mm at 160 mm
    for (_, edge, half_angle_deg), s in zip(SPOT_COMPONENTS, spot_squeezes(sigma)):
        alpha = math.radians(half_angle_deg)
        # A ray at ψ across the plane counts as at tan θ' = tan ψ / s (Blender's squeezed cone).
        inside, outside = math.tan(0.99 * edge * sigma) / s, math.tan(1.01 * edge * sigma) / s
        assert spot_mask(inside, alpha) > 0 and spot_mask(outside, alpha) == 0
    for bad in (0.0, -1e-3, float("nan"), 0.5):
        with pytest.raises(ValueError, match="angular σ"):
            spot_squeezes(bad)
