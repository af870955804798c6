"""Synthetic laser-line images with known sub-pixel centres, for benchmarks and tests.

The line profile across each column is a Gaussian of standard deviation σ
centred at a known row, averaged over each pixel's area (the difference of two
error functions), on a grey background: red channel = background + line, green and
blue = background. Optional additive Gaussian noise (a fraction of the peak, per
channel) and clipping at full scale. The truth comes from the formula, never from
a detector.
"""

from __future__ import annotations

from math import erf, sqrt

import numpy as np

_erf = np.vectorize(erf, otypes=[float])


def gaussian_profile(rows: np.ndarray, centre: np.ndarray, sigma: float, integrate: bool = True) -> np.ndarray:
    """Line intensity (peak 1 before averaging) at integer rows (H, 1) for centres (1, W)."""
    if not integrate:
        return np.exp(-0.5 * ((rows - centre) / sigma) ** 2)
    s = sigma * sqrt(2.0)
    hi = _erf((rows + 0.5 - centre) / s)
    lo = _erf((rows - 0.5 - centre) / s)
    # Mean of exp(−x²/2σ²) over the pixel [row − ½, row + ½].
    return 0.5 * (hi - lo) * sigma * sqrt(2.0 * np.pi)


def line_image(rows_px: int, centres: np.ndarray, sigma: float, *, peak: float = 0.6,
               background: float = 0.2, noise: float = 0.0, clip: bool = True,
               rng: np.random.Generator | None = None, integrate: bool = True) -> np.ndarray:
    """(H, W, 3) float32 RGB image of a red line with centre row ``centres[j]`` in column j.

    peak : line amplitude above the background (fraction of full scale); above
        1 − background the line clips when ``clip`` is set
    noise : standard deviation of additive noise, as a fraction of ``peak``
    """
    centres = np.asarray(centres, dtype=np.float64)
    rows = np.arange(rows_px, dtype=np.float64)[:, None]
    line = peak * gaussian_profile(rows, centres[None, :], sigma, integrate)
    img = np.empty((rows_px, len(centres), 3), dtype=np.float64)
    img[:, :, 0] = background + line
    img[:, :, 1] = background
    img[:, :, 2] = background
    if noise > 0:
        rng = rng or np.random.default_rng(0)
        img += rng.normal(scale=noise * peak, size=img.shape)
    if clip:
        img = np.clip(img, 0.0, 1.0)
    return img.astype(np.float32)
