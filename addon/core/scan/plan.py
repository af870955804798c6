"""A path's plan, made before anything renders: IK for every waypoint (continuous, no
flips), collision checks along the whole motion, then the laser fan cast against the
part and the table. Unreachable waypoints, a colliding motion (naming the frames and
the two bodies) and waypoints whose laser meets nothing inside the probe's range
refuse the path here, in that order; the plan keeps the clearance found, the cameras
worth rendering and, per frame, the sensor rows the line can fall on."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from warnings import catch_warnings, simplefilter

import numpy as np

from ..config.scan import DEFAULT_FILTER, ScanConfig
from ..errors import CollisionError, InputError, ScannerError, UnreachablePose
from ..geometry import metrics
from ..geometry.workpiece import drawn_mesh
from ..geometry.footprint import OCCLUSION_EPS_MM, SurfaceCaster, fan_rays, laser_footprint, seen_by
from ..kinematics.path import solve_path
from ..kinematics.turntable import table_top_mesh
from ..optics.laser_profile import angular_sigma_rad
from ..optics.probe import CAMERAS
from ..optics.surfaces import DIFFUSE_SURFACES
from ..safety import CollisionModel, PathClearance


@dataclass
class Plan:
    """q (n, 6); table_rad (n,); cameras to render; predicted_rows (n, 2): lowest and highest
    sensor row of the line in each frame from the ray casts (NaN: none), rendered cameras only."""

    q: np.ndarray
    table_rad: np.ndarray
    cameras: tuple[int, ...]
    predicted_rows: np.ndarray
    warnings: list = field(default_factory=list)
    clearance: PathClearance | None = None
    # {world fixture name: frames (path indices) where it stands in the laser's way or hides the
    # line from a camera (see fixtures_in_the_way)}
    fixture_frames: dict = field(default_factory=dict)
    # Frames (indices) whose laser puts no surface inside the probe's range: a scan refuses
    # them, a Scanner's step measures nothing there (and says so).
    empty_frames: list = field(default_factory=list)


def frame_ranges(indices) -> str:
    """[0, 1, 2, 5, 7, 8] -> '0-2, 5, 7-8' (the first 12 runs)."""
    idx = sorted(int(i) for i in indices)
    runs, start = [], None
    for a, b in zip(idx, idx[1:] + [None]):
        start = a if start is None else start
        if b != a + 1:
            runs.append(f"{start}" if start == a else f"{start}-{a}")
            start = None
    more = f" and {len(runs) - 12} more runs" if len(runs) > 12 else ""
    return ", ".join(runs[:12]) + more


def plan_scan(config: ScanConfig, allow_blind: bool = False) -> Plan:
    """IK for the whole path and the laser footprint check; raises before anything renders.

    ``allow_blind``: frames whose laser meets nothing in range are kept (a step-by-step
    scanner measures nothing there) instead of refusing the path; where no camera sees
    the line on any frame, ``cameras`` is empty and nothing needs rendering."""
    blind = blind_settings(config)  # cheap, and nothing else matters if it holds
    if blind:
        raise InputError(f"nothing could be measured: {blind}")
    cell = config.cell
    wp = config.waypoints
    sol = solve_path(cell, wp, config.q_start)
    if not sol.ok.all():
        bad = sol.unreachable
        raise UnreachablePose(f"{len(bad)} of {len(wp)} waypoints cannot be reached (frames {frame_ranges(bad)}); "
                              f"first, frame {bad[0]}: {sol.messages[bad[0]]}")
    clearance = check_motion(config, sol.q, wp.table_rad, wp.segment, config.q_start)
    warnings = []
    if sol.jumps:
        warnings.append(f"joint jumps over {math.degrees(max(sol.max_step_rad)):.0f}° between neighbouring "
                        f"waypoints at frames {frame_ranges(sol.jumps)} (near a singularity or a limit)")
    warnings += robot_warnings(config, sol.q) + part_warnings(config)
    plan = plan_frames(config, sol.q, wp.table_rad, allow_blind, warnings)
    plan.clearance = clearance
    return plan


_MODELS: list = []  # the last few collision models, with the objects they were built from


REPOSITION_DEG = 120.0  # a joint turning more than this between two path entries is said


def robot_warnings(config: ScanConfig, q: np.ndarray) -> list[str]:
    """What a cell designer should hear of the robot's motion along the path ``q`` (n, 6): a
    joint turning more than REPOSITION_DEG where the robot goes from one path entry to the next
    (a repositioning the path itself does not show; a cable's wind-up)."""
    robot, seg = config.robot, config.waypoints.segment
    out = []
    turning = ~np.asarray(robot.prismatic)
    for i in np.flatnonzero(seg[1:] != seg[:-1]) + 1:
        step = np.degrees(np.abs(q[i] - q[i - 1]))
        big = [j for j in np.argsort(-step) if turning[j] and step[j] > REPOSITION_DEG]
        if big:
            turns = ", ".join(f"{robot.joint_label(j)} by {step[j]:.0f}°" for j in big)
            out.append(f"between path[{seg[i - 1] + 1}] and path[{seg[i] + 1}] (before frame {i}) the robot "
                       f"repositions: {turns}")
    return out


def collision_model(config: ScanConfig) -> CollisionModel:
    """The cell's collision model for this config (built once per robot, probe, table,
    workpiece, fixtures and clearance: a scanner checks every move with the same one)."""
    same = (config.robot, config.probe, config.workpiece, config.fixtures)  # the very objects
    equal = (config.table, config.safety.min_clearance_mm)
    for (s, e), model in _MODELS:
        if all(a is b for a, b in zip(s, same)) and e == equal:
            return model
    model = CollisionModel(config.cell.robot, config.probe, config.table, config.workpiece.mesh,
                           [(f.name, f.mesh, f.on) for f in config.fixtures], config.safety.min_clearance_mm)
    _MODELS.insert(0, ((same, equal), model))
    del _MODELS[4:]
    return model


def check_motion(config: ScanConfig, q, table_rad, segment=None, q_start=None, table_start=None,
                 nearest: bool = True, may_back_away: bool = False) -> PathClearance | None:
    """Collision checks along the motion through joints q (n, 6) and table angles (n,), from
    ``q_start`` where given; raises CollisionError naming the first frames and the two bodies.
    ``nearest``: also find the smallest clearance per path entry for the report (a planner
    asking only whether a motion is allowed leaves it out). ``may_back_away``: a single move (a
    Scanner's move_to, move_joints or table turn) may leave a start pose that keeps too little
    clearance, where it comes no nearer. None where the config turns the checks off."""
    if not config.safety.check:
        return None
    model = collision_model(config)
    if q_start is not None:
        # The pose the motion starts from, alone first: one that breaks the clearance is refused
        # at once, not after every sample of a path that then breaks it all along (a large
        # [safety] min_clearance_mm: every sample of every pair asks for an exact distance).
        start = np.asarray(q_start, dtype=np.float64).reshape(1, 6)
        t0 = float(np.asarray(table_rad, dtype=np.float64).reshape(-1)[0]) if table_start is None else table_start
        at_start = model.check(start, np.array([t0]), None, start, t0, nearest=False)
        if not at_start.ok:
            # A single move out of a pose that keeps too little clearance without touching (the
            # clearance raised since it was reached) may go where it comes no nearer, so the
            # robot can back away; a path must start clear.
            if not may_back_away or len(np.asarray(q).reshape(-1, 6)) != 1 \
                    or any(c.distance_mm <= 0 for c in at_start.deepest):
                raise CollisionError(at_start.message())
            relaxed = {(c.body_a, c.body_b): c.distance_mm * (1.0 - 1e-9) for c in at_start.deepest}
            result = model.check(q, table_rad, segment, q_start, table_start, nearest=nearest, relaxed=relaxed)
            if not result.ok:
                raise CollisionError(result.message(segment) + f" (it started {at_start.message()})")
            return result
    result = model.check(q, table_rad, segment, q_start, table_start, nearest=nearest)
    if not result.ok:
        raise CollisionError(result.message(segment))  # a config's path: its entries named too
    return result


FWHM_PER_SIGMA = 2.0 * math.sqrt(2.0 * math.log(2.0))  # a Gaussian's full width at half maximum, in σ
MIN_LINE_PX = 0.01  # a line narrower than this on the sensor is never seen (the pixel centres miss it)
WIDE_MARGIN = 3.0  # a line this many times wider than the detector takes, on a surface square to the beam, is never taken


WIDTH_STEP_MM = 1e-3  # across the laser plane: the line's width is its image's rows per mm times its mm
SHALLOW_RANGE_MM = 1.0  # a range this shallow is named first where a camera cannot image the plane
NARROW_LINE_PX = 1.0  # a line narrower than a pixel (FWHM) is undersampled: see narrow_line_warning


def line_widths_px(probe) -> list[float]:
    """The laser line's width (FWHM, px) on camera 0's sensor, seen square on, at seven depths
    spread over the probe's range (the line keeps its angular width); those where the camera
    does not image the plane are left out."""
    z0, z1 = probe.z_range_mm
    step, widths = WIDTH_STEP_MM, []
    for z in np.linspace(z0, z1, 9)[1:-1]:
        fwhm_mm = FWHM_PER_SIGMA * angular_sigma_rad(probe) * z
        uv = probe.project(np.array([[step, 0.0, z], [-step, 0.0, z]]), 0)
        if np.isfinite(uv).all():
            widths.append(abs(uv[0, 1] - uv[1, 1]) / (2 * step) * fwhm_mm)
    return widths


def narrow_line_warning(probe) -> str | None:
    """A line imaged narrower than NARROW_LINE_PX somewhere in the range: its light falls on
    one or two rows, so the sub-pixel peak leans towards row centres by a fraction of a pixel
    that the stated σ does not hold (a user's 160-row probe, 0.66-0.92 px: with sensor noise
    it kept table points 105 µm off, stated at 17 µm; ideal, it dropped good ones as
    uncertain). The default probe's line is 1.04-1.43 px."""
    widths = line_widths_px(probe)
    if not widths or min(widths) >= NARROW_LINE_PX:
        return None
    return (f"the laser line images {min(widths):.2f}-{max(widths):.2f} px wide (FWHM) on the probe's "
            f"{probe.rows_px}-row sensor, under a pixel in part of its range: the sub-pixel peak leans towards row "
            f"centres and the points' stated sigma does not hold it; a wider line (line_width_mm "
            f"{probe.line_width_mm:g}) or more rows")


def wide_line_warning(config: ScanConfig) -> str | None:
    """A line imaged wider than the detector takes ([detect] max_width_px) everywhere in the
    range on a surface seen square on: only surfaces tilted towards a camera, which narrow
    its image, can be measured (wider still, over WIDE_MARGIN times, blind_settings refuses
    it). A user's 50 mm line, 43-60 px against 25, measured nothing on a block."""
    widths, top = line_widths_px(config.probe), config.detect_params.max_width_px
    if not widths or min(widths) <= top:
        return None
    return (f"the laser line images {min(widths):.3g}-{max(widths):.3g} px wide (FWHM) on the probe's "
            f"{config.probe.rows_px}-row sensor, wider than the detector takes ([detect] max_width_px {top:g}) on a "
            f"surface seen square on: only surfaces tilted towards a camera can be measured; a narrower line "
            f"(line_width_mm {config.probe.line_width_mm:g}), fewer rows, or a larger max_width_px")


def blind_settings(config: ScanConfig) -> str | None:
    """A setting that leaves every column of every frame without a point, known before the
    first render: the laser line narrower on the sensor than any pixel can catch or wider
    than the detector takes everywhere in the range, a detection threshold above the
    laser's own peak, or segment ends that drop every column. None where there is none."""
    probe, detect, cleaning = config.probe, config.detect_params, config.profile_filter
    if 2 * cleaning.edge_px >= probe.cols_px:
        return (f"[triangulate] edge_px = {cleaning.edge_px} drops that many columns at each end of every run of "
                f"points, and the sensor has {probe.cols_px}: every point would go; give fewer (default "
                f"{DEFAULT_FILTER.edge_px})")
    if detect.min_peak >= config.render.laser_peak and config.material in DIFFUSE_SURFACES and config.sensor.ideal:
        # A diffuse part is never brighter than the line's peak (a glossy one may glint above
        # it, and a realistic sensor's exposure and gain scale the image).
        return (f"[detect] min_peak = {detect.min_peak:g} is not below the laser's peak {config.render.laser_peak:g} "
                f"([render] laser_peak): no line on a diffuse part is ever bright enough to count; lower min_peak "
                f"or raise laser_peak")
    z0, z1 = probe.z_range_mm
    widths = line_widths_px(probe)
    if not widths:
        # The camera's view spans the plane across about the range's depth: a shallow range or
        # a short baseline (cameras nearly on the laser's axis) each shrink it to nothing.
        fix = ("a deeper range (range_mm) or a wider baseline (a_mm)" if z1 - z0 < SHALLOW_RANGE_MM else
               "a wider baseline (a_mm) or a probe whose cameras look at the laser plane across its range")
        return (f"camera 0 does not image the laser plane {WIDTH_STEP_MM * 1e3:g} µm either side of the line's "
                f"middle anywhere in the probe's range {z0:g}-{z1:g} mm ({z1 - z0:.4g} mm deep; a_mm {probe.a_mm:g}, "
                f"phi {math.degrees(probe.phi_rad):.3g}°, gamma {math.degrees(probe.gamma_rad):.3g}°): its view "
                f"cannot hold the line; {fix}")
    # A surface tilted towards a camera narrows the line's image: refuse only a line that stays
    # too wide even so (three times over, more than the incidence limit's foreshortening gives).
    if widths and min(widths) > WIDE_MARGIN * detect.max_width_px:
        return (f"the laser line is {min(widths):.3g}-{max(widths):.3g} px wide (FWHM) on the probe's {probe.rows_px}-row "
                f"sensor across its range, over {WIDE_MARGIN:g} times what the detector takes ([detect] max_width_px "
                f"{detect.max_width_px:g}) on any surface: a narrower line (line_width_mm) or fewer rows")
    point_sampled = config.sensor.ideal and config.render.filter_width_px < 0.5  # no pixel gathers a thin line's light
    if widths and max(widths) < MIN_LINE_PX and point_sampled:
        return (f"the laser line is at most {max(widths):.3g} px wide (FWHM) on the probe's {probe.rows_px}-row sensor, "
                f"too thin for any pixel to catch: a wider line (line_width_mm {probe.line_width_mm:g}) or more rows")
    return None


def plan_frames(config: ScanConfig, q: np.ndarray, table_rad: np.ndarray, allow_blind: bool = False,
                warnings: list | None = None, surfaces: SurfaceCaster | None = None) -> Plan:
    """The plan for frames whose joints are known (q (n, 6), table_rad (n,)): the laser fan cast
    against the part and the table (``surfaces``, built here when not given) for the cameras to
    render and the rows the line can fall on, and against the fixtures (``fixture_frames``,
    the frames' indices)."""
    blind = blind_settings(config)
    if blind:
        raise InputError(f"nothing could be measured: {blind}")
    wp_probe2table = config.cell.probe2table(q, table_rad)
    surfaces = surfaces or cell_surfaces(config)
    foot = laser_footprint(config.probe, wp_probe2table, surfaces)
    warnings = [] if warnings is None else warnings
    n = len(q)
    if foot.empty_frames and not allow_blind:
        z0, z1 = config.probe.z_range_mm
        raise ScannerError(f"{len(foot.empty_frames)} of {n} waypoints put no surface inside the probe's "
                           f"range {z0:.4g}-{z1:.4g} mm (frames {frame_ranges(foot.empty_frames)}): "
                           f"{out_of_range_text(foot, z0, z1)}")
    cameras = foot.cameras_needed() if config.leave_out.skip_blind_cameras or allow_blind else (0, 1)
    if not cameras and not allow_blind:
        raise ScannerError("neither camera sees the laser line anywhere on the path (hidden or off the sensors)")
    predicted = np.full((n, 2), np.nan)
    if cameras:
        with np.errstate(all="ignore"), catch_warnings():
            simplefilter("ignore", RuntimeWarning)  # frames no camera sees: NaN, as meant
            rows = foot.rows[:, list(cameras)]
            predicted = np.column_stack([np.nanmin(rows[:, :, 0], axis=1), np.nanmax(rows[:, :, 1], axis=1)])
    fixtures = fixtures_in_the_way(config, wp_probe2table, table_rad, surfaces)
    return Plan(np.asarray(q, dtype=np.float64), np.asarray(table_rad, dtype=np.float64), cameras, predicted,
                warnings, fixture_frames=fixtures, empty_frames=list(foot.empty_frames))


# Rays of the laser fan cast per frame against the world fixtures: one per sensor column, at
# most this many (the default probe's 160 put them 1.6 mm apart at 215 mm, so a rod or a
# fence wire of a few mm is not missed between two rays).
FIXTURE_RAYS = 256

_FIXTURE_CASTERS: list = []  # (the config's fixtures tuple, [(world fixture name, SurfaceCaster)])


def out_of_range_text(foot, z0: float, z1: float) -> str:
    """Why the footprint's empty frames measure nothing and which way to move: the laser's
    nearest surface nearer than the range, farther, or none at all."""
    depth = foot.depth_mm[foot.empty_frames]
    with catch_warnings():
        simplefilter("ignore", RuntimeWarning)  # frames that meet nothing: NaN, as meant
        nearest = np.nanmin(depth, axis=1)
    said = []
    near, far = nearest < z0, nearest > z1

    def span(d):
        lo, hi = f"{np.min(d):.0f}", f"{np.max(d):.0f}"
        return f"{lo} mm" if lo == hi else f"{lo}-{hi} mm"

    if near.any():
        said.append(f"{'on ' + str(int(near.sum())) + ' of them ' if not near.all() else ''}the laser meets a "
                    f"surface {span(nearest[near])} from the probe, nearer than "
                    f"its {z0:.4g} mm: move the path away from it")
    if far.any():
        said.append(f"{'on ' + str(int(far.sum())) + ' of them ' if not far.all() else ''}the nearest surface lies "
                    f"{span(nearest[far])} away, beyond the probe's "
                    f"{z1:.0f} mm: move the path closer")
    none = np.isnan(nearest)
    if none.any():
        said.append(f"{'on ' + str(int(none.sum())) + ' of them ' if not none.all() else ''}the laser meets "
                    "nothing: aim it at the part")
    return "; ".join(said) + " (the surface the laser meets first: the part, the table or a fixture)"


def fixtures_in_the_way(config: ScanConfig, probe2table: np.ndarray, table_rad: np.ndarray,
                        surfaces: SurfaceCaster) -> dict:
    """{fixture name: frame indices (into probe2table)} where a world fixture stands in the
    laser fan's way inside the probe's range before the part, the table or its fixtures, or on
    the sight line between a spot the fan lights there and a camera that would see it (the spot
    inside the camera's image and not hidden by what ``surfaces`` holds). World fixtures (walls,
    posts beside the cell) are collision bodies only: no engine renders them, so such a fixture
    would not hide what lies behind it; the scan warns of it instead of passing it over. Table
    fixtures are rendered with the part (see :func:`table_fixtures`) and are never warned of.
    The rays are carried into the robot base's frame per frame."""
    world = tuple(f for f in config.fixtures if f.on == "world")
    if not world or not len(probe2table):
        return {}
    casters = next((c for f, c in _FIXTURE_CASTERS if f is config.fixtures), None)
    if casters is None:
        casters = [(f.name, SurfaceCaster([f.mesh])) for f in world]
        _FIXTURE_CASTERS.insert(0, (config.fixtures, casters))
        del _FIXTURE_CASTERS[4:]
    probe = config.probe
    table_rad = np.asarray(table_rad, dtype=np.float64)
    n, rays = len(probe2table), min(probe.cols_px, FIXTURE_RAYS)
    alpha = np.linspace(-probe.fan_rad / 2, probe.fan_rad / 2, rays)
    origins, dirs = fan_rays(probe, probe2table, rays)
    reach = np.tile(probe.z_range_mm[1] / np.cos(alpha), n)  # each ray's distance to the range's far end
    nearest = reach.copy()
    pts, ray, _ = surfaces.caster.intersects_location(origins, dirs, multiple_hits=False)
    nearest[ray] = np.minimum(reach[ray], np.linalg.norm(pts - origins[ray], axis=1))
    # (origins, unit directions, lengths, frames) of the rays a fixture must not cross: the fan up
    # to what it lights, and each camera's sight line to a spot it lit.
    o, d, length, frame = [origins], [dirs], [nearest], [np.arange(n * rays) // rays]
    lit = np.linalg.norm(pts - origins[ray], axis=1) <= reach[ray]
    spot, f = pts[lit], ray[lit] // rays
    if len(spot):
        R, t = probe2table[f, :3, :3], probe2table[f, :3, 3]
        spot_probe = np.einsum("nji,nj->ni", R, spot - t)  # Rᵀ (p − t)
        for camera in CAMERAS:  # the sight lines from each camera that sees a spot, up to it
            _, seen = seen_by(probe, surfaces.caster, camera, R, t, spot, spot_probe)
            centre = np.einsum("nij,j->ni", R[seen], probe.cam2probe(camera)[:3, 3]) + t[seen]
            to_spot = spot[seen] - centre
            dist = np.linalg.norm(to_spot, axis=1)
            o.append(centre), d.append(to_spot / dist[:, None]), length.append(dist - OCCLUSION_EPS_MM)
            frame.append(f[seen])
    o, d, length, frame = (np.concatenate(a) for a in (o, d, length, frame))
    to_base = config.cell.table.table2base(table_rad[frame])
    world_o = np.einsum("nij,nj->ni", to_base[:, :3, :3], o) + to_base[:, :3, 3]
    world_d = np.einsum("nij,nj->ni", to_base[:, :3, :3], d)
    out = {}
    for name, caster in casters:
        pts, ray, _ = caster.caster.intersects_location(world_o, world_d, multiple_hits=False)
        met = ray[np.linalg.norm(pts - world_o[ray], axis=1) < length[ray]]
        if len(met):
            out[name] = np.unique(frame[met])
    return out


def fixture_warnings(fixture_frames: dict, frames: int) -> list[str]:
    """One warning per fixture in the way (see :func:`fixtures_in_the_way`)."""
    return [f"{name} stands in the laser's way or hides its line from a camera at {len(idx)} of {frames} frames "
            f"({frame_ranges(list(idx))}): fixtures on = \"world\" are collision bodies only, not rendered, so the cloud shows "
            f"what lies behind {name} as if it were not there" for name, idx in fixture_frames.items()]


def table_fixtures(config: ScanConfig) -> tuple:
    """The fixtures that turn with the table: every engine renders them with the part, so they
    hide and shadow it and their points join the cloud (counted apart from the part's)."""
    return tuple(f for f in config.fixtures if f.on == "table")


def frames_in_range(config: ScanConfig) -> ScanConfig:
    """``config`` with only the waypoints whose laser puts some surface (the part, the table,
    a table fixture) inside the probe's range: for a path laid out from the part's box alone
    (``kinematics.path.around_part``), whose sweep ends may look past the part at a table
    beyond a short-range probe's reach."""
    foot = laser_footprint(config.probe, config.waypoints.probe2table, cell_surfaces(config))
    keep = np.setdiff1d(np.arange(len(config.waypoints)), foot.empty_frames)
    if len(keep) == len(config.waypoints):
        return config
    if not len(keep):
        z0, z1 = config.probe.z_range_mm
        raise InputError(f"none of the {len(config.waypoints)} frames of the path puts the part, the table or a "
                         f"fixture inside the probe's range {z0:.4g}-{z1:.4g} mm: check the probe's optics "
                         f"(a, b, φ, γ) and the part's size")
    from dataclasses import replace

    return replace(config, waypoints=config.waypoints.select(keep))


FIXTURE_OVERLAP_MM = 0.05  # a table fixture may touch the part; reaching further into it is warned of
OVERLAP_SAMPLES = 20000    # surface points drawn from each of the two meshes for the check
_PART_LINES: list = []  # ((workpiece, fixtures, probe, detector), warnings) of the last few configs checked


def part_warnings(config: ScanConfig) -> list[str]:
    """What a scan should say about its part and probe before the figures are read: a mesh
    that is not closed (its error has no sign, so no bias), faces lying in the table top
    (drawn_mesh), a laser line narrower than a pixel or wider than the detector takes
    (narrow_line_warning, wide_line_warning), and table fixtures reaching into the part
    (:func:`fixtures_in_the_part`). Kept for the last few configs: a Scanner asks after every
    measurement."""
    from ..geometry.metrics import has_inside

    key = (config.workpiece, config.fixtures, config.probe, config.detect_params)
    known = next((lines for k, lines in _PART_LINES if all(a is b for a, b in zip(k, key))), None)
    if known is not None:
        return list(known)
    wp = config.workpiece
    out = list(wp.notes)
    if not wp.is_analytic and not has_inside(wp.mesh):
        if not wp.mesh.is_watertight:
            _, faces_per_edge = np.unique(wp.mesh.edges_sorted, axis=0, return_counts=True)
            open_edges, shared = int(np.sum(faces_per_edge == 1)), int(np.sum(faces_per_edge > 2))
            why = (f"is not closed ({open_edges} edge{'s border' if open_edges > 1 else ' borders'} one face "
                   f"only)" if open_edges else
                   f"is not one closed surface ({shared} edge{'s are' if shared > 1 else ' is'} shared by more "
                   f"than two faces)")
        elif not wp.mesh.is_winding_consistent:
            why = "is not wound consistently (its faces' normals disagree)"
        else:
            why = "cannot be signed here (libigl is missing)"
        out.append(f"the workpiece mesh {wp.name} {why}: its points' error has no sign, so no bias is given")
    drawn = drawn_mesh(wp)
    if drawn is None:
        out.append(f"the workpiece {wp.name} lies flat in the table top (z = 0): the laser meets the table there, "
                   f"so its points measure the table; lift it (in a config, [workpiece.pose] xyz_mm) or give it "
                   f"a thickness")
    elif drawn is not wp.mesh:
        out.append(f"{len(wp.mesh.faces) - len(drawn.faces)} faces of the workpiece {wp.name} lie in the table top "
                   f"(z = 0): the table is drawn there, and its points there measure the table")
    out += [w for w in (narrow_line_warning(config.probe), wide_line_warning(config)) if w]
    out += fixtures_in_the_part(config)
    _PART_LINES.insert(0, (key, out))
    del _PART_LINES[4:]
    return list(out)


def fixtures_in_the_part(config: ScanConfig) -> list[str]:
    """A warning for each table fixture that reaches into the part by more than
    FIXTURE_OVERLAP_MM (a real clamp touches it at most), judged by the signed distance of
    each mesh's vertices and of points spread over its surface (a rod through a box has no
    vertex inside it) to the other mesh; a fixture that is not a closed mesh cannot be judged
    so and is named instead. An inside-out closed mesh is turned right way out first."""
    out = []
    wp = config.workpiece
    part_points = None  # sampled once, for all the fixtures
    for f in table_fixtures(config):
        fixture = f.mesh
        if not (fixture.is_watertight and fixture.is_winding_consistent):
            out.append(f"{f.name} is not a closed mesh, so whether it reaches into the part was not checked")
            continue
        if fixture.volume < 0:  # inside out: its signed distances would call the outside inside
            fixture = fixture.copy()
            fixture.invert()
        lo, hi = fixture.bounds - 1.0, fixture.bounds + 1.0
        part_points = _surface_points(wp.mesh) if part_points is None else part_points
        P = part_points[np.all((part_points >= lo[0]) & (part_points <= hi[1]), axis=1)]
        depth = 0.0
        if len(P):
            _, signed = metrics.mesh_distances(P, fixture)
            depth = max(depth, float(-signed.min()))
        _, signed = metrics.distances(_surface_points(fixture), wp.truth)
        if signed is not None and len(signed):
            depth = max(depth, float(-signed.min()))
        if depth > FIXTURE_OVERLAP_MM:
            out.append(f"{f.name} reaches {depth:.2f} mm into the part, where a real one would touch it at most: "
                       f"the part's surface inside it is hidden and its points near the contact may count as the "
                       f"fixture's; move it out until it touches")
    return out


def _surface_points(mesh) -> np.ndarray:
    """A mesh's vertices and OVERLAP_SAMPLES points spread evenly (seeded) over its faces."""
    import trimesh

    spread, _ = trimesh.sample.sample_surface(mesh, OVERLAP_SAMPLES, seed=0)
    return np.vstack([mesh.vertices, spread])


def cell_surfaces(config: ScanConfig) -> SurfaceCaster:
    """What the laser can meet in a scan: the part as drawn (workpiece.drawn_mesh; its faces
    first, ``part_faces`` of them), the table top and the table's fixtures, ready for ray casts."""
    drawn = drawn_mesh(config.workpiece)
    part = [] if drawn is None else [drawn]
    return SurfaceCaster([*part, table_top_mesh(), *(f.mesh for f in table_fixtures(config))],
                         part_faces=0 if drawn is None else len(drawn.faces))
