"""One frame's images to one profile: detection per camera (in full-sensor rows when a band
was rendered), lens distortion removed where the probe is calibrated, triangulation, the
profile filter, and the two cameras fused; and the per-scan counters of what was seen."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..config.scan import ScanConfig
from ..optics.detect import detect_line
from ..optics.profile_filter import drop_uncertain, filter_profile
from ..optics.triangulate import Profile, fuse_profiles, merged_counts, triangulate_profile


def new_stats() -> dict:
    """Per-scan counters: sensor columns seen and kept, frames re-rendered at full height,
    rows rendered per frame, columns per detection code, and points dropped after
    detection by reason (``points``: the triangulation's and the profile filter's counts)."""
    return dict(columns=0, valid=0, rerendered=0, band_rows=[], codes={}, points={})


def add_counts(into: dict, counts: dict) -> None:
    """``counts`` added into ``into`` (triangulate.merged_counts, in place)."""
    into.update(merged_counts(into, counts))


def merge_stats(parts: list[dict]) -> dict:
    """The counters of several parts of one scan (shards), added up."""
    out = new_stats()
    for st in parts:
        out["columns"] += int(st["columns"])
        out["valid"] += int(st["valid"])
        out["rerendered"] += int(st["rerendered"])
        out["band_rows"] += [int(v) for v in st["band_rows"]]
        add_counts(out["codes"], st["codes"])
        add_counts(out["points"], st.get("points", {}))  # (shards written before this counter have none)
    return out


def detect_all(images, rows, config: ScanConfig):
    """Detections for each camera's image (None where the camera was not rendered), rows in full-image terms."""
    out = []
    for img in images:
        if img is None:
            out.append(None)
            continue
        line = detect_line(img, config.detect_method, config.detect_params, 0 if rows is None else rows[0])
        if rows is not None:  # the image holds rows r0..r1−1 of the sensor; its rows are the sensor's
            line.shape = (config.probe.rows_px, config.probe.cols_px)
            # (A peak on the band's first or last row is coded EDGE; the caller re-renders
            # such frames at full height: see band.needs_full_frame.)
        out.append(line)
    return out


def frame_profile(probe, lines, config: ScanConfig):
    sensor = config.sensor
    if probe.calibration is not None and sensor.undistort:  # the calibration's lens model, whatever the truth is
        lines = [None if ln is None else _undistorted(ln, probe.measuring_camera(cam).undistort)
                 for cam, ln in enumerate(lines)]
    elif sensor.distortion and sensor.undistort:  # a perfectly calibrated probe removes its lens distortion
        lines = [None if ln is None else _undistorted(ln, lambda u, v: sensor.undistort_pixels(probe, u, v))
                 for ln in lines]
    profs = [filter_profile(triangulate_profile(probe, ln, cam, config.triangulate_method), config.profile_filter)
             for cam, ln in enumerate(lines) if ln is not None]
    if len(profs) == 2 and config.fuse:
        return drop_uncertain(fuse_profiles(*profs), config.profile_filter)
    if len(profs) == 2:  # both cameras' points side by side, and both cameras' dropped columns counted
        return drop_uncertain(Profile.joined(*profs), config.profile_filter)
    return drop_uncertain(profs[0], config.profile_filter)


def _undistorted(line, undistort):
    """A detection with its valid positions moved by ``undistort(u, v) -> (u, v)`` to where
    the camera's ideal pinhole sees them."""
    ok = line.valid
    u, v = line.col.astype(np.float64), line.row.astype(np.float64)
    u[ok], v[ok] = undistort(u[ok], v[ok])
    return replace(line, col=u, row=v)
