"""Where the laser will fall, found by casting its fan against the scene's meshes before rendering.

For every frame, ``rays`` rays leave the probe origin in the laser plane, spread
over the fan angle; their first hits on the workpiece or the table are the line
the cameras would see. From that:

- frames whose laser meets no surface inside the probe's range [z_min, z_max]
  give no data (reported before rendering, by index);
- a camera that sees none of those points, over the whole path (off its sensor
  or hidden behind the part), need not be rendered.

Ray casting is trimesh's, through Embree when the ``embreex`` package is there
(17x faster; single precision, ample for this check) and trimesh's own triangle
tests otherwise; it runs in the table frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from ..optics.probe import Probe

OCCLUSION_EPS_MM = 0.05  # slack for "the first surface on the camera's ray is the lit point" (Embree is float32)


def _intersector(mesh: trimesh.Trimesh):
    try:
        from trimesh.ray.ray_pyembree import RayMeshIntersector

        return RayMeshIntersector(mesh)
    except (ImportError, ModuleNotFoundError):
        return trimesh.ray.ray_triangle.RayMeshIntersector(mesh)


@dataclass
class Footprint:
    """depth_mm (n, k): z in the probe frame of each fan ray's first hit (NaN: no hit);
    in_range (n, k); seen (n, 2): fan points each camera sees (in range, on its sensor, not hidden);
    rows (n, 2, 2): per frame and camera, the lowest and highest sensor row of those points (NaN: none)."""

    depth_mm: np.ndarray
    in_range: np.ndarray
    seen: np.ndarray
    rows: np.ndarray

    @property
    def empty_frames(self) -> list[int]:
        """Frames where no fan ray hits a surface inside the probe's range."""
        return [int(i) for i in np.nonzero(~self.in_range.any(axis=1))[0]]

    def cameras_needed(self) -> tuple[int, ...]:
        return tuple(c for c in (0, 1) if self.seen[:, c].any())


class SurfaceCaster:
    """The cell's surfaces (table frame) with their ray-casting structure built once: a
    step-by-step scanner casts a few rays per measurement, and building the structure
    (about 0.1 s for the demo) would cost more than the casting. ``part_faces``: how many of
    the first faces are the part's (where the caller says)."""

    def __init__(self, meshes: list[trimesh.Trimesh], part_faces: int = 0):
        self.mesh = trimesh.util.concatenate(meshes)
        self.caster = _intersector(self.mesh)
        self.part_faces = int(part_faces)

    # The ray-casting structure (Embree's scene) cannot be pickled: it is built again on loading.
    def __getstate__(self) -> dict:
        return {"mesh": self.mesh, "part_faces": self.part_faces}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self.caster = _intersector(self.mesh)


# A surface exactly at a range end must count as in range: the probe's pose comes from the
# robot's joints and reads it 1e-13 mm off (a plate at 70 mm read 69.99999999999989 on one
# machine and was refused), and Embree's hits are single precision (about 1e-5 mm at this
# range). The range test allows this much.
RANGE_SLACK_MM = 1e-3


def fan_rays(probe: Probe, poses: np.ndarray, rays: int) -> tuple[np.ndarray, np.ndarray]:
    """(origins, directions) (n·rays, 3) of the laser fan of probe poses (n, 4, 4), ``rays``
    spread evenly over the fan's angle; frame i's rays are rows i·rays to (i+1)·rays − 1."""
    alpha = np.linspace(-probe.fan_rad / 2, probe.fan_rad / 2, rays)
    local = np.column_stack([np.zeros(rays), np.sin(alpha), np.cos(alpha)])
    dirs = np.einsum("nij,kj->nki", poses[:, :3, :3], local).reshape(-1, 3)
    return np.repeat(poses[:, :3, 3], rays, axis=0), dirs


def laser_footprint(probe: Probe, probe2table: np.ndarray, meshes: list[trimesh.Trimesh] | SurfaceCaster,
                    rays: int = 65) -> Footprint:
    """Cast the laser fan for frames with probe poses ``probe2table`` (n, 4, 4) against ``meshes``
    (table frame; or a SurfaceCaster built from them once)."""
    caster = (meshes if isinstance(meshes, SurfaceCaster) else SurfaceCaster(meshes)).caster
    n = len(probe2table)
    alpha = np.linspace(-probe.fan_rad / 2, probe.fan_rad / 2, rays)
    R, t = probe2table[:, :3, :3], probe2table[:, :3, 3]
    origins, dirs = fan_rays(probe, probe2table, rays)
    hit_pts, hit_ray = _first_hits(caster, origins, dirs)
    dist = np.full(n * rays, np.nan)
    dist[hit_ray] = np.linalg.norm(hit_pts - origins[hit_ray], axis=1)
    depth = (dist.reshape(n, rays) * np.cos(alpha)[None, :])
    z0, z1 = probe.z_range_mm
    with np.errstate(invalid="ignore"):
        in_range = (depth >= z0 - RANGE_SLACK_MM) & (depth <= z1 + RANGE_SLACK_MM)
    points = origins + dirs * dist[:, None]  # table frame; NaN where no hit
    seen = np.zeros((n, 2), dtype=int)
    rows = np.full((n, 2, 2), np.nan)
    frame_of = np.repeat(np.arange(n), rays)
    lit = np.nonzero(in_range.ravel())[0]
    if lit.size:
        target = points[lit]
        Rf, tf = R[frame_of[lit]], t[frame_of[lit]]
        local = np.einsum("nji,nj->ni", Rf, target - tf)  # into the probe frame: Rᵀ (p − t)
        for camera in (0, 1):
            uv, visible = seen_by(probe, caster, camera, Rf, tf, target, local)
            np.add.at(seen[:, camera], frame_of[lit[visible]], 1)
            f, v = frame_of[lit[visible]], uv[visible, 1]
            lo = np.full(n, np.inf)
            hi = np.full(n, -np.inf)
            np.minimum.at(lo, f, v)
            np.maximum.at(hi, f, v)
            got = np.isfinite(lo)
            rows[got, camera, 0], rows[got, camera, 1] = lo[got], hi[got]
    return Footprint(depth, in_range, seen, rows)


def seen_by(probe: Probe, caster, camera: int, Rf: np.ndarray, tf: np.ndarray, target: np.ndarray,
            local: np.ndarray):
    """Sensor coordinates (m, 2) of points ``target`` (table frame; ``local`` in the probe frame
    of poses Rf, tf) in ``camera``, and whether the camera sees each: on its sensor, and the
    first surface along its ray is the point itself."""
    uv = probe.project(local, camera)
    on_sensor = np.isfinite(uv).all(axis=1)
    centre = tf + np.einsum("nij,j->ni", Rf, probe.cam2probe(camera)[:3, 3])
    to = target - centre
    length = np.linalg.norm(to, axis=1)
    occ_pts, occ_ray = _first_hits(caster, centre, to / length[:, None])
    first = np.full(len(target), np.inf)
    first[occ_ray] = np.linalg.norm(occ_pts - centre[occ_ray], axis=1)
    return uv, on_sensor & (first >= length - OCCLUSION_EPS_MM)


def measurable_points(probe: Probe, probe2table: np.ndarray, surfaces: SurfaceCaster, part_faces: int,
                      max_incidence_deg: float = 90.0, rays: int | None = None, chunk: int = 200) -> np.ndarray:
    """Points (m, 3) mm, table frame, on the part that the path's laser can measure: first hits
    of the fan (``rays`` per frame, default one per sensor column) on the part (the first
    ``part_faces`` faces of ``surfaces``) inside the probe's range, within ``max_incidence_deg``
    of the face's normal, and seen by at least one camera."""
    points, _, seen = measurable_hits(probe, probe2table, surfaces, part_faces, max_incidence_deg, rays, chunk)
    return points[seen.any(axis=0)]


def measurable_hits(probe: Probe, probe2table: np.ndarray, surfaces: SurfaceCaster, part_faces: int,
                    max_incidence_deg: float = 90.0, rays: int | None = None, chunk: int = 200
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The fan's first hits on the part in range and within the incidence limit, as in
    :func:`measurable_points`, before the cameras are asked: (points (m, 3) mm, table frame;
    frame (m,) index into ``probe2table``; seen (2, m) bool, by camera 0 and camera 1)."""
    rays = rays or probe.cols_px
    normals = surfaces.mesh.face_normals
    cos_limit = np.cos(np.radians(min(max_incidence_deg, 90.0)))
    z0, z1 = probe.z_range_mm
    out_points, out_frames, out_seen = [], [], []
    for start in range(0, len(probe2table), chunk):
        T = probe2table[start:start + chunk]
        R, t = T[:, :3, :3], T[:, :3, 3]
        origins, dirs = fan_rays(probe, T, rays)
        if len(origins) == 0:
            continue
        pts, ray, tri = surfaces.caster.intersects_location(origins, dirs, multiple_hits=False)
        frame = ray // rays
        depth = np.einsum("ij,ij->i", pts - origins[ray], R[frame][:, :, 2])  # along the beam (probe z)
        # Either side of a face: an open mesh (a sheet, a scan with holes) is seen from behind
        # too, and renders so; a closed part's first hits face the laser anyway.
        facing = np.abs(np.einsum("ij,ij->i", dirs[ray], normals[tri]))
        keep = ((tri < part_faces) & (depth >= z0 - RANGE_SLACK_MM) & (depth <= z1 + RANGE_SLACK_MM)
                & (facing >= cos_limit - 1e-12))
        pts, frame = pts[keep], frame[keep]
        if not len(pts):
            continue
        local = np.einsum("nji,nj->ni", R[frame], pts - t[frame])
        out_points.append(pts)
        out_frames.append(frame + start)
        out_seen.append(np.stack([seen_by(probe, surfaces.caster, camera, R[frame], t[frame], pts, local)[1]
                                  for camera in (0, 1)]))
    if not out_points:
        return np.zeros((0, 3)), np.zeros(0, dtype=int), np.zeros((2, 0), bool)
    return np.concatenate(out_points), np.concatenate(out_frames), np.concatenate(out_seen, axis=1)


def _first_hits(caster, origins, dirs):
    """First hit of each ray: (points (m, 3), ray index (m,))."""
    if len(origins) == 0:
        return np.zeros((0, 3)), np.zeros(0, dtype=int)
    locations, index_ray, _ = caster.intersects_location(origins, dirs, multiple_hits=False)
    return locations, index_ray
