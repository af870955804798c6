"""``python -m headless realism-figure``: the same probe frame seen by the ideal and the realistic sensor.

Two scans of a few frames around the chosen one run side by side: the ideal
sensor of the paper, and the realistic one with every effect of the realism
bench switched on (pixel integration, auto-exposure and clipping, noise,
speckle, defocus, calibrated distortion, motion blur; glossy part with two
bounces; ambient light). The picture shows the chosen frame's camera image for
each (pixels enlarged, display gamma 2.2), the detected line drawn over it
(green: accepted columns; a red tick above: rejected), and the error of those
frames' points against the exact shape.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

ZOOM = 4
MARGIN = 56
CROP_PX = 24  # rows shown above and below the detected line


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config", default="step_block", help="scan config (default step_block)")
    parser.add_argument("--frame", type=int, default=12, help="frame of the path to show (default 12: the laser on "
                                                              "both treads, clear of the block's edges)")
    parser.add_argument("--camera", type=int, default=0, choices=(0, 1))
    parser.add_argument("--out", default="out/realism_frame.png", help="PNG to write")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from addon.core.errors import InputError
    from addon.core.files import check_output_file, write_png
    from addon.core.config.scan import load_scan_config
    from headless.bench.realism import ALL, ALL_SCENE, configure, ideal

    check_output_file(args.out, "--out")  # before the two scans, not after

    base = load_scan_config(args.config)
    n = len(base.waypoints)
    if not 0 <= args.frame < n:
        raise InputError(f"--frame must be in [0, {n - 1}] for {args.config}, got {args.frame}")
    first = max(0, args.frame - 1)  # neighbours too: motion blur needs the path around the frame
    base = base.with_overrides(frames=slice(first, min(n, args.frame + 2)))
    # Every frame rendered whole, by both cameras: the chosen camera may see no line there.
    base = ideal(replace(base, leave_out=replace(base.leave_out, render_band=False, skip_blind_cameras=False)))
    shots = []
    for title, cfg in (("Ideal sensor", base), ("Realistic sensor", configure(base, ALL, ALL_SCENE))):
        img, line, report = _frame(cfg, args.frame - first, args.camera)
        e = report["error_um"]
        codes = ", ".join(f"{n} {name.lower().replace('_', ' ')}" for name, n in line.counts().items()
                          if name != "OK")
        error = (f"RMS {e['rms_um']:.0f} um, p95 {e['p95_um']:.0f} um" if report["points_on_part"]
                 else "no point on the part")
        caption = (f"{title}: frames {first}-{first + report['frames'] - 1}: {error}. This view: {int(line.valid.sum())} of {len(line.col)} columns "
                   f"accepted" + (f" (rejected: {codes})" if codes else ""))
        shots.append((img, line, caption))
        print(caption, flush=True)
    rows = np.concatenate([ln.row[ln.valid] for _, ln, _ in shots])
    H = shots[0][0].shape[0]
    top = int(max(0, np.floor(rows.min()) - CROP_PX)) if rows.size else 0
    bottom = int(min(H, np.ceil(rows.max()) + CROP_PX)) if rows.size else H
    panels = [_panel(img, line, caption, top, bottom) for img, line, caption in shots]
    gap = np.full((panels[0].shape[0], 16, 3), 255, np.uint8)
    picture = np.hstack([panels[0], gap, panels[1]])
    path = write_png(Path(args.out), picture)
    print(f"wrote {path}")
    return 0


def _frame(cfg, index: int, camera: int):
    from addon.core.scan.frames import detect_all as _detect_all
    from addon.pipeline import ScanRun

    run = ScanRun(cfg, keep_images=True)
    while not run.step():
        pass
    report = run.finish(None).report
    img = run.images[index][camera]
    line = _detect_all(run.images[index], None, cfg)[camera]
    return img, line, report


def _panel(img: np.ndarray, line, caption: str, top: int, bottom: int) -> np.ndarray:
    """Rows top..bottom of the camera image enlarged ZOOM times, the detection over it and
    the caption above (BGR uint8)."""
    shown = np.clip(img[top:bottom], 0.0, 1.0) ** (1 / 2.2)
    bgr = (shown[:, :, ::-1] * 255 + 0.5).astype(np.uint8)
    H, W = bgr.shape[:2]
    big = cv2.resize(bgr, (W * ZOOM, H * ZOOM), interpolation=cv2.INTER_NEAREST)
    ok = line.valid
    pts = np.stack([(line.col + 0.5) * ZOOM, (line.row - top + 0.5) * ZOOM], axis=1)
    # Draw runs of accepted columns; a jump of more than 2 rows (a step edge) starts a new run.
    breaks = (np.diff(ok.astype(np.int8)) != 0) | ~(np.abs(np.diff(np.nan_to_num(line.row))) <= 2)
    for run in np.split(np.arange(W), np.flatnonzero(breaks) + 1):
        if ok[run[0]] and len(run) > 1:
            cv2.polylines(big, [np.round(pts[run]).astype(np.int32)], False, (60, 220, 60), 1, cv2.LINE_AA)
    out = np.full((H * ZOOM + MARGIN, W * ZOOM, 3), 255, np.uint8)
    out[MARGIN:] = big
    for c in np.flatnonzero(~ok):
        x = int((c + 0.5) * ZOOM)
        cv2.line(out, (x, MARGIN - 10), (x, MARGIN - 2), (40, 40, 220), 1)
    words, lines, cur = caption.split(), [], ""
    for w in words:  # two lines of caption
        if cv2.getTextSize(f"{cur} {w}", cv2.FONT_HERSHEY_SIMPLEX, 0.45, 1)[0][0] > W * ZOOM - 8 and cur:
            lines.append(cur)
            cur = w
        else:
            cur = f"{cur} {w}".strip()
    for k, text in enumerate(lines + [cur]):
        cv2.putText(out, text, (4, 16 + 17 * k), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (20, 20, 20), 1, cv2.LINE_AA)
    return out
