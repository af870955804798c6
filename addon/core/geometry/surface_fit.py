"""What neighbouring profiles say about each point: the local surface across the laser line.

One frame sees the surface only along its laser line. Its neighbours in the cloud (the
previous and next profiles, other passes) show the surface across the line too, as a
real profiler's software sees it once several profiles are in. Around each point a
quadric is fitted to its nearest points (at least three frames among them, fitted
well); from it:

- **the surface's incidence to the laser ray**, in three dimensions: a point on a
  surface turned more than the filter's incidence limit from the beam (steep across
  the line, which the profile filter cannot see) is dropped as "steep_surface";
- **the surface's curvature across the line**: the lit strip is as wide as the beam
  (σ_b, growing with range), and on a surface curving by κ across the line its centre
  leaves the laser plane by about κσ_b²/2; that joins the point's σ.

Points without such neighbours (a single profile, the edge of a scan) keep what their
frame gave them.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

NEIGHBOURS = 40           # along a line the points lie about 0.5 mm apart: enough to reach the next lines
MIN_FRAMES = 3            # the point's own and two more
MAX_REACH_MM = 4.0        # the neighbours must lie this close
MAX_FIT_RMS_MM = 0.02     # a quadric that fits its neighbours worse than this is not trusted
MIN_OTHER_SHARE = 0.25    # of the neighbours from other frames
MIN_SPREAD = 0.2          # the neighbours' spread across their main direction, as a share of along it


def local_surfaces(points: np.ndarray, frame: np.ndarray):
    """Per point: (ok (n,), normal (n, 3), tangent basis (n, 2, 3), quadric (n, 3) = a, b, c of
    w = a u² + b uv + c v² + d u + e v + f in that basis, centred on the point)."""
    P = np.asarray(points, dtype=np.float64)
    n = len(P)
    ok = np.zeros(n, bool)
    normal = np.zeros((n, 3))
    basis = np.zeros((n, 2, 3))
    quad = np.zeros((n, 3))
    if n < NEIGHBOURS:
        return ok, normal, basis, quad
    dist, idx = cKDTree(P).query(P, k=NEIGHBOURS)
    frames = np.asarray(frame)[idx]
    distinct = 1 + np.count_nonzero(np.diff(np.sort(frames, axis=1), axis=1), axis=1)
    usable = (distinct >= MIN_FRAMES) & (dist[:, -1] <= MAX_REACH_MM)
    Q = P[idx] - P[:, None, :]                               # (n, K, 3), centred on the point
    C = np.einsum("nki,nkj->nij", Q - Q.mean(axis=1, keepdims=True), Q - Q.mean(axis=1, keepdims=True))
    vals, vecs = np.linalg.eigh(C)                            # ascending: the normal first
    nrm, t1, t2 = vecs[:, :, 0], vecs[:, :, 1], vecs[:, :, 2]
    u, v, w = (np.einsum("nki,ni->nk", Q, a) for a in (t1, t2, nrm))
    A = np.stack([u * u, u * v, v * v, u, v, np.ones_like(u)], axis=2)  # (n, K, 6)
    AtA = np.einsum("nki,nkj->nij", A, A) + 1e-9 * np.eye(6)
    coef = np.linalg.solve(AtA, np.einsum("nki,nk->ni", A, w)[..., None])[..., 0]
    rms = np.sqrt(np.mean((np.einsum("nki,ni->nk", A, coef) - w) ** 2, axis=1))
    # Neighbours strung along one line (a dense sensor, profiles far apart) fix no surface.
    others = np.mean(frames != np.asarray(frame)[:, None], axis=1)
    spread = vals[:, 1] >= MIN_SPREAD ** 2 * vals[:, 2]
    ok = usable & (rms <= MAX_FIT_RMS_MM) & (others >= MIN_OTHER_SHARE) & spread
    # The normal at the point, tilted by the fitted slopes (d, e).
    nn = nrm - coef[:, 3:4] * t1 - coef[:, 4:5] * t2
    normal = nn / np.linalg.norm(nn, axis=1, keepdims=True)
    basis = np.stack([t1, t2], axis=1)
    return ok, normal, basis, coef[:, :3]


def across_line(points, frame, probe2table, line_width_mm: float, mid_range_mm: float, max_incidence_deg: float):
    """(steep (n,) bool, σ across the line (n,) mm) for a cloud's points (table frame), their
    frames and the frames' probe poses ``probe2table`` (m, 4, 4)."""
    P = np.asarray(points, dtype=np.float64)
    n = len(P)
    ok, normal, basis, quad = local_surfaces(P, frame)
    steep = np.zeros(n, bool)
    sigma = np.zeros(n)
    if not ok.any():
        return steep, sigma
    T = np.asarray(probe2table)[np.asarray(frame)]
    laser = T[:, :3, 3]
    ray = P - laser
    rng = np.linalg.norm(ray, axis=1)
    ray /= np.maximum(rng, 1e-12)[:, None]
    cos_inc = np.abs(np.sum(ray * normal, axis=1))
    steep = ok & (cos_inc < np.cos(np.radians(max_incidence_deg)))
    # Across the line: the laser plane's normal (the probe's x) laid into the tangent plane.
    across = T[:, :3, 0]
    tu, tv = np.einsum("ni,ni->n", across, basis[:, 0]), np.einsum("ni,ni->n", across, basis[:, 1])
    norm = np.hypot(tu, tv)
    tu, tv = tu / np.maximum(norm, 1e-12), tv / np.maximum(norm, 1e-12)
    kappa = 2.0 * (quad[:, 0] * tu * tu + quad[:, 1] * tu * tv + quad[:, 2] * tv * tv)
    beam = line_width_mm / 4.0 * rng / mid_range_mm
    sigma = np.where(ok & (norm > 1e-6), 0.5 * np.abs(kappa) * beam ** 2, 0.0)
    return steep, sigma
