"""The error a probe of this design makes because its laser line has a width.

The laser lights a strip across the line, not a curve: the beam is a Gaussian of
1/e² full width ``line_width_mm`` at mid-range, keeping its angle, so a Gaussian
in the angle β out of the laser plane. On a flat surface the strip is centred on
where the laser plane meets the surface, and only perspective (its far half imaged
smaller than its near half) moves the three-point fit's centre, by about 1 µm for the
default probe head on. On a curved surface, near an edge, or where part of the strip
is hidden from the camera, the lit strip's image is no longer centred on that
point: even a perfect detector finds the centre of what the camera sees, and the
point triangulated from it lies off the part.

:func:`line_width_floor` computes that point for each measured point from the
geometry alone (no rendering): it casts the beam as ``samples`` rays across its
width from the laser, through the measured point's direction in the laser plane,
against the part and the table; gives each first hit the radiance a matt surface
shows there (the beam's Gaussian, the cosine of incidence, the inverse square of the
distance from the laser; nothing where the camera cannot see the hit); takes the
image a pixel-sampled sensor makes of it; finds the line's row there as the
detector does (the three-point Gaussian fit at the brightest pixel; a line cut
beside that pixel has no floor, as the detector rejects it); and triangulates that
pixel on the laser
plane, as the probe does. Its distance from the part is the floor of the error for
that point: what the line's width alone costs, with a noise-free sensor and this
probe's detector.
Fused points average their two cameras' floors.

Embree's hits are single precision; each is recomputed in double precision on the
triangle Embree found, so that single precision adds nothing to the floor.
"""

from __future__ import annotations

import numpy as np

from ..optics.probe import Probe
from .footprint import SurfaceCaster, measurable_hits
from .metrics import coverage_of_measurable, distances

FLOOR_SAMPLES = 41         # rays across the beam (more where a strip images wider: see line_width_floor)
FLOOR_MAX_SAMPLES = 801    # at most
FLOOR_SPAN_SIGMAS = 4.0    # the rays cover ±this many beam σ
OCCLUSION_EPS_MM = 0.01


def _exact_hits(mesh, origins, dirs, tri) -> np.ndarray:
    """Ray parameter t of each ray on the plane of its hit triangle, in double precision."""
    n = mesh.face_normals[tri]
    v0 = mesh.vertices[mesh.faces[tri, 0]]
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.einsum("ij,ij->i", n, v0 - origins) / np.einsum("ij,ij->i", n, dirs)


def _first_hits_exact(caster: SurfaceCaster, origins, dirs):
    """(t (m,) mm along each ray, NaN where it hits nothing; face index (m,), −1 where none)."""
    t = np.full(len(origins), np.nan)
    face = np.full(len(origins), -1)
    if not len(origins):
        return t, face
    tri, ray = caster.caster.intersects_id(origins, dirs, multiple_hits=False)[:2]
    t[ray] = _exact_hits(caster.mesh, origins[ray], dirs[ray], tri)
    face[ray] = tri
    return t, face


def _image_profile(v: np.ndarray, w: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Light (n, r) at sensor rows ``rows`` (n, r) of strips sampled at rows ``v`` (n, k) with
    light ``w`` (n, k): a pixel sees the surface point imaged at its centre, so its light is
    interpolated between the two samples around it that lie on one continuous, lit piece of
    surface (less than a pixel apart); the brightest such piece where several cover a row."""
    v0, v1, w0, w1 = v[:, :-1], v[:, 1:], w[:, :-1], w[:, 1:]
    joined = (w0 > 0) & (w1 > 0) & (np.abs(v1 - v0) < 1.0)
    lo, hi = np.minimum(v0, v1), np.maximum(v0, v1)
    out = np.zeros(rows.shape)
    for j in range(rows.shape[1]):
        r = rows[:, j:j + 1]
        inside = joined & (r >= lo) & (r <= hi)
        with np.errstate(invalid="ignore", divide="ignore"):
            a = np.clip(np.where(v1 != v0, (r - v0) / (v1 - v0), 0.0), 0.0, 1.0)
        # Between two samples of the Gaussian beam the light's logarithm is as good as linear.
        light = np.exp((1 - a) * np.log(np.maximum(w0, 1e-300)) + a * np.log(np.maximum(w1, 1e-300)))
        out[:, j] = np.where(inside, light, 0.0).max(axis=1, initial=0.0)
    return out


def _fitted_rows(v: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The row (n,) the three-point Gaussian fit finds on each strip's image, as the
    detector does: around the brightest pixel, from it and its two neighbours. NaN where
    a neighbour gets no light (the detector rejects such a cut line)."""
    n = len(v)
    best = np.argmax(w, axis=1)
    centre = np.rint(v[np.arange(n), best])
    rows = centre[:, None] + np.arange(-2, 3)[None, :]
    light = _image_profile(v, w, rows)
    # The brightest of the pixels around the brightest sample.
    k = 1 + np.argmax(light[:, 1:4], axis=1)
    lm, l0, lp = (light[np.arange(n), k + d] for d in (-1, 0, 1))
    with np.errstate(invalid="ignore", divide="ignore"):
        a, b, c = np.log(lm), np.log(l0), np.log(lp)
        den = a - 2.0 * b + c
        offset = 0.5 * (a - c) / den
    good = (lm > 0) & (l0 > 0) & (lp > 0) & (den < 0) & (np.abs(offset) <= 1.0)
    return np.where(good, rows[np.arange(n), k] + offset, np.nan)


def line_width_floor(probe: Probe, probe2table: np.ndarray, points: np.ndarray, frame: np.ndarray,
                     camera: np.ndarray, surfaces: SurfaceCaster, samples: int = FLOOR_SAMPLES) -> np.ndarray:
    """Floor points (n, 3), table frame: where a perfect detector of this probe would put
    each measured point (``points`` (n, 3) table frame, ``frame`` (n,) index into
    ``probe2table`` (m, 4, 4), ``camera`` (n,) 1, 2 or 3 = both). NaN where the camera
    sees none of the strip. Where the rays image more than a pixel apart (a line wide on the
    sensor: the hires probe with a 1.8 mm line), so that no pixel lies between two of them on
    one piece of surface, the point is cast again with rays as close as a quarter pixel."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    n = len(points)
    T = np.asarray(probe2table, dtype=np.float64)[np.asarray(frame, dtype=int)]
    R, t = T[:, :3, :3], T[:, :3, 3]
    local = np.einsum("nji,nj->ni", R, points - t)  # probe frame
    # The measured point's direction in the laser plane, and the beam's angular σ.
    in_plane = local.copy()
    in_plane[:, 0] = 0.0
    ahead = in_plane / np.linalg.norm(in_plane, axis=1, keepdims=True)
    z0, z1 = probe.z_range_mm
    sigma_beta = probe.line_width_mm / 4.0 / (0.5 * (z0 + z1))
    beta = np.linspace(-FLOOR_SPAN_SIGMAS, FLOOR_SPAN_SIGMAS, samples) * sigma_beta
    gauss = np.exp(-0.5 * (beta / sigma_beta) ** 2)
    # Ray k of point i: direction ahead_i tilted by β_k out of the laser plane (probe x).
    d_local = ahead[:, None, :] + np.tan(beta)[None, :, None] * np.array([1.0, 0.0, 0.0])
    d_local /= np.linalg.norm(d_local, axis=2, keepdims=True)
    dirs = np.einsum("nij,nkj->nki", R, d_local).reshape(-1, 3)
    origins = np.repeat(t, samples, axis=0)
    hit_t, face = _first_hits_exact(surfaces, origins, dirs)
    hits = origins + hit_t[:, None] * dirs
    normals = surfaces.mesh.face_normals[np.maximum(face, 0)]
    # A face met from behind (an open mesh seen from its inside) is lit and seen from that
    # side, as the renderers shade it: its normal turned towards the laser.
    normals = np.where((np.einsum("ij,ij->i", normals, dirs) > 0)[:, None], -normals, normals)
    hit_local = np.einsum("nji,nkj->nki", R, hits.reshape(n, samples, 3) - t[:, None, :]).reshape(-1, 3)
    frame_of = np.repeat(np.arange(n), samples)
    # A pixel sees the surface's radiance, which for a matt surface is its irradiance: the
    # beam's intensity, the cosine of incidence, and the inverse square of the distance.
    with np.errstate(invalid="ignore", divide="ignore"):
        lit = np.maximum(-np.einsum("ij,ij->i", normals, dirs), 0.0) / hit_t ** 2
    lit = np.nan_to_num(lit)

    floors = []
    spread = np.zeros(n)  # the widest step on the sensor between two lit neighbouring rays, per point
    for cam in (0, 1):
        centre_local = probe.cam2probe(cam)[:3, 3]
        centre = t + np.einsum("nij,j->ni", R, centre_local)
        to_cam = centre[frame_of] - hits
        dist = np.linalg.norm(to_cam, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            to_cam_u = to_cam / dist[:, None]
            facing = np.einsum("ij,ij->i", normals, to_cam_u)
        ok = np.isfinite(hit_t) & (face >= 0) & (facing > 0) & (lit > 0)
        # Hidden from the camera: something on the way from the hit to the camera.
        look_t, _ = _first_hits_exact(surfaces, centre[frame_of][ok], -to_cam_u[ok])
        visible = np.zeros(len(hits), bool)
        visible[np.flatnonzero(ok)] = ~(look_t < dist[ok] - OCCLUSION_EPS_MM)
        w = np.where(visible, np.tile(gauss, n) * np.where(ok, lit, 0.0), 0.0).reshape(n, samples)
        uv = probe.project(hit_local, cam).reshape(n, samples, 2)
        w = np.where(np.isfinite(uv).all(axis=2), w, 0.0)
        v, u = np.nan_to_num(uv[:, :, 1]), np.nan_to_num(uv[:, :, 0])
        steps = np.where((w[:, :-1] > 0) & (w[:, 1:] > 0), np.abs(np.diff(v, axis=1)), 0.0)
        spread = np.maximum(spread, steps.max(axis=1, initial=0.0))
        row = _fitted_rows(v, w)
        best = np.argmax(w, axis=1)
        col = u[np.arange(n), best]
        origin, ray = probe.pixel_rays(np.column_stack([col, np.nan_to_num(row)]), cam)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = -origin[0] / ray[:, 0]
        F = origin + s[:, None] * ray
        F[:, 0] = 0.0
        F[~np.isfinite(row)] = np.nan
        floors.append(F)
    cam = np.asarray(camera, dtype=int)
    chosen = np.where((cam == 1)[:, None], floors[0], floors[1])
    both = 0.5 * (floors[0] + floors[1])
    chosen = np.where((cam == 3)[:, None], both, chosen)
    out = np.einsum("nij,nj->ni", R, chosen) + t
    # No floor because the rays lie a pixel or more apart on the sensor (none joined): cast
    # those points again, denser.
    again = ~np.isfinite(out).all(axis=1) & (spread >= 1.0)
    if again.any() and samples < FLOOR_MAX_SAMPLES:
        more = int(min(FLOOR_MAX_SAMPLES, np.ceil(samples * float(spread[again].max()) / 0.25)) // 2 * 2 + 1)
        out[again] = line_width_floor(probe, probe2table, points[again], np.asarray(frame)[again],
                                      cam[again], surfaces, samples=max(more, samples + 2))
    return out


def coverage_ceiling(probe: Probe, probe2table: np.ndarray, surfaces: SurfaceCaster, mesh,
                     max_incidence_deg: float, max_error_mm: float, tolerance_mm: float) -> float:
    """The coverage of the measurable surface (``footprint.measurable_hits``: the path's laser
    in range, within the incidence limit, seen by a camera) that a probe keeping exactly the
    points whose floor (:func:`line_width_floor`, from its better camera) lies within
    ``max_error_mm`` of the part would reach: what the line's width alone leaves coverable
    by points that good. ``mesh`` is the part, the first faces of ``surfaces``."""
    # The part's faces as the laser meets them (plan.cell_surfaces says how many: an open
    # mesh's faces in the table top are not among them); else all of the mesh's.
    part_faces = surfaces.part_faces or len(mesh.faces)
    points, frame, seen = measurable_hits(probe, probe2table, surfaces, part_faces, max_incidence_deg)
    best = np.full(len(points), np.inf)
    for camera in (0, 1):
        m = seen[camera]
        if not m.any():
            continue
        F = line_width_floor(probe, probe2table, points[m], frame[m], np.full(int(m.sum()), camera + 1), surfaces)
        found = np.isfinite(F).all(axis=1)
        error = np.full(int(m.sum()), np.inf)
        error[found] = distances(F[found], mesh)[0]
        best[m] = np.minimum(best[m], error)
    reach = seen.any(axis=0)
    return coverage_of_measurable(points[reach & (best <= max_error_mm)], mesh, points[reach], tolerance_mm)[0]
