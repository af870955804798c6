"""The ray-cast engine: what Cycles renders of the gobo laser on diffuse surfaces, by Embree.

Under the paper's ideal conditions (the laser the only light, Lambertian surfaces, no
bounces, one point sample per pixel) a probe image holds, at each pixel, the direct
light of the laser at the first surface the pixel's ray meets:

    ρ · P · g(n_x) · max(0, N·L) / (4π² d²)     (red channel; 0 where the laser is hidden)

with ρ the surface's albedo, P the laser's power (``laser_profile.laser_power_w``),
g the gobo's Gaussian of the emission direction across the laser plane (zero outside
the fan's cone), N the shading normal, L the unit vector to the laser and d its
distance (m). This module computes exactly that, as Cycles does it:

- shading normals are Blender's smooth ones: per face corner, the corner-angle weighted
  sum of the face normals around the vertex that are joined to it through smooth edges
  (the cell's meshes keep edges sharper than 30° sharp: ``surfaces.SHARP_EDGE_DEG``),
  blended across the triangle by its barycentric coordinates;
- a surface seen from behind is shaded from that side (its normals turned round);
- each pixel is sampled at one point: its centre moved by :data:`SAMPLE_OFFSET_PX`,
  where Cycles puts its one sample at the seed the scans use;
- a shadow ray runs from the surface to the laser, skipping the face it leaves, and on
  smooth-shaded triangles near the shadow terminator from where Cycles starts it
  (:meth:`RaycastScene.terminator_offset`).

Only the pixels that can hold light are cast, per column: the laser's fan is cast
first (three fans across the plane, at −3, 0 and +3 line σ, over the part of the plane
the cameras can see), its hits are joined along each fan and projected into the camera,
and every column gets the rows its segments cross, widened by
:data:`WINDOW_MARGIN_ROWS`. A window whose end pixel is not dark (above
:data:`DARK_SHARE` of its column's peak) grows until it is, so that the rest of the
column is dark as in Cycles. The image returned is the band of rows holding all the
windows; everything outside the windows is 0.

``tests/scene/test_raycast_engine.py`` checks it frame by frame against Cycles.
"""

from __future__ import annotations

import math
import os

import numpy as np
import trimesh

from ..errors import InputError
from ..machine import usable_cpus
from .surfaces import DIFFUSE_SURFACES, FIXTURE, SHARP_EDGE_DEG, TABLE_TOP
from .laser_profile import LASER_RGB, angular_sigma_rad, gobo_strength, laser_power_w
from .probe import Probe

# Where Cycles' one sample per pixel falls, at seed 0 with a 0.01 px box filter, from the pixel centre
# (OpenCV pixels: +u right, +v down); fitted to Cycles' images of a plane.
SAMPLE_OFFSET_PX = (4.8e-4, -4.8e-4)
FAN_OFFSETS_SIGMA = (-3.0, 0.0, 3.0)
WINDOW_MARGIN_ROWS = 1
FAN_RAYS_PER_PX = 1.0             # fan rays per pixel of the cameras' angular resolution
DARK_SHARE = 1e-3                # a window's end pixel below this share of its column's peak is dark
SHADOW_START_MM = 1e-3           # a shadow ray that met its own face goes on from this far past it
TERMINATOR_CUTOFF = 0.1          # Blender's default shadow terminator geometry offset (objects' setting)
MAX_GROWTH_STEPS = 64              # windows double each step: far more than a sensor's height needs
RAYS_PER_THREAD = 1000           # fewer rays than this a core are not worth a thread
NEGLIGIBLE = 1e-7                # film units: light this faint is 0 (no shadow ray is cast for it)


def corner_normals(mesh: trimesh.Trimesh, sharp_deg: float = SHARP_EDGE_DEG) -> np.ndarray:
    """Blender's smooth shading normals of ``mesh`` with edges sharper than ``sharp_deg`` kept
    sharp: (F, 3, 3) unit vectors, one per face corner.

    Corners of one vertex are joined across an edge when the edge has exactly two faces,
    both wound the same way, whose normals differ by no more than ``sharp_deg``; each
    joined group's normal is the sum of its faces' normals weighted by the faces' angles
    at the vertex."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    faces = np.asarray(mesh.faces, dtype=np.int64)
    verts = np.asarray(mesh.vertices, dtype=np.float64)
    F = len(faces)
    tri = verts[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area2 = np.linalg.norm(cross, axis=1)
    fn = np.divide(cross, area2[:, None], out=np.zeros_like(cross), where=area2[:, None] > 0)
    # the angle of each face at each of its corners
    angles = np.zeros((F, 3))
    for k in range(3):
        a = tri[:, (k + 1) % 3] - tri[:, k]
        b = tri[:, (k + 2) % 3] - tri[:, k]
        angles[:, k] = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))

    # directed edges k -> k+1 of each face; an edge is smooth when exactly two faces hold it in opposite directions
    start = faces.ravel()
    end = faces[:, [1, 2, 0]].ravel()
    corner_start = np.arange(3 * F)
    corner_end = (np.arange(F)[:, None] * 3 + np.array([1, 2, 0])[None, :]).ravel()
    key = np.minimum(start, end) * (len(verts) + 1) + np.maximum(start, end)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    first = np.r_[True, ks[1:] != ks[:-1]]
    group = np.cumsum(first) - 1
    count = np.bincount(group)
    pair = count[group] == 2
    i = order[pair][0::2]  # the two directed edges of each two-face edge, side by side
    j = order[pair][1::2]
    fi, fj = i // 3, j // 3
    opposite = (start[i] == end[j]) & (end[i] == start[j])
    cos = np.clip(np.einsum("ij,ij->i", fn[fi], fn[fj]), -1.0, 1.0)
    smooth = opposite & (cos >= math.cos(math.radians(sharp_deg))) & (fi != fj)
    i, j = i[smooth], j[smooth]
    # join the corners at both ends of each smooth edge: i's start is j's end and the other way round
    a = np.concatenate([corner_start[i], corner_end[i]])
    b = np.concatenate([corner_end[j], corner_start[j]])
    n = 3 * F
    graph = coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    weighted = (fn[:, None, :] * angles[:, :, None]).reshape(-1, 3)
    sums = np.zeros((label.max() + 1, 3))
    np.add.at(sums, label, weighted)
    normals = sums[label]
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.where(length > 0, normals / np.where(length > 0, length, 1.0), np.repeat(fn, 3, axis=0))
    return normals.reshape(F, 3, 3)


def vertex_normals(mesh: trimesh.Trimesh) -> np.ndarray:
    """Blender's vertex normals (the corner-angle weighted sum of the normals of every face at
    the vertex, sharp edges or not) at each face's corners: (F, 3, 3) unit vectors."""
    faces = np.asarray(mesh.faces, dtype=np.int64)
    sums = np.zeros((len(mesh.vertices), 3))
    weighted = np.asarray(mesh.face_normals, dtype=np.float64)[:, None, :] * np.asarray(mesh.face_angles)[:, :, None]
    np.add.at(sums, faces.ravel(), weighted.reshape(-1, 3))
    length = np.linalg.norm(sums, axis=1, keepdims=True)
    return (sums / np.where(length > 0, length, 1.0))[faces]


class RaycastScene:
    """The cell's surfaces (table frame, mm), each with its diffuse albedo (RGB), in one Embree
    scene with Blender's shading normals; built once per scan."""

    def __init__(self, surfaces: list[tuple[trimesh.Trimesh, tuple[float, float, float]]], threads: int | None = None):
        """``threads``: how many cores cast rays (None: all)."""
        self.threads = max(1, int(threads or usable_cpus()))
        try:
            import embreex  # noqa: F401
        except ImportError as exc:  # pragma: no cover - the lock installs it
            raise InputError("the raycast engine needs the embreex package (Embree); use engine cycles") from exc
        meshes = [m for m, _ in surfaces]
        self.vertices = np.concatenate([np.asarray(m.vertices, dtype=np.float64)[m.faces] for m in meshes])  # (F, 3, 3)
        self.normals = np.concatenate([corner_normals(m) for m in meshes])
        self.vertex_normals = np.concatenate([vertex_normals(m) for m in meshes])
        self.face_normals = np.concatenate([np.asarray(m.face_normals, dtype=np.float64) for m in meshes])
        # (F, 18): corner 0, the edges to corners 1 and 2, and the same of the corner normals, side
        # by side, so that one gather per hit fetches what blending by barycentrics needs
        c0, n0 = self.vertices[:, 0], self.normals[:, 0]
        self._blend_table = np.ascontiguousarray(np.concatenate(
            [c0, self.vertices[:, 1] - c0, self.vertices[:, 2] - c0, n0, self.normals[:, 1] - n0,
             self.normals[:, 2] - n0], axis=1))
        self.albedo = np.concatenate([np.tile(np.asarray(rgb, dtype=np.float64), (len(m.faces), 1))
                                      for m, rgb in surfaces])
        whole = trimesh.util.concatenate(meshes)
        self._triangles = (np.asarray(whole.vertices, dtype=np.float32), np.asarray(whole.faces, dtype=np.int32))
        self._build_embree()

    def _build_embree(self) -> None:
        from embreex import mesh_construction, rtcore_scene

        self._scene = rtcore_scene.EmbreeScene()
        self._mesh = mesh_construction.TriangleMesh(self._scene, *self._triangles)

    # Embree's scene cannot be pickled: it is left out and built again on loading (a training
    # loop pickles, deep-copies or ships its environments, and with them this scene).
    def __getstate__(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k not in ("_scene", "_mesh")}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._build_embree()

    def first_hits(self, origins: np.ndarray, dirs: np.ndarray, dists: np.ndarray | None = None):
        """(face (n,) int, −1: none; u, v (n,) barycentrics of vertices 1 and 2; t (n,) mm) of rays
        (no farther than ``dists`` mm, when given)."""
        out = self._run(origins, dirs, dists, output=1)
        return out["primID"], out["u"].astype(np.float64), out["v"].astype(np.float64), out["tfar"].astype(np.float64)

    def occluded(self, origins: np.ndarray, dirs: np.ndarray, dists: np.ndarray) -> np.ndarray:
        """Whether each ray meets a surface within ``dists`` mm."""
        return self._run(origins, dirs, dists, query="OCCLUDED") >= 0

    def _run(self, origins, dirs, dists, **kw):
        """Embree's answer for the rays, cast on ``threads`` cores side by side (it releases the GIL)."""
        o = np.ascontiguousarray(origins, dtype=np.float32)
        d = np.ascontiguousarray(dirs, dtype=np.float32)
        t = None if dists is None else np.ascontiguousarray(dists, dtype=np.float32)

        def cast(a: int, b: int):
            if t is None:
                return self._scene.run(o[a:b], d[a:b], **kw)
            return self._scene.run(o[a:b], d[a:b], dists=t[a:b], **kw)

        n = len(o)
        parts = min(self.threads, max(1, n // RAYS_PER_THREAD))
        if parts <= 1:
            return cast(0, n)
        cuts = np.linspace(0, n, parts + 1).astype(int)
        outs = list(_pool(self.threads).map(lambda k: cast(cuts[k], cuts[k + 1]), range(parts)))
        if isinstance(outs[0], dict):
            return {key: np.concatenate([out[key] for out in outs]) for key in outs[0]}
        return np.concatenate(outs)

    def blocked(self, origins: np.ndarray, dirs: np.ndarray, dists: np.ndarray, own: np.ndarray,
                skip_own: np.ndarray) -> np.ndarray:
        """Whether each shadow ray (from ``origins`` along unit ``dirs`` for ``dists`` mm) meets a
        surface; where ``skip_own``, its own face ``own`` does not count (as Cycles' rays skip the
        primitive they leave)."""
        # A ray that may not meet its own face starts a hair along its way, clear of it; the rest
        # start on the surface. Rays that met something and may not meet their own face are
        # asked what they met, and go on past their own face.
        start = np.where(skip_own, SHADOW_START_MM * 0.1, 0.0)
        blocked = self.occluded(origins + dirs * start[:, None], dirs, dists - start)
        todo = np.nonzero(blocked & skip_own)[0]
        blocked[todo] = False
        for _ in range(4):
            if not todo.size:
                break
            o = origins[todo] + dirs[todo] * start[todo, None]
            face, _, _, t = self.first_hits(o, dirs[todo], dists[todo] - start[todo])
            hit = face >= 0
            own_hit = hit & (face == own[todo])
            blocked[todo[hit & ~own_hit]] = True
            start[todo[own_hit]] += t[own_hit] + SHADOW_START_MM * 0.1
            todo = todo[own_hit]
        return blocked

    def terminator_offset(self, face: np.ndarray, u: np.ndarray, v: np.ndarray, ng_l: np.ndarray) -> np.ndarray:
        """Where Cycles starts a shadow ray on a smooth-shaded triangle, relative to the hit point
        (n, 3) mm: near the shadow terminator (the light within ~6° of the triangle's plane,
        ``ng_l`` = N_g·L below 0.1) it lifts the point towards the smooth surface the normals
        describe (the vertices' normals, which know nothing of sharp edges), by Hanika's offset
        (Ray Tracing Gems II, ch. 4): the point is pushed out of each corner's tangent plane it
        lies below, and the pushes are blended by the barycentric weights; full below
        N_g·L = 0.05, fading out by 0.1 (Blender's default shadow terminator geometry offset)."""
        amount = np.clip(2.0 - 2.0 * ng_l / TERMINATOR_CUTOFF, 0.0, 1.0)
        out = np.zeros((len(face), 3))
        near = np.nonzero(amount > 0)[0]
        if not near.size:
            return out
        f, uu, vv = face[near], u[near], v[near]
        tri, nrm = self.vertices[f], self.vertex_normals[f]
        w = np.column_stack([1.0 - uu - vv, uu, vv])
        P = np.einsum("ik,ikj->ij", w, tri)
        below = np.minimum(np.einsum("ikj,ikj->ik", P[:, None, :] - tri, nrm), 0.0)
        out[near] = -np.einsum("ik,ikj->ij", w * below, nrm) * amount[near, None]
        return out

    def points_and_normals(self, face: np.ndarray, u: np.ndarray, v: np.ndarray):
        """Points (n, 3) mm at barycentrics u, v (of vertices 1 and 2) of faces ``face``, and the
        smooth shading normals (n, 3) there: the corners' normals blended, made unit."""
        t = self._blend_table[face]
        uu, vv = u[:, None], v[:, None]
        P = t[:, 0:3] + t[:, 3:6] * uu + t[:, 6:9] * vv
        N = t[:, 9:12] + t[:, 12:15] * uu + t[:, 15:18] * vv
        length = np.sqrt(np.einsum("ij,ij->i", N, N))
        flat = length < 1e-12  # corners' normals that cancel (a folded mesh): the face's own normal
        if flat.any():
            N[flat], length[flat] = self.face_normals[face[flat]], 1.0
        return P, N / length[:, None]


def visible_fan_half_angle(probe: Probe) -> float:
    """The largest angle from the beam (rad, in the laser plane) of a point of the plane either
    camera can see: the plane inside a camera's view is the quadrilateral where its corner
    pixels' rays meet it (the probe's geometry makes every one of them meet it)."""
    W, H = probe.cols_px, probe.rows_px
    corners = np.array([[-0.5, -0.5], [W - 0.5, -0.5], [-0.5, H - 0.5], [W - 0.5, H - 0.5]])
    worst = 0.0
    for camera in (0, 1):
        origin, d = probe.pixel_rays(corners, camera)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -origin[0] / d[:, 0]
        if not np.all(np.isfinite(t) & (t > 0)):
            return probe.fan_rad / 2.0
        P = origin + t[:, None] * d
        worst = max(worst, float(np.abs(np.arctan2(P[:, 1], P[:, 2])).max()))
    return worst


def _pool(threads: int):
    """A thread pool of ``threads`` workers, kept for the process."""
    pool = _POOLS.get(threads)
    if pool is None:
        from concurrent.futures import ThreadPoolExecutor

        pool = _POOLS[threads] = ThreadPoolExecutor(threads, thread_name_prefix="raycast")
    return pool


_POOLS: dict = {}
if hasattr(os, "register_at_fork"):
    # A forked child (a Gymnasium AsyncVectorEnv's worker, a multiprocessing pool) inherits the
    # executors but not their threads: work given to them never ran, and the child hung.
    os.register_at_fork(after_in_child=_POOLS.clear)


def cell_raycast_scene(workpiece_mesh: trimesh.Trimesh | None, surface: str = "grey",
                       threads: int | None = None, fixtures=()) -> RaycastScene:
    """The ray-cast scene of a scan: the workpiece (of diffuse ``surface``), the table top and
    the table's ``fixtures`` (meshes, table frame, diffuse grey)."""
    from ..kinematics.turntable import table_top_mesh

    if surface not in DIFFUSE_SURFACES:
        raise InputError(f"the raycast engine renders diffuse surfaces ({', '.join(DIFFUSE_SURFACES)}); "
                         f"the {surface!r} surface needs light transport: use engine cycles")
    parts = [(table_top_mesh(), TABLE_TOP), *((m, FIXTURE) for m in fixtures)]
    if workpiece_mesh is not None:
        parts.insert(0, (workpiece_mesh, DIFFUSE_SURFACES[surface]))
    return RaycastScene(parts, threads)


class RaycastRenderer:
    """Probe images of the gobo laser by ray casting (see the module docstring). Frames are cast
    together, a chunk at a time: each step (the fans, the pixels, the shadows, each growth of
    the windows) is one call into Embree for all of them."""

    def __init__(self, probe: Probe, scene: RaycastScene, laser_peak: float = 0.5, windows: bool = True):
        """``windows``: cast only the pixels that can hold light (False: every pixel of each
        camera asked for, for comparison; the images are the same)."""
        self.probe, self.scene, self.windows = probe, scene, windows
        self.power_w = laser_power_w(probe, peak=laser_peak)
        self.sigma_rad = angular_sigma_rad(probe)
        self.cos_half_fan = math.cos(probe.fan_rad / 2.0)
        # Along the fan, FAN_RAYS_PER_PX rays per pixel of the cameras' angular resolution (the segments
        # between neighbouring hits cover the columns in between), over the part of the fan the
        # cameras can see: the laser plane inside their views is bounded by where their corner
        # pixels' rays meet it.
        half = min(probe.fan_rad / 2.0, visible_fan_half_angle(probe) + 2.0 / probe.f_px)
        k = int(min(40000, max(16, math.ceil(FAN_RAYS_PER_PX * 2.0 * half * probe.f_px))))
        alpha = np.linspace(-half, half, k)
        beta = np.asarray(FAN_OFFSETS_SIGMA) * self.sigma_rad
        cb = np.cos(beta)[:, None]
        self._fan_dirs = np.stack([np.broadcast_to(np.sin(beta)[:, None], (len(beta), k)),
                                   cb * np.sin(alpha)[None, :], cb * np.cos(alpha)[None, :]], axis=-1)  # (fans, k, 3)
        cx, cy = probe.principal_point
        self._cxy = (cx - SAMPLE_OFFSET_PX[0], cy - SAMPLE_OFFSET_PX[1])

    def render_frames(self, probe2table: np.ndarray, cameras=(0, 1)
                      ) -> list[tuple[list[np.ndarray | None], tuple[int, int]]]:
        """The cameras' images for probe poses ``probe2table`` (n, 4, 4): per frame ([camera 0,
        camera 1] images (r1 − r0, W, 3) float32, None for a camera not asked for; (r0, r1) the
        sensor rows they hold, all the windows of that frame's cameras)."""
        H, W = self.probe.rows_px, self.probe.cols_px
        n, cams = len(probe2table), tuple(cameras)
        if not n:
            return []
        if not cams:
            return [([None, None], (0, min(H, 3)))] * n
        nv = n * len(cams)  # views: frame i, camera cams[k] is view i·len(cams) + k
        cam2table = np.stack([probe2table @ self.probe.cam2probe(c) for c in cams], axis=1).reshape(nv, 4, 4)
        probe2view = np.repeat(probe2table, len(cams), axis=0)  # the probe's pose in each view
        if self.windows:
            fan = self._fan_hits(probe2table)
            lo, hi = np.full((nv, W), H, dtype=np.int64), np.full((nv, W), -1, dtype=np.int64)
            for k, camera in enumerate(cams):
                lo[k::len(cams)], hi[k::len(cams)] = self._windows(fan, camera)
            lo, hi = lo.ravel(), hi.ravel()
        else:
            lo, hi = np.zeros(nv * W, dtype=np.int64), np.full(nv * W, H - 1, dtype=np.int64)
        cells = np.nonzero(hi >= lo)[0]
        pix = _window_pixels(lo[cells], hi[cells], cells)
        parts = [(*pix, *self._shade(cam2table, probe2view, *pix, W))]
        peak, top, bottom = np.zeros(nv * W), np.zeros(nv * W), np.zeros(nv * W)
        for _ in range(MAX_GROWTH_STEPS):
            cell, row, value = parts[-1][0], parts[-1][1], parts[-1][2]
            np.maximum.at(peak, cell, value)
            at_top, at_bottom = row == lo[cell], row == hi[cell]
            top[cell[at_top]], bottom[cell[at_bottom]] = value[at_top], value[at_bottom]
            limit = DARK_SHARE * peak
            up = np.nonzero((top > limit) & (top > 0) & (lo > 0) & (hi >= lo))[0]
            down = np.nonzero((bottom > limit) & (bottom > 0) & (hi < H - 1) & (hi >= lo))[0]
            if not (up.size or down.size):
                break
            old_lo, old_hi = lo.copy(), hi.copy()
            # each growth adds as many rows as the window has (a streak along a column, where the
            # line grazes the surface, is reached in a few steps), at least WINDOW_MARGIN_ROWS
            grow = np.maximum(hi - lo + 1, WINDOW_MARGIN_ROWS)
            lo[up] = np.maximum(lo[up] - grow[up], 0)
            hi[down] = np.minimum(hi[down] + grow[down], H - 1)
            top[up], bottom[down] = 0.0, 0.0
            grown = np.concatenate([up, down])
            first = np.concatenate([lo[up], old_hi[down] + 1])
            last = np.concatenate([old_lo[up] - 1, hi[down]])
            pix = _window_pixels(first, last, grown)
            parts.append((*pix, *self._shade(cam2table, probe2view, *pix, W)))
        cell = np.concatenate([p[0] for p in parts])
        row = np.concatenate([p[1] for p in parts])
        value = np.concatenate([p[2] for p in parts])
        rgb = np.concatenate([p[3] for p in parts])
        return self._images(n, cams, cell, row, value, rgb, lo.reshape(nv, W), hi.reshape(nv, W))

    def _images(self, n, cams, cell, row, value, rgb, lo, hi):
        """Per frame, its cameras' images over the band of rows that holds all their windows."""
        H, W = self.probe.rows_px, self.probe.cols_px
        has = hi >= lo
        view = cell // W
        order = np.argsort(view, kind="stable")
        bounds = np.searchsorted(view[order], np.arange(len(lo) + 1))
        out = []
        for i in range(n):
            views = range(i * len(cams), (i + 1) * len(cams))
            if any(has[v].any() for v in views):
                r0 = int(min(lo[v][has[v]].min() for v in views if has[v].any()))
                r1 = int(max(hi[v][has[v]].max() for v in views if has[v].any())) + 1
            else:
                r0, r1 = 0, 0
            if r1 - r0 < 3:  # the detector needs three rows
                r0 = max(0, min(r0, H - 3))
                r1 = r0 + 3
            images: list[np.ndarray | None] = [None, None]
            for k, camera in enumerate(cams):
                v = i * len(cams) + k
                img = np.zeros((r1 - r0, W, 3), dtype=np.float32)
                sel = order[bounds[v]:bounds[v + 1]]
                if sel.size:
                    for ch in range(3):
                        if LASER_RGB[ch]:
                            img[row[sel] - r0, cell[sel] - v * W, ch] = value[sel] * rgb[sel, ch] * LASER_RGB[ch]
                images[camera] = img
            out.append((images, (r0, r1)))
        return out

    def _fan_hits(self, probe2table: np.ndarray) -> np.ndarray:
        """The fan rays' first hits: probe-frame points (n, fans, k, 3), NaN where none."""
        R, t = probe2table[:, :3, :3], probe2table[:, :3, 3]
        d = self._fan_dirs.reshape(-1, 3)
        dirs = np.einsum("nij,kj->nki", R, d).reshape(-1, 3)
        face, _, _, dist = self.scene.first_hits(np.repeat(t, len(d), axis=0), dirs)
        pts = np.tile(d, (len(R), 1)) * np.where(face >= 0, dist, np.nan)[:, None]
        return pts.reshape(len(R), *self._fan_dirs.shape)

    def _windows(self, fan_probe: np.ndarray, camera: int) -> tuple[np.ndarray, np.ndarray]:
        """Per frame and column, the first and last row that can hold light (n, W) each (lo > hi: none)."""
        H, W, f = self.probe.rows_px, self.probe.cols_px, self.probe.f_px
        n = len(fan_probe)
        T = self.probe.probe2cam(camera)
        pc = fan_probe @ T[:3, :3].T + T[:3, 3]
        with np.errstate(invalid="ignore", divide="ignore"):
            front = pc[..., 2] > 0
            u = np.where(front, f * pc[..., 0] / pc[..., 2] + self._cxy[0], np.nan)
            v = np.where(front, f * pc[..., 1] / pc[..., 2] + self._cxy[1], np.nan)
        frame = np.broadcast_to(np.arange(n)[:, None, None], u.shape)
        # segments between neighbouring hits of a fan, and each hit on its own, one pixel either side
        # (a hit whose neighbours fell on other surfaces, e.g. a thin rim, may light more than its column)
        ua, ub = np.concatenate([u[..., :-1].ravel(), u.ravel() - 1.0]), np.concatenate([u[..., 1:].ravel(), u.ravel() + 1.0])
        va, vb = np.concatenate([v[..., :-1].ravel(), v.ravel()]), np.concatenate([v[..., 1:].ravel(), v.ravel()])
        fr = np.concatenate([frame[..., :-1].ravel(), frame.ravel()])
        ok = np.isfinite(ua) & np.isfinite(ub)
        ua, ub, va, vb, fr = ua[ok], ub[ok], va[ok], vb[ok], fr[ok]
        swap = ub < ua  # each segment from its smaller u to its larger
        ua, ub, va, vb = np.where(swap, ub, ua), np.where(swap, ua, ub), np.where(swap, vb, va), np.where(swap, va, vb)
        keep = (ub >= -0.5) & (ua <= W - 0.5) & (np.maximum(va, vb) >= -0.5 - WINDOW_MARGIN_ROWS) & \
               (np.minimum(va, vb) <= H - 0.5 + WINDOW_MARGIN_ROWS)
        ua, ub, va, vb, fr = ua[keep], ub[keep], va[keep], vb[keep], fr[keep]
        lo = np.full(n * W, H, dtype=np.int64)
        hi = np.full(n * W, -1, dtype=np.int64)
        if ua.size:
            c0 = np.clip(np.floor(ua + 0.5), 0, W - 1).astype(np.int64)
            c1 = np.clip(np.floor(ub + 0.5), 0, W - 1).astype(np.int64)
            span = c1 - c0 + 1
            col = np.repeat(c0, span) + _ramp(span)
            a, b = np.repeat(ua, span), np.repeat(ub, span)
            ya, yb = np.repeat(va, span), np.repeat(vb, span)
            # the part of the segment over this column, by its rows at the column's two edges
            with np.errstate(invalid="ignore", divide="ignore"):
                slope = np.where(b > a, (yb - ya) / (b - a), 0.0)
            y0 = ya + slope * (np.clip(col - 0.5, a, b) - a)
            y1 = ya + slope * (np.clip(col + 0.5, a, b) - a)
            y0, y1 = np.where(b > a, y0, ya), np.where(b > a, y1, yb)
            cells = np.repeat(fr * W, span) + col
            r_lo = np.clip(np.floor(np.minimum(y0, y1) + 0.5) - WINDOW_MARGIN_ROWS, 0, H - 1).astype(np.int64)
            r_hi = np.clip(np.floor(np.maximum(y0, y1) + 0.5) + WINDOW_MARGIN_ROWS, 0, H - 1).astype(np.int64)
            np.minimum.at(lo, cells, r_lo)
            np.maximum.at(hi, cells, r_hi)
        return lo.reshape(n, W), hi.reshape(n, W)

    def _shade(self, cam2table: np.ndarray, probe2view: np.ndarray, cell: np.ndarray, row: np.ndarray, W: int):
        """Radiance (before the laser's colour, linear film units) and albedo (m, 3) of the pixels
        ``row`` of the cells ``cell`` (view · W + column)."""
        m = len(cell)
        value = np.zeros(m)
        albedo = np.zeros((m, 3))
        if not m:
            return value, albedo
        view, col = np.divmod(cell, W)
        f = self.probe.f_px
        x, y = (col - self._cxy[0]) / f, (row - self._cxy[1]) / f
        # the camera's axes (table frame) of each pixel's view, weighted by its ray's camera coordinates
        d = cam2table[view, :3, 0] * x[:, None] + cam2table[view, :3, 1] * y[:, None] + cam2table[view, :3, 2]
        d /= np.sqrt(np.einsum("ij,ij->i", d, d))[:, None]
        face, u, v, _ = self.scene.first_hits(cam2table[view, :3, 3], d)
        hit = np.nonzero(face >= 0)[0]
        if not hit.size:
            return value, albedo
        fc, uu, vv, vw = face[hit], u[hit], v[hit], view[hit]
        P, N = self.scene.points_and_normals(fc, uu, vv)
        Ng = self.scene.face_normals[fc].copy()
        back = np.einsum("ij,ij->i", Ng, d[hit]) > 0  # seen from behind: shaded from that side
        N[back] *= -1.0
        Ng[back] *= -1.0
        laser = probe2view[vw, :3, 3]
        to_laser = laser - P
        dist = np.sqrt(np.einsum("ij,ij->i", to_laser, to_laser))
        L = to_laser / dist[:, None]
        # the emission direction −L in the probe (light) frame: across the plane (x) and along the beam (z)
        emit_x = -np.einsum("ij,ij->i", probe2view[vw, :3, 0], L)
        emit_z = -np.einsum("ij,ij->i", probe2view[vw, :3, 2], L)
        strength = gobo_strength(emit_x, self.sigma_rad) * (emit_z >= self.cos_half_fan)
        dm = dist * 1e-3
        light = self.power_w * strength * np.maximum(np.einsum("ij,ij->i", N, L), 0.0) / (4.0 * math.pi ** 2 * dm * dm)
        on = np.nonzero(light > NEGLIGIBLE)[0]
        light[light <= NEGLIGIBLE] = 0.0
        if on.size:
            ng_l = np.einsum("ij,ij->i", Ng[on], L[on])
            start = P[on] + self.scene.terminator_offset(fc[on], uu[on], vv[on], ng_l)
            # Cycles' shadow ray skips the surface it leaves, except where the light is below
            # that triangle's plane and the start was lifted off it (then it is meant to hit it).
            blocked = self.scene.blocked(start, L[on], np.linalg.norm(laser[on] - start, axis=1), fc[on], ng_l > 0)
            light[on[blocked]] = 0.0
        value[hit] = light
        albedo[hit] = self.scene.albedo[fc]
        return value, albedo


def _ramp(counts: np.ndarray) -> np.ndarray:
    """0, 1, .., c−1 for each count c, concatenated."""
    total = int(counts.sum())
    return np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)


def _window_pixels(first: np.ndarray, last: np.ndarray, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(cell, row) of every pixel from row ``first`` to ``last`` (one each per entry of ``cells``)
    of the cells ``cells``."""
    a, b = first, last
    counts = np.maximum(b - a + 1, 0)
    return np.repeat(cells, counts), np.repeat(a, counts) + _ramp(counts)
