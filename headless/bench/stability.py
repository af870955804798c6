"""Stiff and extreme cases: each with the behaviour it must show, and what it showed.

Every case ends in a bounded error or a clean, counted rejection (a ScannerError
naming what was wrong, or columns and points counted as rejected), never a NaN,
an infinity or an unexplained result. A case that does not is a failure, and the
command exits with status 1.

Kinematics cases run the closed-form and numeric IK at and near the PUMA 560's
and Viper s650's singularities (found numerically, not assumed), at the edge of
reach and just outside it, and along a 1 000-waypoint path through the wrist
singularity. Probe cases build extreme geometries and triangulate exact
projections back. Scene cases render short scans (Cycles, CPU) of plates and
spheres placed to provoke grazing incidence, range limits, float32 trouble far
from the origin, extreme sizes, and surfaces that lose or clip the line.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np


@dataclass
class Outcome:
    measured: str
    ok: bool
    figures: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Case:
    group: str
    name: str
    expected: str
    run: Callable[[], Outcome]
    renders: bool = False


CASES: list[Case] = []


def case(group: str, name: str, expected: str, renders: bool = False):
    def register(fn):
        CASES.append(Case(group, name, expected, fn, renders))
        return fn
    return register


def finite(*arrays) -> bool:
    return all(np.isfinite(np.asarray(a, dtype=np.float64)).all() for a in arrays)


# -- kinematics -------------------------------------------------------------------------
POS_TOL_MM = 1e-6
ROT_TOL_RAD = 1e-9


def _robot(name):
    from addon.core.config.rigs import load_robot

    return load_robot(name)


def _ik_roundtrip(robot, q_true, seed_offset=0.2) -> Outcome:
    from addon.core.kinematics.transforms import rotation_angle

    T = robot.fk(q_true)
    res = robot.ik(T, q_true + seed_offset)
    Tq = robot.fk(res.q)
    pos = float(np.linalg.norm(Tq[:3, 3] - T[:3, 3]))
    rot = float(rotation_angle(Tq[:3, :3].T @ T[:3, :3]))
    ok = res.success and pos <= POS_TOL_MM and rot <= ROT_TOL_RAD and finite(res.q)
    return Outcome(f"{'solved' if res.success else 'FAILED: ' + res.message} ({res.method}); FK of the answer "
                   f"{pos:.1e} mm, {rot:.1e} rad from the target", ok, dict(pos_mm=pos, rot_rad=rot))


def _wrist_centre(robot, q):
    return robot.link_frames(q)[4][:3, 3]


@case("kinematics", "wrist singularity, q5 = 0 (PUMA 560)",
      "IK solves it (J4 + J6 fixed, their split free): FK within 1e-6 mm, 1e-9 rad")
def wrist_singular():
    return _ik_roundtrip(_robot("puma560"), np.array([0.3, -0.6, 0.4, 0.7, 0.0, -0.2]))


@case("kinematics", "near the wrist singularity, q5 = 1e-7 rad (PUMA 560)",
      "IK solves it: FK within 1e-6 mm, 1e-9 rad")
def wrist_near_singular():
    return _ik_roundtrip(_robot("puma560"), np.array([0.3, -0.6, 0.4, 0.7, 1e-7, -0.2]))


@case("kinematics", "shoulder singularity: wrist centre on the J1 axis (Viper s650)",
      "IK solves it (J1 free): FK within 1e-6 mm, 1e-9 rad")
def shoulder_singular():
    from scipy.optimize import least_squares

    robot = _robot("adept_viper_s650")
    q = np.array([0.2, 0.3, 0.2, 0.4, 0.8, -0.3])

    def radial(x):
        qq = q.copy()
        qq[1:3] = x
        return _wrist_centre(robot, qq)[:2] - robot.base[:2, 3]

    lo, hi = robot.q_min_rad[1:3] + 1e-3, robot.q_max_rad[1:3] - 1e-3
    best = None
    for start in ([0.3, 0.2], [1.2, -1.5], [2.0, -2.5], [0.5, -3.5]):
        sol = least_squares(radial, np.clip(start, lo, hi), bounds=(lo, hi), xtol=1e-15, ftol=1e-15, gtol=1e-15)
        if best is None or np.linalg.norm(sol.fun) < np.linalg.norm(best.fun):
            best = sol
    sol = best
    q[1:3] = sol.x
    off_axis = float(np.linalg.norm(radial(sol.x)))
    if not robot.within_limits(q) or off_axis > 1e-9:
        return Outcome(f"could not place the wrist centre on the axis ({off_axis:.1e} mm)", False)
    out = _ik_roundtrip(robot, q)
    out.measured = f"wrist centre {off_axis:.0e} mm off the axis; " + out.measured
    return out


def _stretched(robot, q):
    """q with J3 set where the wrist centre is farthest from the shoulder (the elbow singularity)."""
    from scipy.optimize import minimize_scalar

    def minus_dist(q3):
        qq = q.copy()
        qq[2] = q3
        return -np.linalg.norm(_wrist_centre(robot, qq) - robot.link_frames(qq)[1][:3, 3])

    lo, hi = robot.q_min_rad[2], robot.q_max_rad[2]
    grid = np.linspace(lo, hi, 721)
    k = int(np.argmin([minus_dist(g) for g in grid]))
    res = minimize_scalar(minus_dist, bounds=(grid[max(k - 1, 0)], grid[min(k + 1, 720)]), method="bounded",
                          options={"xatol": 1e-13})
    out = q.copy()
    out[2] = res.x
    return out


@case("kinematics", "elbow singularity: arm stretched (PUMA 560)",
      "IK solves it: FK within 1e-6 mm, 1e-9 rad")
def elbow_singular():
    robot = _robot("puma560")
    return _ik_roundtrip(robot, _stretched(robot, np.array([0.1, -0.4, 0.0, 0.3, 0.6, 0.2])))


def _reach_target(robot, q_stretched, outward_mm):
    T = robot.fk(q_stretched).copy()
    shoulder = robot.link_frames(q_stretched)[1][:3, 3]
    wc = _wrist_centre(robot, q_stretched)
    direction = (wc - shoulder) / np.linalg.norm(wc - shoulder)
    T[:3, 3] += outward_mm * direction
    return T


@case("kinematics", "edge of reach: 1 µm inside (PUMA 560)", "IK solves it: FK within 1e-6 mm")
def reach_inside():
    robot = _robot("puma560")
    q = _stretched(robot, np.array([0.1, -0.4, 0.0, 0.3, 0.6, 0.2]))
    T = _reach_target(robot, q, -1e-3)
    res = robot.ik(T, q)
    pos = float(np.linalg.norm(robot.fk(res.q)[:3, 3] - T[:3, 3]))
    return Outcome(f"{'solved' if res.success else 'FAILED: ' + res.message}; {pos:.1e} mm from the target",
                   res.success and pos <= POS_TOL_MM, dict(pos_mm=pos))


@case("kinematics", "just outside reach: 1 µm beyond (PUMA 560)",
      "no success claimed; reason out_of_reach; the best attempt finite")
def reach_outside():
    robot = _robot("puma560")
    q = _stretched(robot, np.array([0.1, -0.4, 0.0, 0.3, 0.6, 0.2]))
    res = robot.ik(_reach_target(robot, q, 1e-3), q)
    ok = (not res.success) and res.reason == "out_of_reach" and finite(res.q)
    return Outcome(f"success={res.success}, reason {res.reason}, {res.pos_err_mm:.1e} mm short", ok,
                   dict(short_mm=res.pos_err_mm))


def _line_past_wrist_singularity(offset_mm: float, n: int = 1000):
    """A straight 100 mm line of tool positions at one orientation that passes ``offset_mm``
    from a wrist-singular pose of the Viper s650 (q5 = 0 there), and its IK walk."""
    from addon.core.kinematics.cell import Cell
    from addon.core.kinematics.path import Waypoints, solve_path
    from addon.core.kinematics.turntable import Turntable

    robot = _robot("adept_viper_s650")
    cell = Cell(robot, Turntable())
    q_s = np.array([0.2, 0.5, -0.3, 0.4, 0.0, 0.1])
    T_s = robot.fk(q_s)
    forearm = _wrist_centre(robot, q_s) - robot.link_frames(q_s)[3][:3, 3]
    u = np.cross(forearm, [0.0, 0.0, 1.0])
    u /= np.linalg.norm(u)
    w = np.cross(forearm, u)
    w /= np.linalg.norm(w)
    s = np.linspace(-50.0, 50.0, n)
    T = np.repeat(T_s[None], n, axis=0)
    T[:, :3, 3] = T_s[:3, 3] + s[:, None] * u + offset_mm * w
    start = robot.ik(T[0], q_s).q
    wp = Waypoints(cell.table.base2table(0.0) @ T, np.zeros(n), np.zeros(n, int))
    sol = solve_path(cell, wp, start)
    pos = float(np.max(np.linalg.norm(robot.fk(sol.q)[:, :3, 3] - T[:, :3, 3], axis=1)))
    steps = np.degrees(sol.max_step_rad[1:])
    return sol, pos, steps


@case("kinematics", "straight line 1 mm from the wrist singularity, 1 000 waypoints (Viper s650)",
      "every waypoint solved; the wrist turns fast but continuously (no step over 30°); the spike shown")
def path_near_singularity():
    sol, pos, steps = _line_past_wrist_singularity(1.0)
    spike = float(steps.max() / np.median(steps))
    ok = bool(sol.ok.all()) and pos <= POS_TOL_MM and not sol.jumps
    return Outcome(f"{int(sol.ok.sum())}/1000 solved, worst {pos:.1e} mm; joint-rate spike: largest step "
                   f"{steps.max():.1f}° ({spike:.0f}× the median {np.median(steps):.3f}°); {len(sol.jumps)} flips",
                   ok, dict(max_step_deg=float(steps.max()), spike=spike))


@case("kinematics", "straight line 0.01 mm from the wrist singularity (Viper s650)",
      "every waypoint solved; the wrist's half turn within one step reported as a jump, with its waypoint")
def path_grazing_singularity():
    sol, pos, steps = _line_past_wrist_singularity(0.01)
    ok = bool(sol.ok.all()) and pos <= POS_TOL_MM and len(sol.jumps) >= 1
    where = ", ".join(str(j) for j in sol.jumps[:3])
    return Outcome(f"{int(sol.ok.sum())}/1000 solved, worst {pos:.1e} mm; {len(sol.jumps)} jump(s) reported "
                   f"(waypoint {where}: {steps.max():.0f}° in one step)", ok, dict(jumps=len(sol.jumps)))


@case("kinematics", "straight line exactly through the wrist singularity (Viper s650)",
      "every waypoint solved; the walk crosses smoothly (q5 changes sign), no jump")
def path_through_singularity():
    sol, pos, steps = _line_past_wrist_singularity(0.0)
    q5 = np.degrees(sol.q[:, 4])
    ok = bool(sol.ok.all()) and pos <= POS_TOL_MM and not sol.jumps and q5[0] * q5[-1] < 0
    return Outcome(f"{int(sol.ok.sum())}/1000 solved, worst {pos:.1e} mm; q5 from {q5[0]:.2f}° to {q5[-1]:.2f}°, "
                   f"largest step {steps.max():.3f}°; {len(sol.jumps)} jumps", ok, dict(max_step_deg=float(steps.max())))


@case("kinematics", "NaN joint angles", "a clean InputError naming q")
def nan_joints():
    from addon.core.errors import InputError

    try:
        _robot("puma560").fk([0.0, np.nan, 0.0, 0.0, 0.0, 0.0])
    except InputError as exc:
        return Outcome(f"InputError: {exc}", "q" in str(exc))
    return Outcome("no error raised", False)


# -- probe geometry ------------------------------------------------------------------------
def _probe(a, phi, gamma, rows=160, cols=160, name="extreme"):
    from addon.core.optics.probe import Probe

    return Probe(name, a, 0.0, phi, gamma, rows, cols)


def _roundtrip(probe, n=41, min_angle_deg: float | None = None) -> Outcome:
    """Laser-plane points across the range and the line, projected exactly and triangulated back."""
    from addon.core.optics.detect import LineCode, LineDetection
    from addon.core.optics.triangulate import triangulate_profile

    z0, z1 = probe.z_range_mm
    zs = np.linspace(z0, z1, n + 2)[1:-1] if z1 < 1e6 else np.geomspace(z0 * 1.01, z1 * 0.99, n)
    worst, kept, total, sens = 0.0, 0, 0, []
    for camera in (0, 1):
        half = 0.9 * probe.line_half_length_mm(zs)
        ys = np.linspace(-1.0, 1.0, 5)[None, :] * half[:, None]
        pts = np.column_stack([np.zeros(ys.size), ys.ravel(), np.repeat(zs, 5)])
        uv = probe.project(pts, camera)
        inside = np.isfinite(uv).all(axis=1)
        k = int(inside.sum())
        line = LineDetection(uv[inside, 0], uv[inside, 1], np.ones(k), np.ones(k), np.full(k, LineCode.OK, np.uint8),
                             "exact", (probe.rows_px, probe.cols_px))
        kw = {} if min_angle_deg is None else {"min_angle_deg": min_angle_deg}
        prof = triangulate_profile(probe, line, camera, "exact", **kw)
        total += k
        kept += len(prof)
        if not finite(prof.points, prof.sigma_mm):
            return Outcome("non-finite triangulated point", False)
        if len(prof):
            truth = pts[inside]
            d = np.min(np.linalg.norm(prof.points[:, None, :] - truth[None], axis=2), axis=1)
            worst = max(worst, float(np.max(d / prof.points[:, 2])))
            sens.append(float(np.median(prof.sigma_mm)))
    ok = worst <= 1e-9 and kept > 0
    dropped = total - kept
    return Outcome(f"range {z0:.3g}–{z1:.3g} mm; worst round trip {worst:.1e} of the depth over {kept} points"
                   + (f" ({dropped} at grazing angles rejected, counted)" if dropped else "")
                   + (f"; {np.median(sens) * 1e3:.3g} µm per 0.1 px" if sens else ""), ok,
                   dict(worst_rel=worst, kept=kept))


@case("probe", "baseline a = 1 mm",
      "rays meeting the laser plane under the 2° minimum rejected and counted; with the limit lowered, "
      "exact to 1e-9 of the depth")
def tiny_baseline():
    from addon.core.optics.probe import angles_from_range
    from addon.core.optics.triangulate import MIN_ANGLE_DEG

    phi, gamma = angles_from_range(1.0, 0.0, 70.0, 250.0)
    probe = _probe(1.0, phi, gamma)
    default = _roundtrip(probe)
    lowered = _roundtrip(probe, min_angle_deg=0.05)
    counted = default.figures.get("kept", -1) == 0
    return Outcome(f"at the {MIN_ANGLE_DEG:g}° minimum: {default.measured}; at 0.05°: {lowered.measured}",
                   counted and lowered.ok)


@case("probe", "baseline a = 1 000 mm", "finite range; exact triangulation back to 1e-9 of the depth")
def huge_baseline():
    from addon.core.optics.probe import angles_from_range

    phi, gamma = angles_from_range(1000.0, 0.0, 70.0, 250.0)
    return _roundtrip(_probe(1000.0, phi, gamma))


@case("probe", "φ − γ = 1e-6 rad (range reaching 6e7 mm)",
      "finite numbers; points exact to 1e-9 of the depth, or rejected as grazing and counted")
def phi_near_gamma():
    return _roundtrip(_probe(60.0, math.radians(10.0) + 1e-6, math.radians(10.0)))


@case("probe", "γ = 0.01° (a very long lens)", "exact triangulation back to 1e-9 of the depth")
def tiny_gamma():
    return _roundtrip(_probe(60.0, math.radians(20.0), math.radians(0.01)))


@case("probe", "γ = 44° with φ = 45.5° (φ + γ near 90°)", "exact triangulation back to 1e-9 of the depth")
def large_gamma():
    return _roundtrip(_probe(60.0, math.radians(45.5), math.radians(44.0)))


@case("probe", "4 096 × 4 096 sensor",
      "exact triangulation back to 1e-9 of the depth; gauss finds a synthetic line to 0.01 px")
def big_sensor():
    from addon.core.optics.detect import DetectParams, detect_line
    from addon.core.config.rigs import load_probe
    from headless.synthetic import line_image

    probe = load_probe("default").with_resolution(4096, 4096)
    out = _roundtrip(probe)
    centres = 2048.3 + 40 * np.sin(np.arange(4096) / 300.0)
    img = line_image(4096, centres, 2.0, background=0.1)
    t = time.perf_counter()
    line = detect_line(img, "gauss", DetectParams(saturation=np.inf, smoothing_px=0.0))
    ms = (time.perf_counter() - t) * 1e3
    err = float(np.max(np.abs(line.row - centres)[line.valid]))
    out.measured += f"; detection worst {err:.4f} px over {int(line.valid.sum())} columns, {ms:.0f} ms"
    out.ok = out.ok and err <= 0.01 and line.valid.mean() > 0.99
    return out


@case("probe", "no valid range: φ − γ ≤ 0", "a clean InputError naming the allowed angles")
def no_range():
    from addon.core.errors import InputError

    try:
        _probe(60.0, math.radians(10.0), math.radians(12.0))
    except InputError as exc:
        return Outcome(f"InputError: {exc}", "φ" in str(exc) or "phi" in str(exc))
    return Outcome("accepted", False)


# -- scenes ------------------------------------------------------------------------------------
def _scan(cfg):
    from addon.pipeline import run_scan

    return run_scan(cfg, None, write_outputs=False)


def _summary(res) -> tuple[str, bool]:
    r = res.report
    e = r["error_um"]
    finite_ok = finite(res.cloud.points)
    codes = ", ".join(f"{k.lower()} {v}" for k, v in sorted(r["column_codes"].items()) if k != "OK" and v)
    part = (f"{r['points_on_part']} points on the part, RMS {e['rms_um']:.1f} µm, max {e['max_um']:.0f} µm"
            if r["points_on_part"] else "no points on the part")
    text = f"{part}; {r['valid_fraction'] * 100:.0f} % of columns kept" + (f" (rejected: {codes})" if codes else "")
    return text, finite_ok


def _bounded_or_rejected(cfg, bound_um: float = 50.0) -> Outcome:
    """Scan; pass when the points kept on the part are within ``bound_um`` RMS, or none
    were kept (every column rejected and counted), and nothing is NaN."""
    res = _scan(cfg)
    text, fin = _summary(res)
    e = res.report["error_um"]
    ok = fin and (res.report["points_on_part"] == 0 or e["rms_um"] <= bound_um)
    return Outcome(text, ok, dict(rms_um=e["rms_um"]))


def _plate(tilt_deg: float, height_mm: float = 30.0, frames: int = 8, standoff_mm: float = 160.0, size=80.0):
    """The tilted-plane scene with the plate tilted about the line's direction (y) and one sweep."""
    from addon.core.config.scan import load_scan_config
    from addon.core.kinematics.path import sweep
    from addon.core.kinematics.euler import pose_from_xyz_yzz
    from addon.core.geometry.workpiece import builtin_workpiece

    cfg = load_scan_config("tilted_plane")
    pose = pose_from_xyz_yzz([0.0, 0.0, height_mm], np.radians([0.0, tilt_deg, 0.0]))
    wp = builtin_workpiece("plane", pose=pose, width_mm=size, height_mm=size)
    z = height_mm + standoff_mm
    return replace(cfg, workpiece=wp, waypoints=sweep(frames, [-4.0, 0.0, z], [4.0, 0.0, z]))


@case("scene", "surface 5° from the laser plane (plate tilted 85°)",
      "bounded error on what is kept (RMS ≤ 50 µm), the rest rejected and counted", renders=True)
def grazing_laser():
    return _bounded_or_rejected(_plate(85.0))


@case("scene", "surface along one camera's rays (plate tilted 63°)",
      "that camera's points rejected or bounded; RMS ≤ 50 µm", renders=True)
def grazing_camera():
    res = _scan(_plate(63.0))
    text, fin = _summary(res)
    e = res.report["error_um"]
    return Outcome(text, fin and e["rms_um"] <= 50.0, dict(rms_um=e["rms_um"]))


@case("scene", "plate at the range ends: 70, 70.5, 246 and 250 mm",
      "measured to RMS ≤ 10 µm, except where the line's peak falls on the sensor's outer row: rejected as "
      "an edge and counted", renders=True)
def range_ends():
    texts, ok = [], True
    for standoff in (70.0, 70.5, 246.0, 250.0):  # 246 mm: row 0.8 of the sensor (3 mm per row there)
        res = _scan(_plate(0.0, standoff_mm=standoff, frames=4))
        text, fin = _summary(res)
        e, codes = res.report["error_um"], res.report["column_codes"]
        measured = res.report["points_on_part"] > 100 and e["rms_um"] <= 10.0
        edge = codes.get("EDGE", 0) > 0.5 * sum(codes.values())
        ok = ok and fin and (measured or edge)
        texts.append(f"{standoff:g} mm: {text}")
    return Outcome("; ".join(texts), ok)


@case("scene", "plate beyond the range (65 and 255 mm)",
      "refused before rendering, naming the frames and the range")
def beyond_range():
    from addon.core.errors import ScannerError
    from addon.pipeline import plan_scan

    texts, ok = [], True
    for standoff in (65.0, 255.0):
        cfg = _plate(0.0, standoff_mm=standoff, frames=4, size=300.0)  # the whole fan on the plate
        try:
            plan_scan(cfg)
            texts.append(f"{standoff} mm: accepted")
            ok = False
        except ScannerError as exc:
            texts.append(f"{standoff} mm: {exc}")
            ok = ok and "range" in str(exc) and "frames 0-3" in str(exc)
    return Outcome("; ".join(texts), ok)


@case("scene", "cell 1 km from the world origin (float32 in Blender)",
      "the same cloud as at the origin, to 1 µm", renders=True)
def far_from_origin():
    from addon.core.kinematics.transforms import trans

    from addon.core.kinematics.turntable import Turntable

    near = _plate(20.0, frames=6)
    # Robot base and table both 1 km along x from the world origin.
    far = replace(near, robot=near.robot.with_base(trans(1e6, 0.0, 0.0)),
                  table=Turntable(a_mm=near.table.a_mm - 1e6, d_mm=near.table.d_mm))
    a, b = _scan(near), _scan(far)
    same = len(a.cloud) == len(b.cloud)
    d = float(np.max(np.abs(a.cloud.points - b.cloud.points))) * 1e3 if same and len(a.cloud) else float("inf")
    text, fin = _summary(b)
    return Outcome(f"{text}; largest difference from the cell at the origin {d:.2g} µm", fin and same and d <= 1.0,
                   dict(diff_um=d))


@case("scene", "table turned through 2 × 10⁴ small steps (two full turns)",
      "no accumulated error: after 360° and 720° the probe's pose in the table frame and the rendered "
      "images equal the first frame's", renders=True)
def many_table_steps():
    from addon.core.config.scan import load_scan_config
    from addon.core.kinematics.path import turntable
    from addon.pipeline import plan_scan
    from addon.scene.cell import build_cell
    from addon.core.config.render import RenderOptions
    from addon.scene.session import new_scene

    n = 10_000
    cfg = load_scan_config("demo")
    wp = turntable(2 * n + 1, [12.0, 0.0, 210.0], turn_rad=4 * math.pi, table=cfg.table)
    cfg = replace(cfg, waypoints=wp)
    drift = max(float(np.abs(wp.probe2table[k] - wp.probe2table[0]).max()) for k in (n, 2 * n))
    t = time.perf_counter()
    plan = plan_scan(cfg)
    sc = build_cell(new_scene(), cfg.cell, cfg.probe, cfg.workpiece)
    frames = sc.keyframe(plan.q, plan.table_rad)
    images = [sc.render(frames.start + k, frames.start + k, RenderOptions())[0][0] for k in (0, n, 2 * n)]
    seconds = time.perf_counter() - t
    diff = max(float(np.abs(images[k] - images[0]).max()) for k in (1, 2))
    lit = float(images[0][..., 0].max())
    ok = drift <= 1e-9 and diff <= 1e-6 and lit > 0.1
    return Outcome(f"pose after 360° and 720°: {drift:.1e} mm from the first; images at frames {n} and {2 * n} "
                   f"differ from frame 0 by {diff:.1e} (line peak {lit:.2f}); {2 * n + 1} frames planned, keyframed "
                   f"and three rendered in {seconds:.1f} s", ok, dict(drift_mm=drift, image_diff=diff))


@case("scene", "tiny part: sphere of radius 0.5 mm",
      "bounded error on what is kept (RMS ≤ 50 µm), or points rejected and counted", renders=True)
def tiny_sphere():
    from addon.core.kinematics.euler import pose_from_xyz_yzz
    from addon.core.geometry.workpiece import builtin_workpiece

    cfg = _plate(0.0, frames=8)
    wp = builtin_workpiece("sphere", pose=pose_from_xyz_yzz([0.0, 0.0, 30.0], [0.0, 0.0, 0.0]), radius_mm=0.5)
    cfg = replace(cfg, workpiece=wp, waypoints=replace(cfg.waypoints, probe2table=cfg.waypoints.probe2table.copy()))
    cfg.waypoints.probe2table[:, 0, 3] = np.linspace(-0.6, 0.6, len(cfg.waypoints))
    return _bounded_or_rejected(cfg)


@case("scene", "big part: plate 4.9 m square; 20 m refused",
      "the 4.9 m plate measured to RMS ≤ 10 µm; the 20 m one refused with the size limit")
def big_plate():
    from addon.core.errors import InputError

    from addon.core.safety import Safety

    # A plate this size reaches through the robot's own base: a numerical case, not a cell,
    # so its config turns the collision checks off (which the check itself would refuse).
    res = _scan(replace(_plate(20.0, frames=4, size=4900.0), safety=Safety(check=False)))
    text, fin = _summary(res)
    e = res.report["error_um"]
    ok = fin and e["rms_um"] <= 10.0
    try:
        _plate(20.0, size=20000.0)
        text += "; 20 m accepted"
        ok = False
    except InputError as exc:
        text += f"; 20 m: {exc}"
        ok = ok and "larger than" in str(exc)  # refused for its size, not for something else
    return Outcome(text, ok, dict(rms_um=e["rms_um"]))


@case("scene", "black part (albedo 0.06)",
      "what is kept bounded (RMS ≤ 50 µm), or every column rejected; nothing NaN", renders=True)
def black_part():
    return _bounded_or_rejected(_plate(20.0, frames=6).with_realism(_ideal(), "dark"))


@case("scene", "mirror-like part (polished metal, no bounces)",
      "what is kept bounded (RMS ≤ 50 µm), or every column rejected; nothing NaN", renders=True)
def mirror_part():
    return _bounded_or_rejected(_plate(20.0, frames=6).with_realism(_ideal(), "mirror"))


@case("scene", "line 20× full scale on a clipping sensor",
      "most columns rejected as saturated and counted; what is kept bounded (RMS ≤ 50 µm)", renders=True)
def saturated_line():
    from addon.core.optics.sensor import SensorModel

    cfg = _plate(20.0, frames=6).with_realism(SensorModel(saturate=True, exposure_ms=40.0))
    res = _scan(cfg)
    text, fin = _summary(res)
    codes = res.report["column_codes"]
    kept = res.report["points_on_part"]
    ok = fin and codes.get("SATURATED", 0) > 0.5 * sum(codes.values()) \
        and (kept == 0 or res.report["error_um"]["rms_um"] <= 50.0)
    return Outcome(text, ok, dict(saturated=codes.get("SATURATED", 0)))


def _ideal():
    from addon.core.optics.sensor import SensorModel

    return SensorModel()


# -- the command -----------------------------------------------------------------------------
def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--only", choices=("kinematics", "probe", "scene"), help="run one group")
    parser.add_argument("--readme", action="store_true", help="also put the catalogue into docs/stability.md")
    parser.set_defaults(run=run)


def run_case(c: Case) -> Outcome:
    """A case's outcome; an unexpected exception is a failure with its message, not a crash."""
    try:
        return c.run()
    except Exception as exc:  # noqa: BLE001 - the catalogue reports every failure
        return Outcome(f"unexpected {type(exc).__name__}: {exc}", False)


def run(args: argparse.Namespace) -> int:
    from headless.bench import check_readme_whole

    check_readme_whole(args, only=None)
    rows = []
    for c in CASES:
        if args.only and c.group != args.only:
            continue
        t = time.perf_counter()
        out = run_case(c)
        rows.append((c, out, time.perf_counter() - t))
        print(f"  {'PASS' if out.ok else 'FAIL'}  {c.group:<11}{c.name}: {out.measured}", flush=True)
    md = to_markdown(rows)
    print()
    print(md)
    failed = [c.name for c, out, _ in rows if not out.ok]
    if args.readme:
        from headless.bench import readme

        readme.update("stability", md)
    if failed:
        print(f"{len(failed)} case(s) failed: {'; '.join(failed)}")
        return 1
    print(f"all {len(rows)} cases pass")
    return 0


def to_markdown(rows) -> str:
    lines = ["Measured with `python -m headless bench stability` (exit status 1 if any case fails).", "",
             "| group | case | expected | measured | |", "|---|---|---|---|---|"]
    for c, out, seconds in rows:
        measured = out.measured.replace("|", "\\|")
        lines.append(f"| {c.group} | {c.name} | {c.expected} | {measured} | {'pass' if out.ok else '**FAIL**'} |")
    return "\n".join(lines) + "\n"
