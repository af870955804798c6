"""Cleaning one camera's profile before it joins the cloud: steep points and segment ends.

A profile is a chain of points along the laser line, one per sensor column. Two
kinds of point in it are unreliable however good the detector is:

- **Steep points**: where the surface turns almost parallel to the laser (the
  in-plane incidence angle, between the laser ray and the profile's own normal in
  the laser plane, nears 90°), the line's image is stretched and skewed, and its
  centre no longer marks the laser plane. The incidence is read off the profile
  itself (central differences of neighbouring points), as a real profiler does;
  a step between neighbours steeper than that (or than 80°) is a discontinuity
  (an occlusion, a step edge), not a surface.
- **Segment ends**: at the end of a run of points (the part's silhouette, a step
  edge, the end of the line) some of the rows a column's profile spans see
  another surface, so the profile is cut on one side and its fitted centre is
  pulled by up to a pixel. ``edge_px`` columns are dropped at each end of every
  run; runs break where a column is missing or the incidence says "jump".

Both act per camera, in the probe frame, before the two cameras are fused.

Each point's σ comes from the detector (``detect._centre_sigma``), which reads the
strip's curvature across the line off the profile's asymmetry. An earlier version
added the profile's bend between neighbouring points (the curvature along the line)
as a stand-in; along the line a column sees only its own slice of the strip, so that
bend said little about the error and, on the real-parts bench, dropped good points
near every crease (the bunny kept 73 % of its measurable surface covered with it, 77 %
without, its RMS 18.0 → 15.0 µm).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError, check_whole
from .triangulate import Profile


@dataclass(frozen=True)
class ProfileFilter:
    """max_incidence_deg: drop points whose in-plane incidence exceeds it (90: keep all);
    edge_px: columns dropped at each end of every run of points (0: none);
    max_sigma_mm: after fusion, drop points whose depth uncertainty exceeds it (inf: keep all)."""

    max_incidence_deg: float = 90.0
    edge_px: int = 0
    max_sigma_mm: float = float("inf")

    def __post_init__(self) -> None:
        if not (isinstance(self.max_incidence_deg, (int, float)) and 0 < self.max_incidence_deg <= 90):
            raise InputError(f"max_incidence_deg must be in (0, 90], got {self.max_incidence_deg!r}")
        check_whole(self.edge_px, "edge_px", 0, 1000)
        if not (isinstance(self.max_sigma_mm, (int, float)) and self.max_sigma_mm > 0):
            raise InputError(f"max_sigma_mm must be > 0 (inf: keep every point), got {self.max_sigma_mm!r}")

    @property
    def off(self) -> bool:
        return self.max_incidence_deg >= 90 and self.edge_px == 0


JUMP_DEG = 80.0  # neighbours at least this steep apart are a discontinuity, not a surface


def incidence_deg(points: np.ndarray, col: np.ndarray, jump_deg: float = JUMP_DEG) -> tuple[np.ndarray, np.ndarray]:
    """(in-plane incidence (n,) degrees, jump after point i (n-1,) bool) for a profile
    ordered by column. Points are in the probe frame; the laser sits at the origin
    and the laser plane is x = 0, so only y and z count. A step between neighbours
    steeper than ``jump_deg`` (or a missing column) is a jump."""
    n = len(points)
    if n < 2:
        return np.zeros(n), np.zeros(max(n - 1, 0), bool)
    y, z = points[:, 1], points[:, 2]
    dy, dz = np.diff(y), np.diff(z)
    rays = np.stack([y, z], axis=1)
    rays /= np.maximum(np.sqrt(np.einsum("ij,ij->i", rays, rays)), 1e-300)[:, None]

    def angle_to_rays(ty, tz, r):
        t = np.stack([ty, tz], axis=1)
        t /= np.maximum(np.sqrt(np.einsum("ij,ij->i", t, t)), 1e-300)[:, None]
        # The surface normal is perpendicular to the tangent t; incidence = 90° − angle(t, ray).
        cos_t_ray = np.abs(np.sum(t * r, axis=1))
        return np.degrees(np.arcsin(np.minimum(np.maximum(cos_t_ray, 0.0), 1.0)))

    step_angle = angle_to_rays(dy, dz, 0.5 * (rays[1:] + rays[:-1]))
    jump = (np.diff(col) > 1.5) | (step_angle >= jump_deg)
    # Central differences inside runs; one-sided where a neighbour is missing or across a jump.
    left_ok = np.concatenate([[False], ~jump])
    right_ok = np.concatenate([~jump, [False]])
    prev = np.where(left_ok, np.arange(n) - 1, np.arange(n))
    nxt = np.where(right_ok, np.arange(n) + 1, np.arange(n))
    alone = prev == nxt
    ty, tz = y[nxt] - y[prev], z[nxt] - z[prev]
    inc = angle_to_rays(np.where(alone, 1.0, ty), np.where(alone, 0.0, tz), rays)
    inc[alone] = 90.0  # a lone point has no slope to judge: it counts as steep
    return inc, jump


def drop_uncertain(profile: Profile, f: ProfileFilter) -> Profile:
    """The profile without the points whose σ exceeds ``f.max_sigma_mm`` (counted as
    "uncertain"): the fused profile's last cleaning, once each point's σ is final."""
    keep = ~(profile.sigma_mm > f.max_sigma_mm)
    out = profile.take(keep)
    out.masked = dict(profile.masked)
    out.masked["uncertain"] = out.masked.get("uncertain", 0) + int(np.sum(~keep))
    return out


def filter_profile(profile: Profile, f: ProfileFilter) -> Profile:
    """The profile without its steep points and segment ends; counts in ``masked``."""
    if f.off or len(profile) == 0:
        return profile
    order = np.argsort(profile.col, kind="stable")
    p = profile.take(order)
    inc, jump = incidence_deg(p.points, p.col, min(f.max_incidence_deg, JUMP_DEG))
    steep = inc > f.max_incidence_deg + 1e-9 if f.max_incidence_deg < 90 else np.zeros(len(p), bool)
    # Runs break at missing columns, at jumps, and around steep points (which are dropped).
    breaks = np.concatenate([[True], jump | steep[1:] | steep[:-1]])
    run_id = np.cumsum(breaks)
    edge = np.zeros(len(p), bool)
    if f.edge_px > 0:
        idx = np.arange(len(p))
        starts = np.flatnonzero(breaks)
        ends = np.append(starts[1:], len(p))
        start_of, end_of = starts[run_id - 1], ends[run_id - 1]
        edge = (idx - start_of < f.edge_px) | (end_of - 1 - idx < f.edge_px)
    edge &= ~steep
    keep = ~(steep | edge)
    out = p.take(keep)
    out.masked = dict(p.masked)
    out.masked["steep"] = out.masked.get("steep", 0) + int(steep.sum())
    out.masked["edge"] = out.masked.get("edge", 0) + int(edge.sum())
    return out

