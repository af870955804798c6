"""Detection error against noise: rendered lines through the sensor model beside the synthetic images.

One rendered frame of a plane at mid-range (pixel area integration, 64 samples)
is put through the sensor with exposure, clipping and noise at several line
levels (auto-exposure to that fraction of full scale), many times with fresh
noise. The error is the detected centre's departure from the same detector on
the noise-free render (so only the noise's share is measured). Beside it: the
synthetic-image bench's setting (``bench detect``) with a Gaussian line of the
rendered line's width and additive noise equal to the noise the sensor put on
the line's peak pixels.
"""

from __future__ import annotations

import math

import numpy as np

LEVELS = (0.05, 0.1, 0.2, 0.4, 0.7)


def rendered_plane_line():
    """(image (H, W, 3), probe): camera 0's view of a plane 150 mm below the probe, area-sampled."""
    from addon.core.kinematics.cell import Cell
    from addon.core.kinematics.euler import pose_from_xyz_yzz
    from addon.core.config.rigs import load_robot
    from addon.core.config.rigs import load_probe
    from addon.core.kinematics.transforms import trans
    from addon.core.geometry.workpiece import builtin_workpiece
    from addon.scene.cell import build_cell
    from addon.core.config.render import RenderOptions
    from addon.scene.session import new_scene

    probe = load_probe("default")
    wp = builtin_workpiece("plane", pose=trans(0, 0, 20))
    sc = build_cell(new_scene(), Cell(load_robot("adept_viper_s650")), probe, wp)
    res = sc.cell.ik(pose_from_xyz_yzz([0, 0, 170], [math.pi / 2, math.pi, 0]),
                     np.radians([0, 40, -100, 0, -30, 0]), relative_to="table")
    frames = sc.keyframe(res.q[None])
    image = sc.render(frames.start, frames.start, RenderOptions(samples=64, pixel_filter="BOX",
                                                                 filter_width_px=1.0))[0][0]
    return image, probe


def compare(frames: int = 20, seed: int = 0) -> list[tuple]:
    """Rows (level, noise at the peak as a fraction of it, rendered error px, synthetic error px, σ px)."""
    from addon.core.optics.detect import DetectParams, detect_line
    from addon.core.optics.sensor import SensorModel
    from headless.synthetic import gaussian_profile, line_image
    from headless.bench.detect import curved_centres

    clean, probe = rendered_plane_line()
    ideal = DetectParams(saturation=np.inf)
    ref = detect_line(clean, "gauss", ideal)
    sigma = float(np.nanmedian(ref.width[ref.valid])) / 2.355
    cols = np.flatnonzero(ref.valid)
    peak_rows = np.argmax(clean[:, :, 0], axis=0)[cols]
    rng = np.random.default_rng(seed)
    # The synthetic line's amplitude that makes its brightest pixel (line centred on a
    # pixel) the level, as auto-exposure makes the rendered line's.
    centre_pixel = float(gaussian_profile(np.zeros(1), np.zeros(1), sigma, True)[0])
    out = []
    for level in LEVELS:
        sensor = SensorModel(saturate=True, noise=True, auto_exposure=True, target_peak=level, seed=seed)
        # Both detectors accept a line down to half the level: the threshold is not what is compared.
        rendered_params = DetectParams(saturation=1.0, min_peak=0.5 * level)
        synthetic_params = DetectParams(saturation=np.inf, min_peak=0.5 * level)
        errors, peaks, dark = [], [], []
        for k in range(frames):
            img = sensor.apply(clean, probe, 0, k)
            line = detect_line(img, "gauss", rendered_params)
            ok = line.valid[cols]
            errors.append(np.abs(line.row[cols] - ref.row[cols])[ok])
            peaks.append(img[peak_rows, cols, 0])
            dark.append(img[peak_rows, cols, 1])
        peaks, dark = np.array(peaks), np.array(dark)
        contrast = float(np.mean(peaks - dark))
        noise = float(np.median(peaks.std(axis=0))) / contrast
        synthetic = []
        for _ in range(frames):
            centres = curved_centres(probe.rows_px, probe.cols_px, rng)
            amplitude = level / centre_pixel
            syn = line_image(probe.rows_px, centres, sigma, peak=amplitude, background=0.0,
                             noise=noise * level / amplitude, rng=rng)  # the same absolute noise as at the peak
            line = detect_line(syn, "gauss", synthetic_params)
            synthetic.append(np.abs(line.row - centres)[line.valid])
        out.append((level, noise, float(np.concatenate(errors).mean()), float(np.concatenate(synthetic).mean()),
                    sigma))
    return out


def print_table(rows) -> None:
    print()
    print("Detection error from sensor noise (gauss), rendered plane through the sensor model vs synthetic images")
    print(f"(rendered line sigma {rows[0][4]:.2f} px; 12-bit, 10 000 e- full well, 5 e- read noise, 1 % PRNU)")
    hdr = f"{'line level':>11}{'noise at peak':>15}{'rendered px':>13}{'synthetic px':>14}{'ratio':>8}"
    print(hdr + "\n" + "-" * len(hdr))
    for level, noise, rendered, synthetic, _ in rows:
        print(f"{level * 100:>10.0f}%{noise * 100:>14.2f}%{rendered:>13.4f}{synthetic:>14.4f}"
              f"{rendered / synthetic:>8.2f}")


def to_markdown(rows, frames: int) -> str:
    lines = [f"Measured with `python -m headless bench realism --only noise --noise-frames {frames}` "
             f"(rendered line σ = {rows[0][4]:.2f} px):", "",
             "| line level | noise at the peak | rendered + sensor (gauss) | synthetic, same noise | ratio |",
             "|---|---|---|---|---|"]
    for level, noise, rendered, synthetic, _ in rows:
        lines.append(f"| {level * 100:.0f} % | {noise * 100:.2f} % | {rendered:.4f} px | {synthetic:.4f} px | "
                     f"{rendered / synthetic:.2f} |")
    return "\n".join(lines) + "\n"
