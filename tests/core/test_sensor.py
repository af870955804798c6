"""The realistic sensor, effect by effect: each test fails if its effect is not applied."""

import math

import cv2
import numpy as np
import pytest

from addon.core.optics.detect import DetectParams, detect_line
from addon.core.errors import InputError
from addon.core.config.rigs import load_probe
from addon.core.optics.sensor import SensorModel, speckle_pattern
from headless.synthetic import line_image

PROBE = load_probe("default")


def flat(level, rows=160, cols=160):
    return np.full((rows, cols, 3), level, np.float32)


def test_the_default_sensor_is_ideal_and_changes_nothing():
    s = SensorModel()
    assert s.ideal
    img = line_image(160, np.full(160, 70.3), 1.2)
    np.testing.assert_array_equal(s.apply(img, PROBE, 0, 0), img)


def test_noise_has_the_predicted_spread():
    s = SensorModel(noise=True, saturate=True)
    level = 0.3
    out = s.apply(flat(level), PROBE, camera=0, frame=3)
    e = level * s.electrons_per_unit * s.exposure_ms
    sigma_e = math.sqrt(e + s.read_noise_e ** 2 + (s.prnu * e) ** 2)  # shot, read, fixed pattern
    dn_per_unit = (2 ** s.bit_depth - 1)
    expected = sigma_e * s.gain * (2 ** s.bit_depth - 1) / s.full_well_e / dn_per_unit
    assert np.std(out) == pytest.approx(expected, rel=0.05)
    mean_expected = (e * s.gain * (2 ** s.bit_depth - 1) / s.full_well_e + s.dark_offset_dn) / dn_per_unit
    assert np.mean(out) == pytest.approx(mean_expected, rel=0.01)
    assert np.std(SensorModel(saturate=True).apply(flat(level), PROBE, 0, 3)) < 1e-6  # noise off: none


def test_fixed_pattern_stays_put_and_frames_differ():
    s = SensorModel(noise=True, saturate=True)
    a, b = s.apply(flat(0.3), PROBE, 0, 1), s.apply(flat(0.3), PROBE, 0, 1)
    np.testing.assert_array_equal(a, b)  # seeded: reproducible
    c = s.apply(flat(0.3), PROBE, 0, 2)
    assert not np.array_equal(a, c)
    # The fixed pattern correlates between frames, the temporal noise does not.
    s2 = SensorModel(noise=True, saturate=True, prnu=0.2, read_noise_e=0.0)
    f1, f2 = s2.apply(flat(0.5), PROBE, 0, 1)[..., 0], s2.apply(flat(0.5), PROBE, 0, 2)[..., 0]
    assert np.corrcoef(f1.ravel(), f2.ravel())[0, 1] > 0.9


def test_saturation_clips_and_quantises():
    s = SensorModel(saturate=True, bit_depth=10)
    out = s.apply(flat(2.0), PROBE, 0, 0)
    assert out.max() == 1.0
    q = SensorModel(saturate=True, bit_depth=8).apply(flat(0.1234), PROBE, 0, 0)
    steps = q * 255
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-4)
    # A clipped line is flagged by the detector.
    img = line_image(160, np.full(160, 70.0), 1.5, peak=0.6)
    bright = SensorModel(saturate=True, exposure_ms=5.0).apply(img, PROBE, 0, 0)
    assert np.all(detect_line(bright, "gauss", DetectParams(saturation=1.0)).code == 2)


@pytest.mark.parametrize("gain, noise", [(0.5, False), (0.5, True), (0.8, True), (1.0, True)])
def test_a_line_clipped_at_the_full_well_is_flagged_whatever_the_gain(gain, noise):
    """Below gain 1 the full well clips before the ADC's top: the detector is told that level
    by the config (it was told 1.0, and a line clipped at half scale passed as good)."""
    from addon.core.config.scan import load_scan_config

    sensor = SensorModel(saturate=True, noise=noise, gain=gain, exposure_ms=5.0)
    cfg = load_scan_config("demo").with_realism(sensor)
    img = line_image(160, np.full(160, 70.0), 1.5, peak=0.6)
    out = sensor.apply(img, PROBE, 0, 0)
    assert out.max() == pytest.approx(cfg.detect.saturation, abs=1e-6)  # what a clipped pixel reads
    line = detect_line(out, "gauss", cfg.detect)
    assert np.mean(line.code == 2) > 0.95, line.counts()
    # a line under the clip stays good
    dim = sensor.apply(line_image(160, np.full(160, 70.0), 1.5, peak=0.02), PROBE, 0, 0)
    assert np.mean(detect_line(dim, "gauss", cfg.detect).code == 2) == 0.0


def test_auto_exposure_puts_the_peak_at_the_target():
    s = SensorModel(saturate=True, auto_exposure=True, target_peak=0.7)
    img = line_image(160, np.full(160, 70.0), 1.5, peak=0.05, background=0.0, integrate=False)
    out = s.apply(img, PROBE, 0, 0)  # metered from the frame itself
    assert out[..., 0].max() == pytest.approx(0.7, abs=2e-3)
    # Under speckle the meter aims at the 95th percentile of the column peaks: about
    # one column in twenty reaches the target (hot spots go above it; few clip).
    speckled = SensorModel(saturate=True, auto_exposure=True, target_peak=0.7, speckle=True)
    out = speckled.apply(img, PROBE, 0, 0)
    peaks = out[..., 0].max(axis=0)
    assert np.mean(peaks >= 0.7 - 2e-3) == pytest.approx(0.05, abs=0.03)
    assert np.mean(peaks >= 1.0) < 0.05


def autocorrelation_half_width(pattern):
    p = pattern - pattern.mean()
    ac = np.real(np.fft.ifft2(np.abs(np.fft.fft2(p)) ** 2))[0]
    ac /= ac[0]
    k = int(np.argmax(ac < 0.5))
    return k - 1 + (ac[k - 1] - 0.5) / (ac[k - 1] - ac[k])  # interpolated


def test_speckle_grain_follows_the_optics():
    rng = np.random.default_rng(0)
    w8 = autocorrelation_half_width(speckle_pattern(256, 256, 8.0, rng, oversample=1))
    w16 = autocorrelation_half_width(speckle_pattern(256, 256, 16.0, rng, oversample=1))
    # Airy² correlation: half maximum at 0.211 grain.
    assert w8 == pytest.approx(0.211 * 8, rel=0.15) and w16 / w8 == pytest.approx(2.0, rel=0.15)
    s = SensorModel(speckle=True)
    f = s.focal_mm(PROBE)
    pitch_mm = 6.4 / PROBE.cols_px  # the default chip, 6.4 mm wide, shared by the columns
    for z in (70.0, 250.0):
        expected = 2.44 * 650e-6 * (1 + f / (z - f)) * s.f_number / pitch_mm
        assert s.speckle_grain_px(PROBE, z) == pytest.approx(expected)
    assert s.speckle_grain_px(PROBE, 70.0) > s.speckle_grain_px(PROBE, 250.0)  # larger M up close
    assert SensorModel(speckle=True, f_number=2 * s.f_number).speckle_grain_px(PROBE, 150.0) == pytest.approx(
        2 * s.speckle_grain_px(PROBE, 150.0))


def test_grains_smaller_than_a_pixel_average_out_as_goodman_predicts():
    rng = np.random.default_rng(3)
    for grain in (0.2, 0.5):
        p = speckle_pattern(200, 200, grain, rng)
        M = 1 + 1 / ((4 / np.pi) * (grain / 2.44) ** 2)  # degrees of freedom: pixel / correlation area
        assert p.mean() == pytest.approx(1.0, abs=0.01)
        assert p.std() == pytest.approx(1 / np.sqrt(M), rel=0.05)
    # Where the resolved model takes over, the two agree within 15 %.
    resolved = speckle_pattern(200, 200, 0.7, rng, oversample=16).std()
    integrated = speckle_pattern(200, 200, 0.7, rng, oversample=1).std()
    assert integrated == pytest.approx(resolved, rel=0.15)


def test_the_lens_is_the_same_at_every_resolution():
    s = SensorModel()
    assert s.pitch_um(PROBE) == pytest.approx(6400 / PROBE.cols_px)
    wide = PROBE.with_resolution(PROBE.rows_px * 8, PROBE.cols_px * 8)
    assert s.focal_mm(wide) == pytest.approx(s.focal_mm(PROBE))  # 8× the pixels, 1/8 the pitch
    assert SensorModel(pixel_pitch_um=5.0).pitch_um(PROBE) == 5.0
    # The default focus balances the blur at the two ends of the range.
    ends = s.row_depths_mm(PROBE, np.array([0.0, PROBE.rows_px - 1.0]))
    near, far = s.blur_sigma_px(PROBE, ends)
    assert near == pytest.approx(far, rel=0.05) and near > 0.5
    with pytest.raises(InputError, match="focal length"):
        SensorModel(focus_mm=5.0).blur_sigma_px(PROBE, 100.0)


def test_speckle_modulates_the_line_and_moves_its_centre():
    centre = np.full(160, 70.3)
    img = line_image(160, centre, 1.2, background=0.1)
    out = SensorModel(speckle=True).apply(img, PROBE, 0, 5)
    ideal = detect_line(img, "gauss", DetectParams(saturation=np.inf))
    noisy = detect_line(out, "gauss", DetectParams(saturation=np.inf))
    err = np.abs(noisy.row - centre)[noisy.valid]
    assert err.mean() > 5 * np.abs(ideal.row - centre)[ideal.valid].mean() + 0.01
    np.testing.assert_allclose(out[..., 1], img[..., 1])  # the ambient (green, blue) is untouched


def test_defocus_blurs_by_the_thin_lens_circle():
    s = SensorModel(defocus=True, f_number=1.4, focus_mm=90.0)
    f = s.focal_mm(PROBE)
    z = 200.0
    c = (f / 1.4) * f * abs(z - 90.0) / (z * (90.0 - f)) / (6.4 / PROBE.cols_px) / 2.355
    assert s.blur_sigma_px(PROBE, z) == pytest.approx(c)
    # A line at the far end of the range widens; one in focus does not.
    depths = s.row_depths_mm(PROBE, np.arange(160.0))
    far_row = int(np.argmin(np.abs(depths - 230)))
    near_row = int(np.argmin(np.abs(depths - 90)))
    for row, wider in ((far_row, True), (near_row, False)):
        img = line_image(160, np.full(160, float(row)), 1.0, background=0.0)
        w0 = np.median(detect_line(img, "gauss").width)
        w1 = np.median(detect_line(s.apply(img, PROBE, 0, 0), "gauss").width)
        assert (w1 > w0 * 1.2) == wider, (row, w0, w1)


def test_defocus_spreads_each_rows_light_by_its_own_depth_so_a_line_stays_centred():
    """Where the blur changes fast across the sensor (f/1: σ from 0 to 7 px), a straight line
    keeps its centre and its light: each row's light spreads with the blur of the depth that
    row sees. Blurring each row by its own depth instead moved a line by up to 0.3 px."""
    s = SensorModel(defocus=True, f_number=1.0)
    sigma = s.blur_sigma_px(PROBE, s.row_depths_mm(PROBE, np.arange(160.0)))
    assert sigma.max() > 5.0 and np.max(np.abs(np.diff(sigma))) > 0.05  # a steep change across the sensor
    for row in (20.3, 40.7, 100.4, 130.6):
        img = line_image(160, np.full(160, row), 0.55, background=0.0)
        out = s.apply(img, PROBE, 0, 0)
        found = detect_line(out, "gauss", DetectParams(saturation=np.inf))
        assert found.valid.all() and abs(np.median(found.row) - row) < 0.03, (row, np.median(found.row))
        assert out[..., 0].sum() == pytest.approx(img[..., 0].sum(), rel=1e-3)  # no light made or lost
    # A band of rows rendered around the line gets the rows the blur spreads it over.
    assert s.spread_px(PROBE) == math.ceil(3 * sigma.max()) and SensorModel().spread_px(PROBE) == 0


def test_distortion_moves_points_as_opencv_predicts_and_calibration_undoes_it():
    s = SensorModel(distortion=(-0.8, 0.3, 0.002, -0.004))  # strong: the field of view is narrow
    K, d = PROBE.K, s.dist_coeffs()
    u0, v0 = 140.0, 25.0  # far off-centre: a large shift
    yy, xx = np.mgrid[0:160, 0:160].astype(np.float64)
    spot = np.exp(-((xx - u0) ** 2 + (yy - v0) ** 2) / (2 * 1.2 ** 2))  # centred exactly at (u0, v0)
    img = np.repeat(spot[..., None], 3, axis=2).astype(np.float32)
    out = s.apply(img, PROBE, 0, 0)
    m = cv2.moments(out[..., 0])
    found = np.array([m["m10"] / m["m00"], m["m01"] / m["m00"]])
    # Where a distorting lens puts the undistorted point:
    ray = np.linalg.solve(K, [u0, v0, 1.0])
    expected, _ = cv2.projectPoints(ray.reshape(1, 1, 3), np.zeros(3), np.zeros(3), K, d)
    expected = expected.ravel()
    assert np.linalg.norm(expected - [u0, v0]) > 2.0  # the effect is visible
    assert np.linalg.norm(found - expected) < 0.15
    back_u, back_v = s.undistort_pixels(PROBE, np.array([found[0]]), np.array([found[1]]))
    assert abs(back_u[0] - u0) < 0.15 and abs(back_v[0] - v0) < 0.15


@pytest.mark.parametrize("coeffs", [(-0.5, 0.0, 0.0, 0.0), (0.3, -0.2, 0.004, -0.003), (-0.8, 0.3, 0.002, -0.004)])
def test_the_band_spread_covers_how_far_distortion_moves_a_point_along_its_column(coeffs):
    """A band of rows rendered around where the pinhole puts the line must reach where the lens
    puts it: the spread is at least the column shift of every sensor pixel's ideal point, found
    here the other way round (OpenCV's forward projection of the ideal pixels' rays)."""
    s = SensorModel(distortion=coeffs)
    K, d = PROBE.K, s.dist_coeffs()
    v, u = np.mgrid[0:PROBE.rows_px:3, 0:PROBE.cols_px:3].astype(np.float64)
    rays = np.linalg.solve(K, np.stack([u.ravel(), v.ravel(), np.ones(u.size)]))
    seen, _ = cv2.projectPoints(rays.T.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, d)
    seen = seen.reshape(-1, 2)
    on_sensor = (seen[:, 0] >= 0) & (seen[:, 0] <= PROBE.cols_px - 1) & (seen[:, 1] >= 0) & (seen[:, 1] <= PROBE.rows_px - 1)
    shift = np.abs(seen[on_sensor, 1] - v.ravel()[on_sensor]).max()
    assert shift > 1.0  # the effect is there
    assert shift <= s.spread_px(PROBE) <= shift + 2.0
    assert SensorModel().spread_px(PROBE) == 0


def test_band_renders_get_the_same_noise_as_full_frames():
    s = SensorModel(noise=True, saturate=True, speckle=True)
    img = line_image(160, np.full(160, 80.2), 1.2)
    full = s.apply(img, PROBE, 1, 7)
    band = s.apply(img[60:100], PROBE, 1, 7, row0=60)
    np.testing.assert_allclose(band, full[60:100], atol=1e-6)


@pytest.mark.parametrize("kwargs,fragment", [
    (dict(bit_depth=7), "bit_depth"), (dict(exposure_ms=0.0), "exposure_ms"), (dict(prnu=-1.0), "prnu"),
    (dict(distortion=(0.1,)), "distortion"), (dict(motion_blur=True, exposure_ms=20.0), "longer than 0.98 of a frame"),
    # 0.99 of a frame: Blender's shutter would be cut to the cell's motion keys (0.98), not refused
    (dict(motion_blur=True, exposure_ms=9.9), "at most 0.98 of a frame \\(9.8 ms"),
    (dict(target_peak=1.5), "target_peak")])
def test_bad_sensor_settings(kwargs, fragment):
    with pytest.raises(InputError, match=fragment):
        SensorModel(**kwargs)


def test_the_longest_shutter_motion_blur_takes_is_the_one_the_scene_keys():
    from addon.core.config.render import RenderOptions, with_sensor

    s = SensorModel(motion_blur=True, exposure_ms=9.8)  # 0.98 of a frame at 100 Hz
    assert with_sensor(RenderOptions(), s).motion_blur_shutter == pytest.approx(0.98)
    with pytest.raises(InputError, match="motion blur shutter"):
        RenderOptions(motion_blur_shutter=0.99)


def test_a_copy_with_another_seed_or_spread_has_its_own_fixed_pattern():
    """dataclasses.replace() hands the copy the original's cache: a copy with prnu 0 kept the
    5 % pattern, and one with another seed the same pattern."""
    from dataclasses import replace

    probe = load_probe("default")
    s = SensorModel(noise=True, saturate=True, prnu=0.05, seed=1)
    first = s._prnu_map(probe, 0)
    assert np.std(first) == pytest.approx(0.05, rel=0.05)
    assert np.all(replace(s, prnu=0.0)._prnu_map(probe, 0) == 1.0)
    other = replace(s, seed=2)._prnu_map(probe, 0)
    assert not np.allclose(other, first)
    np.testing.assert_array_equal(other, SensorModel(noise=True, saturate=True, prnu=0.05, seed=2)._prnu_map(probe, 0))


def test_auto_exposure_under_motion_blur_never_outlasts_a_frame():
    """A dark part at 200 Hz took 7.3 ms, 1.46 frames, where exposure_ms = 7.3 is refused."""
    from addon.core.optics.sensor import MAX_SHUTTER_FRAMES

    s = SensorModel(saturate=True, auto_exposure=True, motion_blur=True, frame_rate_hz=200.0)
    dim = 1e-6  # a line so faint that the target needs a long exposure
    assert SensorModel(saturate=True, auto_exposure=True).exposure_for(dim) > 1000.0 / 200.0
    assert s.exposure_for(dim) == pytest.approx(MAX_SHUTTER_FRAMES * 1000.0 / 200.0)
