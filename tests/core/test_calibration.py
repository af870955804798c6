"""Probe calibration (core): the calibrated probe model, its file, the ChArUco board, and the
solve on synthetic views whose truth is known from geometry.

Synthetic views: the board's corners are projected through the true probe (its cameras at
the true poses) from probe poses the robot would take; the laser line is where the true
laser plane X = 0 meets the plate, projected the same way. Gaussian noise of σ px on every
pixel. The solve's stated 1-σ (the bundle adjustment's covariance) is the bound: every
recovered parameter must lie within 4.5 σ of the truth.
"""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest

from addon.core.calibration import (BoardView, ChArUcoBoard, board2table, board_for, board_views, calibrate_probe,
                                    deviations, flat_views, triangulation_error)
from addon.core.config.rigs import load_probe, probe_toml
from addon.core.errors import CalibrationError, ConfigError, InputError
from addon.core.kinematics.transforms import rigid_inverse, rot_y, trans
from addon.core.optics.calibrated import CameraModel, ProbeCalibration
from addon.core.optics.detect import LineDetection
from addon.core.optics.triangulate import triangulate_profile

PROBE = load_probe("default")


def synthetic_views(probe, board, poses, sigma_px=0.05, seed=1, line=True):
    rng = np.random.default_rng(seed)
    B2T = board2table(board)
    obj = board.corners_mm
    views = []
    for P in poses:
        ids, corners, lines = [], [], []
        plate2probe = rigid_inverse(P) @ B2T
        for c in (0, 1):
            uv = probe.project(obj @ plate2probe[:3, :3].T + plate2probe[:3, 3], c)
            inside = np.isfinite(uv).all(axis=1)
            inside[inside] &= ((uv[inside] > 2).all(axis=1) & (uv[inside, 0] < probe.cols_px - 3)
                               & (uv[inside, 1] < probe.rows_px - 3))
            ids.append(np.nonzero(inside)[0])
            corners.append(uv[inside] + rng.normal(0.0, sigma_px, (int(inside.sum()), 2)))
            if line:
                n, p0 = plate2probe[:3, 2], plate2probe[:3, 3]
                y = np.linspace(-30.0, 30.0, 300)
                z = (n @ p0 - n[1] * y) / n[2]
                on = probe.project(np.column_stack([np.zeros_like(y), y, z]), c)
                ok = np.isfinite(on).all(axis=1)
                lines.append(on[ok] + rng.normal(0.0, sigma_px, (int(ok.sum()), 2)))
            else:
                lines.append(None)
        views.append(BoardView(P @ rigid_inverse(probe.mount), ids, corners, lines))
    return views


def given_rows(rows):
    """A detection with the line at ``rows`` (W,) in every column of the default probe."""
    W = PROBE.cols_px
    return LineDetection(np.arange(W), np.asarray(rows, float), np.ones(W), np.ones(W), np.zeros(W, np.uint8),
                         "given", (PROBE.rows_px, W))


# -- the calibrated probe model ------------------------------------------------------------------
def test_a_perfect_calibration_triangulates_as_the_truth():
    rng = np.random.default_rng(3)
    perfect = replace(PROBE, calibration=ProbeCalibration.of(PROBE))
    for cam in (0, 1):
        rows = rng.uniform(5, PROBE.rows_px - 6, PROBE.cols_px)
        line = given_rows(rows)
        a = triangulate_profile(PROBE, line, cam)
        b = triangulate_profile(perfect, line, cam)
        assert len(a) == len(b) > 100
        assert np.abs(a.points - b.points).max() < 1e-9
        assert np.abs(a.sigma_mm - b.sigma_mm).max() < 1e-9


def test_a_calibrated_plane_and_camera_put_points_on_their_rays_and_plane():
    """Points from a calibrated probe lie on the calibrated plane and on the calibrated camera's
    pixel rays (geometry, computed here independently)."""
    n = np.array([1.0, 0.02, -0.01])
    n /= np.linalg.norm(n)
    cam = CameraModel(np.array([[330.0, 0, 81.0], [0, 334.0, 78.0], [0, 0, 1]]), np.zeros(5),
                      trans(0.5, -0.3, 0.2) @ rot_y(0.01) @ PROBE.cam2probe(0))
    cal = ProbeCalibration((cam, ProbeCalibration.of(PROBE).cameras[1]), n, 0.4)
    probe = replace(PROBE, calibration=cal)
    rows = np.full(PROBE.cols_px, 80.0, np.float32)
    line = given_rows(rows)
    P = triangulate_profile(probe, line, 0).points
    assert len(P) > 100
    assert np.abs(P @ n - 0.4).max() < 1e-9
    # back into the camera: each point images at its pixel through K
    T = rigid_inverse(cam.cam2probe)
    Pc = P @ T[:3, :3].T + T[:3, 3]
    uv = Pc[:, :2] / Pc[:, 2:] * [330.0, 334.0] + [81.0, 78.0]
    assert np.abs(uv[:, 1] - 80.0).max() < 1e-9


def test_calibrated_probe_file_round_trip(tmp_path):
    n = np.array([0.999, 0.03, 0.01])
    cams = tuple(CameraModel(np.array([[331.0 + c, 0, 79.9], [0, 332.5, 80.1], [0, 0, 1]]),
                             [0.01, -0.002, 1e-4, -2e-4, 0.0], trans(0.2, 0.1, -0.3) @ PROBE.cam2probe(c))
                 for c in (0, 1))
    # Names as users give them: quotes, a backslash, a tab, a control character, an emoji
    # (JSON's escaping wrote it as two surrogates, which no TOML reader takes).
    probe = replace(PROBE, name='odd "name" \\ 🔧\t\x01\x7f', source="ü 𝛑",
                    calibration=ProbeCalibration(cams, n, 0.25, "test 🔧"))
    path = tmp_path / "probe.toml"
    path.write_text(probe_toml(probe), encoding="utf-8")
    back = load_probe(path)
    assert back.name == probe.name and back.source == probe.source and back.calibration.source == "test 🔧"
    assert abs(back.phi_rad - PROBE.phi_rad) < 1e-15 and np.abs(back.mount - PROBE.mount).max() < 1e-12
    for a, b in zip(back.calibration.cameras, cams):
        assert np.abs(a.K - b.K).max() < 1e-12
        assert np.abs(a.distortion - b.distortion).max() < 1e-15
        assert np.abs(a.cam2probe - b.cam2probe).max() < 1e-12
    assert np.abs(back.calibration.plane_normal - n / np.linalg.norm(n)).max() < 1e-15
    assert back.calibration.plane_offset_mm == 0.25


@pytest.mark.parametrize("edit, words", [
    (lambda t: t.replace("[calibration.laser]", "[calibration.other]"), "calibration.laser"),
    (lambda t: t.replace("normal = [", "normal = [0.0, 0.0, 0.0] #"), "normal"),
    (lambda t: t.replace("fx_px = ", "fx_px = -", 1), "fx_px"),
    (lambda t: t.replace("distortion = [", "distortion = [1.0, ", 1), "distortion"),
    (lambda t: t.replace("rotvec_deg = [", "rotvec_deg = [nan, ", 1), "rotvec_deg"),
])
def test_bad_calibration_tables_name_the_key(tmp_path, edit, words):
    path = tmp_path / "probe.toml"
    path.write_text(edit(probe_toml(replace(PROBE, calibration=ProbeCalibration.of(PROBE)))))
    with pytest.raises(ConfigError, match=words):
        load_probe(path)


def test_a_calibrated_probe_refuses_another_resolution_and_the_paper_formula():
    probe = replace(PROBE, calibration=ProbeCalibration.of(PROBE))
    with pytest.raises(InputError, match="calibrat"):
        probe.with_resolution(320, 320)
    line = given_rows(np.full(PROBE.cols_px, 80.0))
    with pytest.raises(InputError, match="exact"):
        triangulate_profile(probe, line, 0, "paper")


# -- the board -----------------------------------------------------------------------------------
def test_board_corners_are_found_where_the_homography_puts_them():
    """A board image warped by a known plane-to-image homography (8× supersampled, then
    area-averaged like a sensor): the corners found lie within 0.15 px RMS (0.25 px at most)
    of where the homography puts the board model's corners."""
    board = ChArUcoBoard((7, 5), 10.0, 7.5)
    ppm = 20
    tex = board.texture(ppm)
    K = PROBE.K
    for tilt in (0.0, 0.4):
        R = cv2.Rodrigues(np.array([tilt, 0.2, 0.1]))[0]
        t = np.array([-35.0, -25.0, 170.0])
        H = K @ np.column_stack([R[:, 0], R[:, 1], t])                 # board mm -> image px
        texel = np.array([[1 / ppm, 0, 0.5 / ppm], [0, 1 / ppm, 0.5 / ppm], [0, 0, 1]])
        ss = 8
        up = np.array([[ss, 0, (ss - 1) / 2], [0, ss, (ss - 1) / 2], [0, 0, 1]])
        big = cv2.warpPerspective(tex, up @ H @ texel, (160 * ss, 160 * ss), flags=cv2.INTER_LINEAR,
                                  borderValue=255)
        img = cv2.resize(big.astype(np.float32) / 255.0, (160, 160), interpolation=cv2.INTER_AREA)
        ids, found = board.detect(img)
        assert len(ids) >= 15
        obj = board.corners_mm[ids]
        truth = (H @ np.column_stack([obj[:, :2], np.ones(len(obj))]).T).T
        truth = truth[:, :2] / truth[:, 2:]
        err = np.linalg.norm(found - truth, axis=1)
        assert np.sqrt(np.mean(err ** 2)) < 0.15 and err.max() < 0.25


def test_board_checks_its_values():
    with pytest.raises(InputError, match="marker_mm"):
        ChArUcoBoard((7, 5), 10.0, 12.0)
    with pytest.raises(InputError, match="squares"):
        ChArUcoBoard((2, 5))
    with pytest.raises(InputError, match="dictionary"):
        ChArUcoBoard(dictionary="DICT_9X9")
    with pytest.raises(InputError, match="markers"):
        ChArUcoBoard((20, 20), dictionary="DICT_4X4_50")
    assert len(ChArUcoBoard().detect(np.zeros((160, 160)))[0]) == 0


# -- the solve -----------------------------------------------------------------------------------
@pytest.mark.parametrize("probe_name", ["default", "hires"])
def test_calibration_recovers_the_truth_within_its_stated_deviation(probe_name):
    probe = load_probe(probe_name)
    board = board_for(probe)
    sigma = 0.05
    views = synthetic_views(probe, board, board_views(board, probe.z_range_mm, 12), sigma)
    fit = calibrate_probe(probe, board, views)
    dev = deviations(probe, fit.probe.calibration)
    for c, cam in enumerate(fit.cameras):
        # the residual is the pixel noise
        assert 0.7 * sigma < cam.reprojection_error_px < 1.3 * sigma
        d, sd = dev[f"camera{c}"], cam.std_intrinsics
        for key in ("fx_px", "fy_px", "cx_px", "cy_px"):
            assert abs(d[key]) <= 4.5 * sd[key], (c, key, d[key], sd[key])
        assert d["position_mm"] <= 4.5 * cam.std_pose["position_mm"]
        assert d["rotation_deg"] <= 4.5 * cam.std_pose["rotation_deg"]
    # the plane: its points carry the cameras' pose error, and its stated σ carries it too (the
    # points' scatter alone stated it some 90 times too small); no larger than the cameras' own
    rot = max(c.std_pose["rotation_deg"] for c in fit.cameras)
    assert dev["laser"]["tilt_deg"] <= 4.5 * fit.plane_std["tilt_deg"] <= 4.5 * rot
    pos = max(c.std_pose["position_mm"] for c in fit.cameras)
    assert abs(dev["laser"]["offset_mm"]) <= 4.5 * fit.plane_std["offset_mm"] <= 4.5 * pos
    assert fit.plane_rms_mm < 0.05
    # the points: a perfect calibration moves nothing, this one little
    assert triangulation_error(probe, replace(probe, calibration=ProbeCalibration.of(probe)))["all"]["max_mm"] < 1e-9
    z0, z1 = probe.z_range_mm
    assert triangulation_error(probe, fit.probe)["all"]["rms_mm"] < 0.01 * (z1 - z0)


def test_the_plane_is_fitted_through_every_line_point_on_the_plate():
    """The laser points kept for the plane are those the true geometry puts on the plate, all
    but a band at its edge (where the table lies just beyond): counted here from the plate's
    true pose. (The pattern's width was once overwritten by the undistorted pixel rows, and
    the edge test dropped about a third of the good points.)"""
    from addon.core.calibration.solve import PLATE_EDGE_MM

    board = board_for(PROBE)
    poses = board_views(board, PROBE.z_range_mm, 10)
    views = synthetic_views(PROBE, board, poses, 0.0)
    fit = calibrate_probe(PROBE, board, views)
    w, h = board.pattern_mm
    inner = board.margin_mm - PLATE_EDGE_MM
    expected = 0
    for P in poses:
        plate2probe = rigid_inverse(P) @ board2table(board)
        n, p0 = plate2probe[:3, 2], plate2probe[:3, 3]
        y = np.linspace(-30.0, 30.0, 300)
        X = np.column_stack([np.zeros_like(y), y, (n @ p0 - n[1] * y) / n[2]])
        B = (X - plate2probe[:3, 3]) @ plate2probe[:3, :3]  # on the plate
        on = (B[:, 0] > -inner) & (B[:, 0] < w + inner) & (B[:, 1] > -inner) & (B[:, 1] < h + inner)
        for c in (0, 1):
            expected += int((on & np.isfinite(PROBE.project(X, c)).all(axis=1)).sum())
    assert expected > 1000 and abs(fit.plane_points - expected) <= 0.01 * expected, (fit.plane_points, expected)


def test_more_noise_gives_a_larger_stated_deviation():
    board = board_for(PROBE)
    poses = board_views(board, PROBE.z_range_mm, 10)
    a = calibrate_probe(PROBE, board, synthetic_views(PROBE, board, poses, 0.05))
    b = calibrate_probe(PROBE, board, synthetic_views(PROBE, board, poses, 0.4))
    for c in (0, 1):
        ratio = b.cameras[c].std_intrinsics["fx_px"] / a.cameras[c].std_intrinsics["fx_px"]
        assert 5.0 < ratio < 12.0  # σ scales with the pixel noise (8×)


def test_distortion_is_recovered_when_asked():
    """Corners and line pixels distorted by a known Brown–Conrady model: the fit with distortion
    finds the lens's effect (where it moves pixels, corners of the sensor included) to a small share
    of a pixel."""
    dist = np.array([-0.12, 0.01, 0.0, 0.0, 0.0])  # k2 as small as the realistic sensor's: k1 is what is fitted
    board = board_for(PROBE)
    views = synthetic_views(PROBE, board, board_views(board, PROBE.z_range_mm, 16), 0.02)
    for v in views:
        for c in (0, 1):
            for arr in (v.corners[c], v.line[c]):
                und = cv2.undistortPoints(arr.reshape(-1, 1, 2), PROBE.K, dist, P=PROBE.K).reshape(-1, 2)
                # distort: the point whose undistortion is arr (fixed point, a few iterations)
                x = arr.copy()
                for _ in range(30):
                    und = cv2.undistortPoints(x.reshape(-1, 1, 2), PROBE.K, dist, P=PROBE.K).reshape(-1, 2)
                    x += arr - und
                arr[:] = x
    fit = calibrate_probe(PROBE, board, views, distortion=True)
    grid = np.stack(np.meshgrid(np.linspace(0, 159, 9), np.linspace(0, 159, 9)), -1).reshape(-1, 2)
    for c in (0, 1):
        cam = fit.probe.calibration.cameras[c]
        assert cam.distorted
        # where the true lens and the fitted lens put the same undistorted points
        truth = cv2.undistortPoints(grid.reshape(-1, 1, 2), PROBE.K, dist, P=PROBE.K).reshape(-1, 2)
        fitted = np.column_stack(cam.undistort(grid[:, 0].copy(), grid[:, 1].copy()))
        assert np.abs(fitted - truth).max() < 0.5
        assert fit.cameras[c].reprojection_error_px < 0.05


def test_too_few_views_are_refused():
    board = board_for(PROBE)
    views = synthetic_views(PROBE, board, board_views(board, PROBE.z_range_mm, 3))
    with pytest.raises(CalibrationError, match="at least 4"):
        calibrate_probe(PROBE, board, views)


def test_parallel_views_are_refused():
    board = board_for(PROBE)
    views = synthetic_views(PROBE, board, flat_views(board, PROBE.z_range_mm, 8))
    with pytest.raises(CalibrationError, match="parallel"):
        calibrate_probe(PROBE, board, views)


def test_a_board_never_found_is_refused():
    board = board_for(PROBE)
    views = synthetic_views(PROBE, board, board_views(board, PROBE.z_range_mm, 8))
    for v in views:
        v.ids[1], v.corners[1] = np.zeros(0, int), np.zeros((0, 2))
    with pytest.raises(CalibrationError, match="camera 1 found the board"):
        calibrate_probe(PROBE, board, views)


def test_no_laser_line_is_refused():
    board = board_for(PROBE)
    views = synthetic_views(PROBE, board, board_views(board, PROBE.z_range_mm, 8), line=False)
    with pytest.raises(CalibrationError, match="laser"):
        calibrate_probe(PROBE, board, views)


def test_views_spread_over_depth_and_tilt():
    board = board_for(PROBE)
    poses = board_views(board, PROBE.z_range_mm, 20)
    beams = -poses[:, :3, 2]
    tilts = np.degrees(np.arccos(np.clip(beams[:, 2], -1, 1)))
    assert 9.9 < tilts.min() and tilts.max() < 25.1
    z0, z1 = PROBE.z_range_mm
    # the beam passes through the board's centre at a depth inside the range
    centre = board2table(board) @ np.array([*(0.5 * np.array(board.pattern_mm)), 0.0, 1.0])
    depth = np.linalg.norm(poses[:, :3, 3] - centre[:3], axis=1)
    assert (depth > z0).all() and (depth < z1).all() and depth.max() - depth.min() > 0.3 * (z1 - z0)
    assert math.isclose(float(np.abs(np.cross(beams, centre[:3] - poses[:, :3, 3])).max()), 0.0, abs_tol=1e-9)


def test_undistort_false_keeps_a_calibrated_probe_from_undistorting():
    """``[sensor] undistort = false`` triangulates a calibrated probe's raw detections (its lens
    model is not applied); true (the default) moves each through the calibration's distortion,
    as OpenCV's undistortPoints does independently here."""
    from addon.core.config.scan import load_scan_config
    from addon.core.scan.frames import frame_profile

    k = [-0.2, 0.02, 0.0, 0.0, 0.0]
    cams = tuple(CameraModel(np.array([[330.0, 0, 80.0], [0, 330.0, 80.0], [0, 0, 1]]), k, PROBE.cam2probe(c))
                 for c in (0, 1))
    probe = replace(PROBE, calibration=ProbeCalibration(cams, np.array([1.0, 0.0, 0.0]), 0.0, "test"))
    config = load_scan_config("demo")
    config = replace(config, probe=probe, fuse=False,
                     profile_filter=replace(config.profile_filter, max_sigma_mm=float("inf")))
    rows = np.full(PROBE.cols_px, 60.0)
    line = given_rows(rows)
    raw = triangulate_profile(probe, line, 0)
    for undistort, expect_raw in ((False, True), (True, False)):
        cfg = replace(config, sensor=replace(config.sensor, undistort=undistort))
        got = frame_profile(probe, [line, None], cfg)
        assert len(got) > 100
        same = np.abs(got.points[:, None] - raw.points[None]).sum(axis=2).min(axis=1) < 1e-9
        assert same.all() == expect_raw and (same.any() or not expect_raw)
    # undistort = true: the points are those of the detection undistorted by OpenCV directly
    u = np.arange(PROBE.cols_px, dtype=float)
    und = cv2.undistortPoints(np.column_stack([u, rows]).reshape(-1, 1, 2), cams[0].K, np.array(k),
                              P=cams[0].K).reshape(-1, 2)
    assert np.abs(und - np.column_stack([u, rows])).max() > 0.5  # the lens model moves them
    W = PROBE.cols_px
    moved = LineDetection(und[:, 0], und[:, 1], np.ones(W), np.ones(W), np.zeros(W, np.uint8), "given",
                          (PROBE.rows_px, W))
    expected = triangulate_profile(probe, moved, 0)
    got = frame_profile(probe, [line, None], replace(config, sensor=replace(config.sensor, undistort=True)))
    assert len(got) >= len(expected) - 2 > 100  # (the filter drops the line's two end columns)
    nearest = np.linalg.norm(got.points[:, None] - expected.points[None], axis=2).min(axis=1)
    assert nearest.max() < 1e-6


def test_the_laser_planes_offset_deviation_is_calibrated_minus_truth():
    """Every deviation is calibrated minus truth but the plane's offset, whose sign was flipped
    (a hunt: "+6 um" for a plane that sat at -6.4 µm): a plane moved +0.2 mm along the probe's
    x, and one tilted about y through the point 0.2 mm along x at mid-range, both read +0.2."""
    probe = load_probe("default")
    exact = ProbeCalibration.of(probe)
    mid = 0.5 * sum(probe.z_range_mm)
    n = np.asarray(exact.plane_normal, dtype=float)
    moved = replace(exact, plane_offset_mm=float(exact.plane_offset_mm + 0.2 * n[0]))
    assert deviations(probe, moved)["laser"]["offset_mm"] == pytest.approx(0.2, abs=1e-9)
    a = np.radians(1.0)
    tilted_n = np.array([np.cos(a), 0.0, np.sin(a)]) * np.sign(n[0])
    through = np.array([0.2, 0.0, mid])
    tilted = replace(exact, plane_normal=tilted_n, plane_offset_mm=float(tilted_n @ through))
    dev = deviations(probe, tilted)["laser"]
    assert dev["offset_mm"] == pytest.approx(0.2, abs=1e-9) and dev["tilt_deg"] == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize("change, said", [
    (dict(plane_normal=np.array([0.0, 0.0, 1.0])), "laser plane's normal is 90° from the design's"),
    (dict(plane_offset_mm=500.0), "laser plane lies 500 mm from the design's"),
    (dict(fx=0.5), "fx_px 165.9 is 0.5 times the design"),
    (dict(turn=90.0), "camera 0 is turned 90° from the design"),
    (dict(k1=5.0), "k1 5 is beyond any lens's"),
    (dict(fx=1.01, k1=-0.2), None),  # a real lens, a real calibration's error: taken
])
def test_a_calibration_far_from_its_probes_design_is_refused_where_it_is_read(tmp_path, change, said):
    """A plane 90° off, a focal length of half a pixel or an offset of 500 mm loaded, and the
    scan found 0 points and blamed the sensor; k1 = 5 scanned at 4.7 mm RMS without a word (a
    hunt). Each is checked against the probe's design when the rig is read."""
    probe = load_probe("default")
    exact = ProbeCalibration.of(probe)
    cams = list(exact.cameras)
    K = cams[0].K.copy()
    K[0, 0] *= change.get("fx", 1.0)
    dist = np.array([change.get("k1", 0.0), 0.0, 0.0, 0.0, 0.0])
    pose = cams[0].cam2probe @ (rot_y(np.radians(change["turn"])) if "turn" in change else np.eye(4))
    cams[0] = CameraModel(K, dist, pose)
    cal = replace(exact, cameras=tuple(cams), **{k: v for k, v in change.items()
                                                   if k in ("plane_normal", "plane_offset_mm")})
    path = tmp_path / "probe.toml"
    path.write_text(probe_toml(replace(probe, calibration=cal)))
    if said is None:
        assert load_probe(path).calibration is not None
        return
    with pytest.raises(ConfigError, match=r"\[calibration\]: .*" + said.replace("(", r"\(")):
        load_probe(path)
