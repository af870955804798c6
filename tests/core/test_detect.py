"""Laser-line detection on synthetic images with known sub-pixel centres, and on bad images."""

import numpy as np
import pytest

from addon.core.optics.detect import DetectParams, LineCode, detect_line
from addon.core.errors import InputError
from headless.synthetic import line_image

H, W = 160, 200


def smooth_line(seed=0, rows=H, cols=W):
    """A gently tilted and curved line, continuous from column to column, at known centres."""
    rng = np.random.default_rng(seed)
    u = np.arange(cols)
    return rows / 2 + rng.uniform(-0.5, 0.5) + 0.05 * (u - cols / 2) + 3 * np.sin(u / 23.0 + rng.uniform(0, 6))


# Mean absolute error bounds; the benchmark (python -m headless bench detect) measures the full grid.
BOUNDS = {  # method: (noise-free, 2 % noise)
    "gauss": (0.01, 0.05),
    "steger": (0.01, 0.05),
    "cog": (0.1, 0.12),
    "threshold": (0.35, 0.4),
}


@pytest.mark.parametrize("method", list(BOUNDS))
@pytest.mark.parametrize("sigma", [0.7, 1.0, 2.0, 3.0])
@pytest.mark.parametrize("noise", [0.0, 0.02])
def test_sub_pixel_accuracy(method, sigma, noise):
    centre = smooth_line(seed=int(sigma * 10))
    img = line_image(H, centre, sigma, noise=noise, rng=np.random.default_rng(1))
    line = detect_line(img, method)
    assert line.valid.mean() >= 0.95, line.counts()
    err = np.abs(line.row - centre)[line.valid]
    assert err.mean() <= BOUNDS[method][0 if noise == 0 else 1], (method, sigma, noise, err.mean())


def test_result_layout():
    centre = smooth_line()
    line = detect_line(line_image(H, centre, 1.2), "gauss")
    np.testing.assert_array_equal(line.col, np.arange(W))
    assert line.row.shape == line.peak.shape == line.width.shape == line.code.shape == (W,)
    assert line.shape == (H, W)
    # FWHM of a Gaussian is 2.355 σ.
    assert np.median(line.width) == pytest.approx(2.355 * 1.2, rel=0.1)
    assert np.median(line.peak) == pytest.approx(0.6, rel=0.15)


@pytest.mark.parametrize("method", list(BOUNDS))
def test_reflection_double_peak_is_rejected_not_averaged(method):
    centre = smooth_line()
    img = line_image(H, centre, 1.2, peak=0.6)
    ghost = line_image(H, centre + 30, 1.2, peak=0.3, background=0.0)  # a reflection 30 px away
    both = np.clip(img + ghost, 0, 1)
    line = detect_line(both, method)
    assert np.all(line.code[5:-5] == LineCode.AMBIGUOUS), line.counts()
    assert np.isnan(line.row[line.code == LineCode.AMBIGUOUS]).all()
    # A reflection 3-4 px away, inside the band that hides the main line's own flanks: the
    # dip between them tells two lines from one (cog averaged them, gauss took either).
    # (the paper's threshold sees one lit run until the lines are 3.5 px apart; steger smooths
    # the image first, which merges lines closer than about 5 px: docs/optics.md)
    for gap in {"gauss": (3.0, 3.5, 4.0), "cog": (3.0, 3.5, 4.0), "threshold": (3.5, 4.0)}.get(method, ()):
        near = np.clip(img + line_image(H, centre + gap, 0.6, peak=0.4, background=0.0), 0, 1)
        narrow = np.clip(line_image(H, centre, 0.6, peak=0.6) + line_image(H, centre + gap, 0.6, peak=0.4,
                                                                             background=0.0), 0, 1)
        line = detect_line(narrow, method)
        assert np.mean(line.code[5:-5] == LineCode.AMBIGUOUS) > 0.9, (gap, line.counts())
        assert detect_line(near, method).valid.sum() <= detect_line(img, method).valid.sum()
    # A faint stray reflection (below the ratio) does not reject the column.
    faint = np.clip(img + line_image(H, centre + 30, 1.2, peak=0.05, background=0.0), 0, 1)
    ok = detect_line(faint, method)
    assert ok.valid.mean() > 0.95


@pytest.mark.parametrize("method", list(BOUNDS))
def test_saturated_line_is_flagged(method):
    img = line_image(H, smooth_line(), 1.5, peak=1.5)  # clips at full scale
    line = detect_line(img, method)
    assert np.all(line.code == LineCode.SATURATED), line.counts()


@pytest.mark.parametrize("method", list(BOUNDS))
@pytest.mark.parametrize("fill", [0.0, 0.5, 1.0])
def test_blank_images_have_no_line(method, fill):
    line = detect_line(np.full((H, W, 3), fill, np.float32), method)
    assert np.all(line.code == LineCode.NO_LINE)
    assert np.isnan(line.row).all()


@pytest.mark.parametrize("method", list(BOUNDS))
def test_nan_pixels_only_spoil_their_columns(method):
    img = line_image(H, smooth_line(), 1.2)
    img[40, 10] = np.nan
    img[100, 50, 1] = np.inf
    line = detect_line(img, method)
    assert line.code[10] == LineCode.BAD_PIXELS and line.code[50] == LineCode.BAD_PIXELS
    others = np.delete(np.arange(W), [10, 50])
    assert line.valid[others].mean() > 0.95


def test_too_wide_and_edge():
    wide = detect_line(line_image(H, np.full(W, 80.0), 15.0, peak=0.6), "gauss")
    assert np.all(wide.code == LineCode.TOO_WIDE)
    for method in BOUNDS:  # every method, the paper's threshold too (it reported these as good)
        for centre in (-0.4, 0.0, H - 1.0, H - 0.55):
            edge = detect_line(line_image(H, np.full(W, centre), 1.0), method)
            assert np.all(edge.code == LineCode.EDGE), (method, centre, edge.counts())


def test_integer_and_colour_formats_agree():
    centre = smooth_line()
    img = line_image(H, centre, 1.5, peak=0.5)
    ref = detect_line(img, "gauss").row
    u8 = detect_line(np.round(img * 255).astype(np.uint8), "gauss").row
    u16 = detect_line(np.round(img * 65535).astype(np.uint16), "gauss").row
    rgba = detect_line(np.dstack([img, np.ones((H, W), np.float32)]), "gauss").row
    grey = detect_line(img[:, :, 0] - img[:, :, 1], "gauss").row
    assert np.nanmax(np.abs(u8 - ref)) < 0.05  # 8-bit quantisation
    assert np.nanmax(np.abs(u16 - ref)) < 1e-3
    np.testing.assert_allclose(rgba, ref, atol=1e-9)
    np.testing.assert_allclose(grey, ref, atol=1e-5)


@pytest.mark.parametrize(
    "image,fragment",
    [
        (np.zeros(10), "shape"),
        (np.zeros((5, 5, 2)), "shape"),
        (np.zeros((2, 5)), "at least 3 rows"),
        (np.zeros((5, 5), dtype=bool), "dtype"),
        (np.zeros((5, 5), dtype=complex), "dtype"),
        ([[0.0, 1.0]], "numpy array"),
    ],
)
def test_bad_inputs_give_clear_errors(image, fragment):
    with pytest.raises(InputError, match=fragment):
        detect_line(image)


def test_unknown_method():
    with pytest.raises(InputError, match="not one of"):
        detect_line(np.zeros((5, 5)), "magic")


def test_columns_much_wider_than_the_line_are_rejected_when_asked():
    from addon.core.optics.detect import DetectParams

    W = 100
    sigma = np.full(W, 0.8)
    sigma[40:50] = 2.0  # a stretch where the line spreads (grazing across it)
    img = np.concatenate([line_image(160, np.full(1, 70.3), s, integrate=False) for s in sigma], axis=1)
    plain = detect_line(img, "gauss", DetectParams(saturation=np.inf, smoothing_px=0.0))
    assert plain.valid.all()
    picky = detect_line(img, "gauss", DetectParams(saturation=np.inf, smoothing_px=0.0, max_width_ratio=1.6))
    assert np.array_equal(np.flatnonzero(~picky.valid), np.arange(40, 50))
    assert (picky.code[40:50] == LineCode.TOO_WIDE).all()


def test_a_line_cut_by_a_depth_edge_is_not_fitted():
    from addon.core.optics.detect import DetectParams

    img = line_image(160, np.full(60, 70.2), 0.55, background=0.0, integrate=False)
    img[71:, :30, 0] = 0.0  # the part ends just past the peak in the first 30 columns
    line = detect_line(img, "gauss", DetectParams(saturation=np.inf, smoothing_px=0.0))
    assert (line.code[:30] == LineCode.EDGE).all() and line.valid[30:].all()
    assert np.abs(line.row[30:] - 70.2).max() < 1e-6  # the whole Gaussian is still exact


def test_auto_smoothing_leaves_narrow_gaussian_lines_alone_and_smooths_wide_noisy_ones():
    rng = np.random.default_rng(3)
    centres = 80 + rng.uniform(-0.5, 0.5, 400)
    # A point-sampled line of σ 0.5 px (a 1-spp render): smoothing could only bias it.
    narrow = line_image(160, centres, 0.5, peak=0.6, background=0.0, integrate=False)
    auto, none = detect_line(narrow, "gauss"), detect_line(narrow, "gauss", DetectParams(smoothing_px=0.0))
    np.testing.assert_array_equal(auto.row, none.row)
    assert np.nanmax(np.abs(auto.row - centres)) < 0.005
    # A line of σ 1.5 px at 2 % noise: the matched smoothing halves the error.
    errors = {}
    for name, params in (("auto", None), ("none", DetectParams(smoothing_px=0.0))):
        img = line_image(160, centres, 1.5, peak=0.6, background=0.0, noise=0.02, rng=np.random.default_rng(4))
        line = detect_line(img, "gauss", params)
        errors[name] = np.sqrt(np.mean((line.row - centres)[line.valid] ** 2))
    assert errors["auto"] < 0.7 * errors["none"], errors


def test_a_flat_topped_line_is_always_smoothed():
    # The slit laser's line at 1 px: one row lit, a quarter of the next (a hard edge
    # inside the pixel), dark around. As narrow as that it would be read unsmoothed.
    H, W = 60, 50
    img = np.zeros((H, W), np.float32)
    img[30, :] = 0.6
    img[31, :] = 0.15
    plain = detect_line(img, "gauss")
    flat = detect_line(img, "gauss", DetectParams(flat_top=True))
    assert not plain.valid.any()  # unsmoothed, a neighbour row is dark: the fit has no flank
    assert flat.valid.all()
    np.testing.assert_allclose(flat.row, 30.2, atol=0.15)  # near the lit run's centre of mass


def test_a_line_cut_across_its_width_is_rejected_and_a_whole_one_states_a_small_sigma():
    # A point-sampled Gaussian line; in 20 columns an edge of the part dims everything from
    # 0.6 σ beside the centre on to a seventh (the strip's far side lies on a surface
    # turned away, still lit: no row is dark, so only the profile's shape tells).
    sigma = 0.8
    centre = smooth_line(seed=3)
    img = line_image(H, centre, sigma, integrate=False, background=0.0)
    rows = np.arange(H)[:, None]
    cut = np.zeros(W, bool)
    cut[60:80] = True
    img[(rows > centre[None, :] + 0.6 * sigma) & cut[None, :]] *= 1.0 / 7.0
    params = DetectParams(min_width_ratio=0.8, smoothing_px=0.0)
    line = detect_line(img, "gauss", params)
    assert np.all(line.code[cut] == LineCode.EDGE), line.code[cut]
    whole = ~cut & line.valid
    assert whole.mean() > 0.85
    err = np.abs(line.row - centre)[whole]
    # The stated σ is small where the line is whole and covers its error there.
    assert np.median(line.sigma_px[whole]) < 0.02
    assert np.mean(err <= 2 * line.sigma_px[whole]) >= 0.9
    # Without the check, those columns are measured off the line's true centre.
    loose = detect_line(img, "gauss", DetectParams(min_width_ratio=None, smoothing_px=0.0))
    assert np.nanmax(np.abs(loose.row - centre)[cut]) > 0.1


def test_sigma_grows_with_the_image_noise():
    centre = smooth_line(seed=4)
    quiet = detect_line(line_image(H, centre, 1.0, integrate=False), "gauss", DetectParams(smoothing_px=0.0))
    noisy = detect_line(line_image(H, centre, 1.0, integrate=False, noise=0.03, rng=np.random.default_rng(2)),
                        "gauss", DetectParams(smoothing_px=0.0))
    assert np.nanmedian(noisy.sigma_px) > 3 * np.nanmedian(quiet.sigma_px)
    err = np.abs(noisy.row - centre)[noisy.valid]
    assert np.mean(err <= 2 * noisy.sigma_px[noisy.valid]) >= 0.9


def test_a_row_offset_that_is_not_a_whole_number_is_refused():
    img = line_image(H, smooth_line(), 1.0)
    for bad in (float("nan"), 2.5, "3", True):
        with pytest.raises(InputError, match="row_offset"):
            detect_line(img, row_offset=bad)
    assert np.nanmax(detect_line(img, row_offset=10.0).row) > 10


def bent_strip_image(curvature_px: np.ndarray, strip_sigma: float = 1.2, rows: int = 40) -> tuple[np.ndarray, float]:
    """Columns imaging a Gaussian strip (σ across the line, in its own units) through
    row = r0 + x + c·x², c per column: a strip on a surface that bends across the line. Each
    pixel integrates its row's share of the strip (fine sampling of x). Returns the image and
    r0, the row of the strip's centre line x = 0 (the laser plane), which the probe means."""
    r0 = rows / 2 + 0.3
    x = np.linspace(-6 * strip_sigma, 6 * strip_sigma, 24001)
    weight = np.exp(-0.5 * (x / strip_sigma) ** 2)
    img = np.zeros((rows, len(curvature_px)))
    for j, c in enumerate(curvature_px):
        r = r0 + x + c * x * x
        img[:, j] = np.bincount(np.clip(np.floor(r + 0.5).astype(int), 0, rows - 1), weights=weight, minlength=rows)
    return 0.8 * img / img.max(), r0  # below full scale: not saturated


def test_a_strip_bent_across_the_line_states_the_shift_its_asymmetry_shows():
    """The strip's mean moves by c·σ² (E[c x²] for x ~ N(0, σ²)) and its peak, which the
    detector fits, by up to 2cσ² (the density φ(x)/(1 + 2cx) peaks at x ≈ −2cσ²); the
    detector's stated σ grows with the bend and covers the detected centre's distance from
    the laser plane's row, while an unbent strip keeps a small σ."""
    strip_sigma = 1.2
    c = np.repeat([0.0, 0.02, 0.05, 0.1, 0.15], 8)  # the fold x = −1/2c stays beyond 2.7 σ
    img, r0 = bent_strip_image(c, strip_sigma)
    line = detect_line(img, "gauss", DetectParams(smoothing_px=0.0))
    assert line.valid.all()
    err = np.abs(line.row - r0)
    assert np.median(line.sigma_px[c == 0]) < 0.02 and err[c == 0].max() < 0.02
    for k in (0.05, 0.1, 0.15):
        at = c == k
        mean_shift = k * strip_sigma ** 2  # what the strip's curvature moves its mean by
        assert mean_shift < err[at].min() <= 2.0 * mean_shift  # the bend moves the fitted peak
        assert np.all(err[at] <= 2.0 * line.sigma_px[at]), (k, err[at], line.sigma_px[at])
        assert mean_shift <= np.median(line.sigma_px[at]) <= 4.0 * mean_shift
    assert np.all(np.diff([np.median(line.sigma_px[c == k]) for k in np.unique(c)]) > 0)


def test_a_line_widened_in_a_few_columns_keeps_a_small_sigma_and_one_cut_there_states_its_shift():
    """Three samples cannot tell a strip that is wider on both sides from one cut on one side;
    the light can. Where a crease turns the surface for three columns the strip's image is
    wider there and whole (its light grows with its width): its centre stays on the line and
    its σ stays small. Where an edge dims one side for three columns, light is lost: the
    centre moves and the stated σ covers it."""
    sigma = 0.7
    centre = smooth_line(seed=5)
    img = line_image(H, centre, sigma, background=0.0)
    wide = line_image(H, centre, 1.3 * sigma, background=0.0)
    spread = np.zeros(W, bool)
    spread[[50, 51, 52, 120, 121, 122]] = True
    img[:, spread] = wide[:, spread]
    cut = np.zeros(W, bool)
    cut[[80, 81, 82, 150, 151, 152]] = True
    rows = np.arange(H)[:, None]
    img[(rows > centre[None, :] + 0.3) & cut[None, :]] *= 0.2
    line = detect_line(img, "gauss", DetectParams(min_width_ratio=None, smoothing_px=0.0))
    assert line.valid[spread | cut].all()
    err = np.abs(line.row - centre)
    assert err[spread].max() < 0.02 and line.sigma_px[spread].max() < 0.03, (err[spread], line.sigma_px[spread])
    assert err[cut].min() > 0.05  # the cut moves the fitted centre
    assert np.all(err[cut] <= 2.0 * line.sigma_px[cut]), (err[cut], line.sigma_px[cut])


@pytest.mark.parametrize("sigma", [0.6, 1.0, 2.0])
def test_a_line_cut_on_one_side_at_any_depth_and_phase_states_a_sigma_that_covers_its_shift(sigma):
    # Each column's line is cut (dimmed to nothing) beyond its own depth, 0.1 to 3 line σ from
    # its centre, at its own sub-pixel phase; whole columns between them give the reference.
    rng = np.random.default_rng(7)
    centre = H / 2 + rng.uniform(-0.5, 0.5, W)
    img = line_image(H, centre, sigma, background=0.0)
    cut = np.zeros(W, bool)
    cut[5::10] = True
    depth = np.linspace(0.1, 3.0, cut.sum()) * sigma
    rows = np.arange(H)[:, None]
    hidden = (rows > centre[None, cut] + depth[None, :])
    img[:, cut] = np.where(hidden[..., None], 0.0, img[:, cut])
    line = detect_line(img, "gauss", DetectParams(min_width_ratio=None, smoothing_px=0.0))
    at = cut & line.valid
    assert at.sum() >= 0.4 * cut.sum()  # the shallowest cuts leave a neighbour dark: coded EDGE
    err = np.abs(line.row - centre)
    assert np.all(err[at] <= 2.0 * line.sigma_px[at]), (err[at], line.sigma_px[at])


@pytest.mark.parametrize("fwhm, accepted", [(10.0, True), (17.0, True), (24.0, True), (30.0, False)])
def test_lines_up_to_the_width_limit_are_measured_and_wider_ones_refused(fwhm, accepted):
    """max_width_px (25) is the limit: the half-level search looked only 8 rows from the peak,
    so a line over 16 px wide read infinitely wide and every column was refused as too wide
    (a probe with a 17-23 px line measured nothing, filed under 'no detection')."""
    from addon.core.optics.detect import DetectParams, LineCode, detect_line

    rows = np.arange(200.0)[:, None]
    rgb = np.zeros((200, 16, 3), np.float32)
    rgb[..., 0] = 0.8 * np.exp(-0.5 * ((rows - 100.3) / (fwhm / 2.355)) ** 2)
    found = detect_line(rgb, "gauss", DetectParams(smoothing_px=0.0))
    if accepted:
        assert (found.code == LineCode.OK).all()
        np.testing.assert_allclose(found.width, fwhm, rtol=0.01)
        np.testing.assert_allclose(found.row, 100.3, atol=0.02)
    else:
        assert (found.code == LineCode.TOO_WIDE).all()
