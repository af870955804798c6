"""Triangulation: detected line pixels -> 3-D points on the laser plane (paper Eq. 6).

``method="exact"`` (default) intersects each pixel's viewing ray (from the
camera's K and cam2probe) with the laser plane X = 0. It holds for any camera
pose, not only the paper's symmetric one. A calibrated probe
(:mod:`addon.core.optics.calibrated`) uses its calibrated cameras and laser plane.

``method="paper"`` is Eq. 6 as printed but for its P_Z, which prints a/(f·tan(...)) + b:
a dimensional typo (taken literally, P_Z is about 0.35 mm; Eq. 7's range has no f). With the
paper's pixel coordinates
p_x = ±(u − c_x), p_y = c_y − v (see :mod:`addon.core.optics.probe`)::

    P_X = 0,  P_Y = a·p_x / (f·sin(φ − atan(p_y/f))),  P_Z = a / tan(φ − atan(p_y/f)) + b

Its P_Z is exact; its P_Y uses f where the exact ray has √(f² + p_y²), so P_Y is
too long by the factor √(1 + (p_y/f)²): zero on the centre row, largest at the top
and bottom rows (1/cos γ, +2.9 % for the default probe).

Stability: a ray that meets the laser plane at a shallow angle (the paper's
φ − atan(p_y/f) → 0) gives a huge, ill-conditioned depth. Such points (angle below
``min_angle_deg``) and points outside the probe's range [z_min, z_max] are masked
and counted, never returned as inf, NaN or huge values.

Per point, the result also carries the triangulation angle (between viewing ray
and laser plane) and its depth uncertainty: the detector's uncertainty of the line
centre (``LineDetection.sigma_px``) times how far the point moves per pixel along
the triangulation direction.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .detect import LineDetection
from ..errors import InputError
from .probe import MIN_ANGLE_DEG, Probe, _check_camera

TRIANGULATION_METHODS = ("exact", "paper")
UNKNOWN_SIGMA_PX = 0.1  # a detection that states no uncertainty (made up from given rows)
CAMERA_BITS = {0: 1, 1: 2}  # Profile.camera: 1 = camera 0, 2 = camera 1, 3 = both (fused)


@dataclass
class Profile:
    """One frame's triangulated laser profile in the probe frame (valid points only).

    points : (n, 3) mm, probe frame
    col : (n,) float, sensor column the point came from (camera 0's for fused points)
    camera : (n,) uint8, 1 = camera 0, 2 = camera 1, 3 = both cameras (fused)
    angle_rad : (n,) triangulation angle between viewing ray and laser plane
    sigma_mm : (n,) depth uncertainty, mm: the line centre's uncertainty times the distance
        the point moves per pixel
    masked : counts of dropped columns by reason ("no_detection", "grazing", "out_of_range",
        and after fusion "camera_conflict")
    """

    points: np.ndarray
    col: np.ndarray
    camera: np.ndarray
    angle_rad: np.ndarray
    sigma_mm: np.ndarray
    masked: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.points)

    @staticmethod
    def empty() -> "Profile":
        return Profile(np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.uint8), np.zeros(0), np.zeros(0), {})

    def take(self, keep: np.ndarray) -> "Profile":
        return Profile(self.points[keep], self.col[keep], self.camera[keep], self.angle_rad[keep],
                       self.sigma_mm[keep], dict(self.masked))

    @staticmethod
    def joined(a: "Profile", b: "Profile") -> "Profile":
        """``a``'s points then ``b``'s, and the columns both dropped, counted together."""
        return Profile(*(np.concatenate([getattr(a, name), getattr(b, name)])
                         for name in ("points", "col", "camera", "angle_rad", "sigma_mm")),
                       merged_counts(a.masked, b.masked))


def merged_counts(*counts: dict) -> dict:
    """Counts by name (dropped columns, detection codes), added up."""
    out: dict = {}
    for each in counts:
        for name, count in each.items():
            out[name] = out.get(name, 0) + int(count)
    return out


def _laser_plane_hits(probe: Probe, u: np.ndarray, v: np.ndarray, camera: int, method: str):
    """Points (n, 3) and triangulation angles (n,) for pixels (u, v); NaN where the ray misses."""
    if method == "exact" and probe.calibration is not None:
        origin, d = probe.measuring_camera(camera).rays(np.column_stack([u, v]))
        n, offset = probe.measuring_plane
        along = d @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (offset - origin @ n) / along
        hits = (t > 0) & np.isfinite(t)
        P = origin + np.where(hits, t, np.nan)[:, None] * d
        angle = np.arcsin(np.minimum(np.abs(along), 1.0))
        return P, np.where(hits, angle, 0.0)
    if method == "exact":
        origin, d = probe.pixel_rays(np.column_stack([u, v]), camera)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -origin[0] / d[:, 0]
        hits = (t > 0) & np.isfinite(t)
        t = np.where(hits, t, np.nan)
        P = origin + t[:, None] * d
        P[:, 0] = 0.0  # on the plane by construction; remove rounding
        angle = np.arcsin(np.minimum(np.abs(d[:, 0]), 1.0))
        return P, np.where(hits, angle, 0.0)
    if probe.calibration is not None:
        raise InputError(f"probe {probe.name!r} is calibrated: Eq. 6 (method 'paper') assumes the nominal "
                         "symmetric geometry; triangulate with method 'exact'")
    cx, cy = probe.principal_point
    f = probe.f_px
    px = (u - cx) * (1.0 if camera == 0 else -1.0)
    py = cy - v
    psi = probe.phi_rad - np.arctan(py / f)
    with np.errstate(divide="ignore", invalid="ignore"):
        P = np.column_stack([np.zeros_like(px), probe.a_mm * px / (f * np.sin(psi)),
                             probe.a_mm / np.tan(psi) + probe.b_mm])
    ok = psi > 0
    P[~ok] = np.nan
    return P, np.where(ok, psi, 0.0)


def triangulate_profile(probe: Probe, line: LineDetection, camera: int = 0, method: str = "exact", *,
                        min_angle_deg: float = MIN_ANGLE_DEG) -> Profile:
    """Triangulate one camera's detected line into a :class:`Profile` (probe frame, valid points only)."""
    _check_camera(camera)
    if method not in TRIANGULATION_METHODS:
        raise InputError(f"triangulation method {method!r} is not one of: {', '.join(TRIANGULATION_METHODS)}")
    if line.shape != (probe.rows_px, probe.cols_px):
        raise InputError(f"the detection is for a {line.shape[0]}x{line.shape[1]} (rows x cols) image, but the "
                         f"probe's sensor is {probe.rows_px}x{probe.cols_px}")
    ok = line.valid & np.isfinite(line.row)
    masked = {"no_detection": int(np.sum(~ok))}
    u = line.col[ok].astype(np.float64)
    v = line.row[ok].astype(np.float64)
    sigma_px = np.full(len(u), UNKNOWN_SIGMA_PX) if line.sigma_px is None else line.sigma_px[ok].astype(np.float64)
    # The points, and (for the sensitivity below) the points ±0.05 px along the triangulation
    # direction, where the ray's direction is as good as linear: one call for all three.
    n = len(u)
    P3, angle3 = _laser_plane_hits(probe, np.tile(u, 3), np.concatenate([v, v - 0.05, v + 0.05]), camera, method)
    P, angle, Pa, Pb = P3[:n], angle3[:n], P3[n:2 * n], P3[2 * n:]
    grazing = ~np.isfinite(P).all(axis=1) | (angle < np.radians(min_angle_deg))
    z0, z1 = probe.z_range_mm
    tol = 1e-9 * max(abs(z0), abs(z1), 1.0)
    with np.errstate(invalid="ignore"):
        outside = ~grazing & ((P[:, 2] < z0 - tol) | (P[:, 2] > z1 + tol) | (v < -0.5) | (v > probe.rows_px - 0.5))
    masked["grazing"] = int(np.sum(grazing))
    masked["out_of_range"] = int(np.sum(outside))
    keep = ~grazing & ~outside
    u, v, P, angle, sigma_px = u[keep], v[keep], P[keep], angle[keep], sigma_px[keep]
    # Sensitivity: how far the point moves per pixel along the triangulation direction.
    dP = Pa[keep] - Pb[keep]
    sigma = 10.0 * np.sqrt(np.einsum("ij,ij->i", dP, dP)) * sigma_px
    return Profile(P, u, np.full(len(P), CAMERA_BITS[camera], np.uint8), angle, sigma, masked)


def triangulate(probe: Probe, line: LineDetection, camera: int = 0, method: str = "exact", *,
                min_angle_deg: float = MIN_ANGLE_DEG) -> np.ndarray:
    """Points (n, 3) in mm, probe frame, for the valid columns of ``line`` seen by ``camera``."""
    return triangulate_profile(probe, line, camera, method, min_angle_deg=min_angle_deg).points


TIE_SPACING = 1e-3  # the two cameras' samples this close (share of the spacing) are the same Y


def fuse_profiles(p0: Profile, p1: Profile, *, gate_sigmas: float = 5.0, gate_floor_mm: float = 0.05,
                  max_gap_factor: float = 2.5) -> Profile:
    """Combine the two cameras' profiles of one frame into one.

    Both cameras see the same laser line, sampled at different Y. Where camera 1's
    profile covers a camera-0 point (neighbours on both sides in Y, no gap wider
    than ``max_gap_factor`` × its typical spacing), its Z is interpolated there and
    the two are averaged with weights 1/σ²; the point is marked 3 (both) and its σ
    is the larger of the average's and half the two cameras' difference. Where the two
    disagree by more than the gate (gate_sigmas·σ combined, at least gate_floor_mm),
    at least one camera sees something other than the lit strip on the laser plane (an
    occlusion edge hiding part of it, a reflection): neither can be trusted, and both
    are dropped (counted as "camera_conflict"). Points only one camera sees are kept
    as they are, so one camera fills in where the other is occluded.
    """
    if len(p0) == 0 or len(p1) == 0:
        other = p1 if len(p0) == 0 else p0
        out = other.take(np.ones(len(other), bool))
        out.masked = merged_counts(p0.masked, p1.masked)
        out.masked["fused"] = 0
        return out
    o0 = np.argsort(p0.points[:, 1], kind="stable")
    o1 = np.argsort(p1.points[:, 1], kind="stable")
    a, b = p0.take(o0), p1.take(o1)
    y0, y1 = a.points[:, 1], b.points[:, 1]
    z1, s1 = b.points[:, 2], b.sigma_mm

    def covered(yq, ys):
        """Index of the right neighbour in ys for each yq, and whether both neighbours are close.

        The two cameras of a symmetric probe see the same Y on a surface symmetric about the
        laser plane, to rounding: a point level with the other camera's sample (within
        TIE_SPACING of the spacing) counts as at that sample, so that rounding, not the
        surface, does not decide whether it lies inside the other camera's run or beyond it."""
        if len(ys) < 2:
            return np.zeros(len(yq), int), np.zeros(len(yq), bool)
        spacing = np.median(np.diff(ys))
        j = np.clip(np.searchsorted(ys, yq), 1, len(ys) - 1)
        nearest = np.where(yq - ys[j - 1] <= ys[j] - yq, j - 1, j)
        yq = np.where(np.abs(yq - ys[nearest]) <= TIE_SPACING * spacing, ys[nearest], yq)
        inside = (yq >= ys[0]) & (yq <= ys[-1])
        jj = np.clip(np.searchsorted(ys, yq), 1, len(ys) - 1)
        gap = ys[jj] - ys[jj - 1]
        return jj, inside & (gap <= max_gap_factor * max(spacing, 1e-12))

    j, cov0 = covered(y0, y1)
    w = np.where(cov0, (y0 - y1[j - 1]) / np.maximum(y1[j] - y1[j - 1], 1e-300), 0.0)
    z1_at = (1 - w) * z1[j - 1] + w * z1[j]
    s1_at = (1 - w) * s1[j - 1] + w * s1[j]
    gate = np.maximum(gate_sigmas * np.hypot(a.sigma_mm, s1_at), gate_floor_mm)
    agree = cov0 & (np.abs(a.points[:, 2] - z1_at) <= gate)

    fused = a.take(np.ones(len(a), bool))
    wa, wb = 1.0 / a.sigma_mm[agree] ** 2, 1.0 / s1_at[agree] ** 2
    fused.points[agree, 2] = (wa * a.points[agree, 2] + wb * z1_at[agree]) / (wa + wb)
    fused.sigma_mm[agree] = np.maximum(1.0 / np.sqrt(wa + wb), 0.5 * np.abs(a.points[agree, 2] - z1_at[agree]))
    fused.camera[agree] = 3
    # Camera-1 points that camera 0's profile covers are dropped: they agreed (and are in the
    # average) or they conflict with it (and neither camera's point is kept).
    k, cov1 = covered(y1, y0)
    near0 = np.where(cov1, np.minimum(np.abs(y1 - y0[k - 1]), np.abs(y1 - y0[k])), np.inf)
    conflict0 = cov0 & ~agree
    drop1 = cov1 & np.isfinite(near0)
    conflict1 = drop1 & (conflict0[k - 1] | conflict0[k])
    # A point only one camera sees has no second opinion: its σ also carries how far each
    # camera's points stray from the other's in this frame (the RMS of half the differences
    # on the fused points, each camera's share of them).
    spread = float(np.sqrt(np.mean((a.points[agree, 2] - z1_at[agree]) ** 2) / 2.0)) if agree.any() else 0.0
    fused.sigma_mm[~agree] = np.hypot(fused.sigma_mm[~agree], spread)
    fused = fused.take(~conflict0)
    extra = b.take(~drop1)
    extra.sigma_mm = np.hypot(extra.sigma_mm, spread)
    out = Profile.joined(fused, extra)  # (their counts: p0's and p1's)
    out.masked["fused"] = int(np.sum(agree))
    out.masked["camera_conflict"] = int(np.sum(conflict0) + np.sum(conflict1))
    order = np.argsort(out.points[:, 1], kind="stable")
    return out.take(order)

