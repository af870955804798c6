"""When a band render must be redone at full height: only when the band may have cut the line.

A line cut by the part itself (one flank dark: a depth edge) is coded EDGE wherever it
lies; that is the scene's own and re-rendering the frame at full height cannot change
it. A line whose peak sits on the band's first or last row may run on outside the band.
"""

import numpy as np

from addon.core.optics.detect import DetectParams, LineCode, detect_line
from addon.core.scan.band import needs_full_frame as _needs_full_frame

ROWS, COLS = 100, 64
BAND = (30, 60)
UNSMOOTHED = DetectParams(smoothing_px=0.0)


def band_image(centre_rows, dark_below=None):
    """The band's rows of a sensor image with a Gaussian line (σ 0.8 px) at ``centre_rows``
    (sensor rows, one per column); in the columns of ``dark_below`` everything below the
    peak row is dark (the line's far flank hidden by an edge of the part)."""
    v = np.arange(BAND[0], BAND[1], dtype=float)[:, None]
    img = np.exp(-0.5 * ((v - np.asarray(centre_rows, float)[None, :]) / 0.8) ** 2)
    if dark_below is not None:
        peak = np.round(centre_rows).astype(int)
        for c in np.flatnonzero(dark_below):
            img[peak[c] - BAND[0] + 1:, c] = 0.0
    return img.astype(np.float32)


def detect(img):
    return detect_line(img, "gauss", UNSMOOTHED, row_offset=BAND[0])


def test_a_line_cut_by_the_part_inside_the_band_is_not_rendered_again():
    centre = np.full(COLS, 45.2)
    cut = np.zeros(COLS, bool)
    cut[20:30] = True
    line = detect(band_image(centre, cut))
    assert np.all(line.code[cut] == LineCode.EDGE)  # the scene's own edge, rejected
    assert line.valid[~cut].all()
    assert not _needs_full_frame([line, None], BAND, [None, None], ROWS, 4)


def test_a_line_on_the_bands_edge_is_rendered_again():
    for row in (BAND[0] - 0.3, BAND[1] - 1 + 0.3):  # peak on the first or last row of the band
        line = detect(band_image(np.full(COLS, row)))
        assert np.any(line.code == LineCode.EDGE)
        assert _needs_full_frame([line, None], BAND, [None, None], ROWS, 4), row


def test_the_sensors_own_edge_is_not_a_reason_to_render_again():
    band = (0, 30)  # the band starts at the sensor's first row: nothing lies beyond it
    v = np.arange(band[0], band[1], dtype=float)[:, None]
    img = np.exp(-0.5 * ((v - 0.2) / 0.8) ** 2).astype(np.float32)
    line = detect_line(img, "gauss", UNSMOOTHED, row_offset=0)
    assert np.all(line.code == LineCode.EDGE)
    assert not _needs_full_frame([line, None], band, [None, None], ROWS, 4)


def test_peak_rows_are_sensor_rows_for_every_column_and_method():
    centre = np.linspace(38.0, 52.0, COLS)
    img = band_image(centre)
    for method in ("gauss", "cog", "steger", "threshold"):
        line = detect_line(img, method, UNSMOOTHED if method == "gauss" else None, row_offset=BAND[0])
        np.testing.assert_array_equal(line.peak_row, np.round(centre).astype(int), err_msg=method)
