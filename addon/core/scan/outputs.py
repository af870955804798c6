"""A scan's result: the cloud measured against the truth (points nearer the part count as the
part's, the rest as the table's), the report, and cloud.ply, report.json and preview.png
written atomically, all at the end."""

from __future__ import annotations

import functools
import platform
import sys
import time
from importlib import metadata
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from ..config.render import with_sensor
from ..config.scan import ScanConfig
from ..files import png_bytes, write_set
from ..geometry import metrics
from ..geometry.cloud import Cloud, ply_bytes
from ..geometry.footprint import measurable_points
from ..geometry.surface_fit import across_line
from ..optics.detect import LineCode
from ..optics.sensor import EFFECTS, SensorModel
from ..kinematics.turntable import TABLE_RADIUS_MM, TABLE_SECTIONS, TABLE_THICKNESS_MM, table_top_mesh
from .plan import Plan, cell_surfaces, fixture_warnings, table_fixtures
from .preview import render_preview
from .report import report_json


@dataclass
class ScanResult:
    """cloud (table frame); report (the report.json content, but for figures with no finite
    value: NaN or inf here, null once written by report_json); files written; per point:
    |error| in µm to what it counts as (the part, the table's disc or a fixture), whether the
    point counts as the part's, and whether as one of the table's fixtures' (neither: the
    table's)."""

    cloud: object
    report: dict
    files: dict
    error_um: np.ndarray | None = None
    on_part: np.ndarray | None = None
    on_fixture: np.ndarray | None = None


# Packages whose version a scan's figures depend on, where installed: the distribution's name.
VERSIONED = {"trimesh": "trimesh", "embreex": "embreex", "libigl": "libigl", "python-fcl": "python-fcl"}


# The extension's manifest: beside the addon package, in the repository and in the installed extension alike.
MANIFEST = Path(__file__).resolve().parents[3] / "blender_manifest.toml"


@functools.cache
def simulator_version() -> str | None:
    """This simulator's version, from its manifest (None where the manifest cannot be read);
    read once per process."""
    import tomllib

    try:
        return str(tomllib.loads(MANIFEST.read_text(encoding="utf-8"))["version"])
    except (OSError, ValueError, KeyError):
        return None


def blender_version() -> str | None:
    """The version of the Blender loaded in this process (None: none is; this core never
    imports it)."""
    bpy = sys.modules.get("bpy")
    return bpy.app.version_string if bpy is not None and hasattr(bpy, "app") else None


def software_versions(blender: str | None = None) -> dict:
    """What produced a scan: this simulator's version, Python, numpy, OpenCV, Blender (``blender``
    where given: a farm's workers'; else the one loaded here, None where none is: this core
    never imports it), and the geometry packages installed. The keys keep one order."""
    out = {"scanner": simulator_version(), "python": platform.python_version(), "numpy": np.__version__,
           "opencv": cv2.__version__, "blender": blender or blender_version()}
    for key, dist in VERSIONED.items():
        try:
            out[key] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            pass
    return out

SMALL_SHARE = 0.05  # a path measuring less of its part than this is said to miss most of it
SATURATED_SHARE = 0.1  # saturated columns, of those that saw a line, above which a scan says so


def assemble(config: ScanConfig, plan: Plan, cloud, stats: dict, timing: dict, out_dir: str | Path | None,
             t_start: float, extra: dict | None = None, step_by_step: bool = False,
             user_extra: dict | None = None) -> ScanResult:
    """The scan's result from its cloud and counters: error against the truth, the report,
    and (with ``out_dir``) cloud.ply, report.json and preview.png written atomically.
    ``step_by_step``: frames a Scanner took one by one (not a path), which, like frames picked
    from a path (``config.path_frames``), say nothing of how much of the part a path measures.
    ``extra`` joins the report (the caller's own fields: a farm's, the render device);
    ``user_extra`` too, but may not replace any of the report's fields."""
    probe = config.probe
    timing = dict(timing)
    t = time.perf_counter()
    poses = config.cell.probe2table(plan.q, plan.table_rad) if len(plan.q) else None
    cloud, stats = across_the_lines(cloud, stats, poses, config)
    timing["neighbours"] = time.perf_counter() - t
    t = time.perf_counter()
    quality, on_part, error_um, on_fixture = measure_against_truth(cloud, config, poses)
    timing["metrics"] = time.perf_counter() - t
    n = int(len(stats["band_rows"]))
    scan_time = timing.get("render", 0.0) + timing.get("detect", 0.0) + timing.get("triangulate", 0.0)
    r = with_sensor(config.render, config.sensor)  # as rendered: a sensor model may raise the samples
    warnings = list(plan.warnings) + fixture_warnings(plan.fixture_frames, len(plan.q))
    share = quality.get("measurable_share", 0.0)
    if n and not np.any(on_part) and not step_by_step:  # (a planner's poses may see nothing on purpose)
        what = "no point at all" if len(cloud) == 0 else f"{len(cloud)} points, none of them on the part"
        why = ("none of the laser rays sampled along the path (one per sensor column) meets the part within the "
               "probe's range and a camera's view: a path onto the part ([[path]] entries; the preview shows where "
               "the points are), or a part narrower than the line or a column's footprint" if share == 0 else
               f"the laser meets {share * 100:.1f} % of the part within the probe's range, and every column there was "
               f"dropped or found no line (see the points dropped after detection): the sensor's settings, the "
               f"detector's, or the probe's view of the part")
        codes = stats.get("codes", {})
        saturated = codes.get("SATURATED", 0)
        if saturated and saturated >= 0.5 * sum(v for k, v in codes.items() if k != "OK"):
            why += (f"; {saturated} of the columns were saturated, the line clipped at full scale: a shorter "
                    f"[sensor] exposure_ms or a lower gain (or auto_exposure)")
        warnings.append(f"the scan measured {what}: {why}")
    else:
        # Clipped lines are dropped column by column: a scan that lost most of its line to
        # saturation said nothing while any point survived (a hunt: 160 of 3 320 points left).
        codes = stats.get("codes", {})
        saturated, lit = codes.get("SATURATED", 0), sum(v for k, v in codes.items() if k != "NO_LINE")
        if saturated and saturated >= SATURATED_SHARE * lit:
            warnings.append(f"{saturated} of the {lit} sensor columns that saw a line ({saturated / lit * 100:.0f} %) "
                            f"were saturated, the line clipped at full scale, and dropped: a shorter [sensor] "
                            f"exposure_ms or a lower gain (or auto_exposure)")
    if n and np.any(on_part) and 0 < share < SMALL_SHARE and not step_by_step and config.path_frames is None:
        warnings.append(f"the path can measure only {share * 100:.1f} % of the part's surface (whole-part coverage "
                        f"{quality['coverage'] * 100:.1f} %): most of the part lies outside what it scans; "
                        "a path of the part's own size: [[path]] entries, or the adaptive planner")
    if not config.safety.check:
        # (report.json's clearance read null, as for a Scanner that measured without moving,
        # and the summary left the line out: a shared report did not say nothing was checked)
        warnings.append("collision checks were off ([safety] check = false): no motion was checked against the "
                        "table, the part or the fixtures")
    used = (extra or {}).get("render_device")
    if r.engine == "cycles" and r.device != "CPU" and used == "CPU":
        warnings.append(f"render device {r.device} asked for, but no such GPU answered: rendered on the CPU")
    report = {
        "config": {"name": config.name, "file": config.source, "robot": config.robot.name, "probe": probe.name,
                   "sensor_px": [probe.cols_px, probe.rows_px], "workpiece": config.workpiece.source,
                   # Where the part stood and how large it was read (a Scanner's part, loaded with a
                   # scale and put down by a script, left only its file's name)
                   "workpiece_pose": np.round(np.asarray(config.workpiece.pose, float), 9).tolist(),
                   "workpiece_size_mm": [round(float(v), 6) for v in config.workpiece.mesh.extents],
                   "engine": r.engine, "samples": r.samples, "detect": config.detect_method,
                   "triangulate": config.triangulate_method, "fuse": config.fuse,
                   "sensor": "ideal" if config.sensor.ideal else sensor_effects(config.sensor),
                   "sensor_settings": sensor_settings(config.sensor),
                   "material": config.material,
                   # The probe model triangulation used: None for the nominal (exact) probe, else
                   # the calibration file it came from.
                   "calibration": None if probe.calibration is None else (probe.calibration.source or "given"),
                   "fixtures": [{"name": f.name, "on": f.on} for f in config.fixtures],
                   # The path's frame number of each frame scanned, where --frames picked some
                   # (frames are numbered from 0 in the order picked); None: the whole path.
                   "path_frames": None if config.path_frames is None else [int(i) for i in config.path_frames]},
        "frames": n,
        "points": len(cloud),
        "valid_fraction": stats["valid"] / max(stats["columns"], 1),
        # Every code, sorted (the same file from the same scan, and the same keys from every
        # scan: a code no column met was missing, a KeyError for a reader).
        "column_codes": {name: int(stats["codes"].get(name, 0)) for name in sorted(c.name for c in LineCode)},
        # After detection: columns dropped on the way to a point, by reason (no detection, a ray
        # grazing the laser plane, out of the range, steep, a run's edge, the cameras in conflict),
        # and the points both cameras agreed on.
        "points_dropped": {k: v for k, v in sorted(stats.get("points", {}).items()) if k != "fused"},
        # Counted in the cloud as written: fused points that the neighbouring profiles then
        # dropped as uncertain are not in it (camera 3: both cameras, optics.triangulate).
        "points_fused": int(np.sum(cloud.camera == 3)),
        "cameras_rendered": list(plan.cameras),
        "frames_rerendered_full": stats["rerendered"],
        "mean_rows_rendered": float(np.mean(stats["band_rows"])) if stats["band_rows"] else 0.0,
        "time_s": {k: round(v, 4) for k, v in timing.items()},
        "profiles_per_s": n / scan_time if scan_time > 0 else float("inf"),
        **quality,
        # The smallest distance between the robot or the probe and the table, the workpiece or a
        # fixture, over the whole motion and per path entry, with where it occurs (None: not checked).
        "clearance": None if plan.clearance is None else plan.clearance.report(),
        "warnings": warnings,
        "software": software_versions(),
        **(extra or {}),
    }
    # A caller's own record (Scanner.result's extra) joins the report; it may not replace the
    # report's fields ({"frames": 999} made a report of 999 frames).
    clash = sorted(set(user_extra or {}) & set(report))
    if clash:
        from ..errors import InputError

        raise InputError(f"extra: {', '.join(map(repr, clash))} {'is' if len(clash) == 1 else 'are'} the report's own "
                         f"(frames, points, config, ...); give your record under keys of its own, e.g. "
                         f"{{\"mine\": {{...}}}}")
    report.update(user_extra or {})
    report["time_s"]["total"] = round(time.perf_counter() - t_start, 4)
    result = ScanResult(cloud, report, {}, error_um, on_part, on_fixture)
    return result if out_dir is None else written(result, config, out_dir, t_start)


def written(result: ScanResult, config: ScanConfig, out_dir: str | Path, t_start: float) -> ScanResult:
    """``result`` written into ``out_dir``: the same result with its files, and its report's
    time_s gaining the writing and the new total (the given result is left as it was)."""
    report = {**result.report, "time_s": dict(result.report["time_s"])}
    files = write_outputs(Path(out_dir), result.cloud, report, config, result.on_part, result.error_um, t_start,
                          result.on_fixture)
    return replace(result, report=report, files=files)


def across_the_lines(cloud: Cloud, stats: dict, poses, config: ScanConfig) -> tuple[Cloud, dict]:
    """The cloud judged by each point's neighbouring profiles (geometry.surface_fit): points on
    surfaces steeper than the filter's limit across the line dropped ("steep_surface"), every
    σ widened by the line's width on the curvature across it, and points whose σ then exceeds
    the filter's limit dropped ("uncertain"). Off with the profile filter's incidence limit."""
    f = config.profile_filter
    if poses is None or not len(cloud) or f.max_incidence_deg >= 90:
        return cloud, stats
    z0, z1 = config.probe.z_range_mm
    steep, across = across_line(cloud.points, cloud.frame, poses, config.probe.line_width_mm, 0.5 * (z0 + z1),
                                f.max_incidence_deg)
    sigma = np.hypot(cloud.quality.astype(np.float64), across)
    uncertain = ~steep & (sigma > f.max_sigma_mm)
    keep = ~(steep | uncertain)
    out = Cloud(cloud.points[keep], cloud.frame[keep], cloud.camera[keep], sigma[keep])
    stats = dict(stats)
    points = dict(stats.get("points", {}))
    points["steep_surface"] = points.get("steep_surface", 0) + int(steep.sum())
    points["uncertain"] = points.get("uncertain", 0) + int(uncertain.sum())
    stats["points"] = points
    return out, stats


def sensor_effects(sensor) -> list[str]:
    return [n for n in EFFECTS if getattr(sensor, n)] + (["distortion"] if sensor.distortion else [])


def sensor_settings(sensor) -> dict:
    """The sensor model's parameters that differ from its defaults ({} for the ideal sensor):
    two sensors with the same effects on (undistorted or not, another exposure) read apart."""
    from dataclasses import fields

    if sensor.ideal:
        return {}
    default = SensorModel()
    out = {}
    for f in fields(sensor):
        if f.name.startswith("_") or f.name in EFFECTS:
            continue
        value, was = getattr(sensor, f.name), getattr(default, f.name)
        if value != was:
            out[f.name] = list(value) if isinstance(value, tuple) else value
    return out


def measurable_coverage(config: ScanConfig, probe2table: np.ndarray, part_points: np.ndarray) -> dict:
    """The coverage of the surface the path's laser can measure (in range, within the profile
    filter's incidence limit, seen by a camera) and that surface's share of the part."""
    if len(probe2table) == 0:
        return {"coverage_measurable": 0.0, "measurable_share": 0.0}
    surfaces = cell_surfaces(config)  # the table's fixtures hide the part as rendered
    reachable = measurable_points(config.probe, probe2table, surfaces, surfaces.part_faces,
                                  config.profile_filter.max_incidence_deg)
    cov, share = metrics.coverage_of_measurable(part_points, config.workpiece.mesh, reachable,
                                                config.coverage_tolerance_mm)
    return {"coverage_measurable": cov, "measurable_share": share}


RIM_SLACK_MM = 0.5  # points this far beyond the table's rim, seen from above, may still be its side's


@functools.lru_cache(maxsize=1)
def _disc():
    return table_top_mesh()


def table_distances(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(unsigned, signed (outside positive)) mm from points (n, 3), table frame, to the table's
    disc as drawn: its top, its side and its bottom (the side's points were measured against
    the top's plane, 13 mm off, and beside a part overhanging the rim counted as the part's);
    inf beyond the rim."""
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    r, z = np.hypot(P[:, 0], P[:, 1]), P[:, 2]
    unsigned, signed = np.abs(z), z.copy()
    # Over the top face, well inside the side (the polygon's inner radius) and the bottom: the
    # top's plane is the nearest of the disc's faces.
    inner = TABLE_RADIUS_MM * np.cos(np.pi / TABLE_SECTIONS)
    elsewhere = (r <= TABLE_RADIUS_MM + RIM_SLACK_MM) & ~((r <= inner - np.maximum(-z, 0.0)) & (z > -TABLE_THICKNESS_MM / 2))
    if elsewhere.any():
        d, s = metrics.mesh_distances(P[elsewhere], _disc())
        if s is None:  # (a Python without libigl signs nothing: the disc is solid, ask it what is inside)
            s = np.where(_disc().contains(P[elsewhere]), -d, d)
        unsigned[elsewhere], signed[elsewhere] = d, s
    beyond = r > TABLE_RADIUS_MM + RIM_SLACK_MM
    unsigned[beyond], signed[beyond] = np.inf, np.inf
    return unsigned, signed


def measure_against_truth(cloud, config: ScanConfig, probe2table: np.ndarray | None = None
                          ) -> tuple[dict, np.ndarray, np.ndarray, np.ndarray]:
    """Error against the truth: points nearer the part count as the part's, those nearer one of
    the table's fixtures (rendered with the part) as the fixtures', the rest as the table's;
    coverage of the whole part and (given the frames' probe poses) of what the path can measure.

    Returns (report entries, on_part (n,) bool, |error| (n,) µm to what each point counts as,
    on a fixture (n,) bool)."""
    wp = config.workpiece
    P = cloud.points
    poses = np.zeros((0, 4, 4)) if probe2table is None else probe2table
    if len(P) == 0:
        return ({"points_on_part": 0, "points_on_table": 0, "points_on_fixtures": 0,
                 "outliers": 0, "within_2_sigma": None,
                 "error_um": metrics.error_stats([]).as_dict(),
                 "table_error_um": metrics.error_stats([]).as_dict(), "coverage": 0.0,
                 **measurable_coverage(config, poses, P),
                 "coverage_tolerance_mm": config.coverage_tolerance_mm}, np.zeros(0, bool), np.zeros(0), np.zeros(0, bool))
    d_part, s_part = metrics.distances(P, wp.truth)
    d_table, s_table = table_distances(P)
    on_fixture = np.zeros(len(P), bool)  # nearer one of the table's fixtures than the part and the table top
    fixtures = table_fixtures(config)
    for f in fixtures:
        on_fixture |= metrics.NearMesh(f.mesh).within(P, np.minimum(d_part, d_table))
    on_part = (d_part <= d_table) & ~on_fixture
    on_table = ~on_part & ~on_fixture
    # Each point's error against what it counts as (the cloud object's error_um: a table point
    # read its distance to the part, tens of millimetres).
    d_own = np.where(on_part, d_part, d_table)
    if on_fixture.any():
        d_own[on_fixture] = np.min([metrics.unsigned_distances(P[on_fixture], f.mesh) for f in fixtures], axis=0)
    part = metrics.error_stats(d_part[on_part], None if s_part is None else s_part[on_part])
    table = metrics.error_stats(d_table[on_table], s_table[on_table])
    coverage = metrics.coverage(P[on_part], wp.mesh, config.coverage_tolerance_mm)
    d = d_part[on_part]
    within = float(np.mean(d <= 2.0 * cloud.quality[on_part])) if len(d) else None
    return ({"points_on_part": int(on_part.sum()), "points_on_table": int(on_table.sum()),
             "points_on_fixtures": int(on_fixture.sum()),
             "outliers": int(np.sum(d > metrics.OUTLIER_MM)), "within_2_sigma": within,
             "error_um": part.as_dict(), "table_error_um": table.as_dict(), "coverage": coverage,
             **measurable_coverage(config, poses, P[on_part]),
             "coverage_tolerance_mm": config.coverage_tolerance_mm}, on_part, d_own * 1e3, on_fixture)


OUTPUT_FILES = {"cloud": "cloud.ply", "report": "report.json", "preview": "preview.png"}


def preview_title(name: str, points: int, report: dict) -> str:
    """The preview picture's title: the points, their error and the coverage."""
    e = report["error_um"]
    covered = f"{report['coverage'] * 100:.0f} % of the whole part"
    if report.get("measurable_share"):  # the share of what the path can measure comes first, as in the summary
        # (not the whole part's in brackets: there the summary gives the share the path can measure)
        covered = f"{report['coverage_measurable'] * 100:.0f} % of what the path can measure, {covered}"
    # (no point on the part: its statistics are NaN here, null once written)
    error = (f"RMS {e['rms_um']:.1f} um, p95 {e['p95_um']:.1f} um" if e.get("n") else "no point on the part")
    title = f"{name}: {points} points, {error}, covers {covered}"
    if report.get("points_on_fixtures"):
        title += f", {report['points_on_fixtures']} on fixtures"
    return title


def write_outputs(out: Path, cloud, report: dict, config: ScanConfig, on_part, err, t_start: float,
                  on_fixture=None) -> dict:
    """cloud.ply, report.json and preview.png into ``out``, all together or none (files.write_set);
    the report's time_s gains the time taken to make them ("write") and the total."""
    t = time.perf_counter()
    title = preview_title(config.name, len(cloud), report)
    picture = render_preview(config.workpiece.mesh, cloud.points, err, on_part, title, on_fixture=on_fixture)
    contents = {"cloud.ply": ply_bytes(cloud), "preview.png": png_bytes(picture)}
    report["time_s"]["write"] = round(time.perf_counter() - t, 4)
    report["time_s"]["total"] = round(time.perf_counter() - t_start, 4)
    contents["report.json"] = report_json(report).encode()
    written = write_set(out, contents)
    return {key: written[name] for key, name in OUTPUT_FILES.items()}
