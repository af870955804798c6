"""The laser line: its power, its Gaussian profile across the line, and that profile built
from spot lights (for Eevee).

Power: a Lambertian surface of albedo ρ at distance r lit head-on by a point light
of power P has radiance ρ·P / (4π·π·r²) (Cycles rates its spot lights like point
lights). :func:`laser_power_w` inverts that to put the line's peak at a chosen
level of the film at mid-range; Blender's lights (``addon/scene/laser.py``) and the
ray-cast engine (``addon/core/optics/raycast.py``) both take their power from it.

The probe's line is a Gaussian across its width: intensity exp(−v²/2) at v line σ
from the laser plane. Cycles renders that exactly with a gobo (a node tree on the
light, ``addon/scene/laser.py``); Eevee ignores light node trees. What Eevee and
Cycles both shape is a spot light's cone. Blender squeezes the cone with the light
object's scale: a ray leaving at direction n (light frame, n_z along the beam) counts
as if at the angle θ' with tan θ' = |(n_x / s_x, n_y / s_y)| / n_z, and the spot's
blend softens its edge; with blend 1 the intensity is

    smoothstep((cos θ' − cos α) / (1 − cos α)),   α = half the spot size,

which is what :func:`spot_mask` evaluates. Squeezed across the line (s_x small) and
stretched along it (s_y = :data:`SPOT_STRETCH`, so that the mask hardly changes over the
±17° of the line the default probe's cameras see, nor over its 60° fan), one spot gives a
line with a smooth, symmetric profile across it. But smoothstep has no slope at
its top, so the profile is flat to fourth order at its centre, and the three-point
Gaussian fit of the detector misreads it by an amount that depends on the line's width
in pixels: for a 70° cone and a profile as wide as the Gaussian, 0.011 px RMS over the
sub-pixel phases at σ = 0.55 px (the default probe) and 0.045 px at 1.1 px, against 0
for the Gaussian.

So the line is a sum of :data:`SPOT_COMPONENTS`: five coaxial spots, each with its own
cone angle, squeezed to its own width and given its share of the power. Widths, angles
and shares were fitted (least squares of the relative difference over ±3 σ, shares
summing to 1) to the Gaussian: the sum is within 0.11 % of it over ±2.5 σ and 0.21 %
over ±3 σ. Read by the three-point fit at line σ of 0.45–2 px, its centre is at most
0.003 px off (tests/core/test_laser_profile.py). Narrower images of the line (a
surface turned away from the camera across the line) sample its profile beyond 3 σ,
where the sum departs from the Gaussian: the fit is up to 0.015 px off at σ = 0.4 px,
0.04 px at 0.35 px and 0.1 px at 0.27 px, and the detector's σ grows with it.
One component is wide (a quarter of the peak, reaching out to 9 σ): a real line laser has
such a pedestal too. Along the line the profile keeps its shape: at 30° from the beam it
is within 0.6 % of the Gaussian over ±2.5 σ. The stretch lets the line reach almost to
±90° along the laser plane, dimming, where a real fan ends at its opening angle; no
camera of the probe looks there.
"""

from __future__ import annotations

import math

import numpy as np

from .surfaces import WORKPIECE_GREY

LASER_RGB = (1.0, 0.0, 0.0)  # the laser's colour in the render (the detector reads red against green and blue)


def mid_range_mm(probe) -> float:
    """The middle of the probe's measuring range (mm from the laser, along the beam)."""
    z0, z1 = probe.z_range_mm
    return 0.5 * (z0 + z1)


def laser_power_w(probe, peak: float = 0.5, albedo: float = WORKPIECE_GREY, distance_mm: float | None = None) -> float:
    """Light power (W) that puts the line peak at ``peak`` (linear film units) on a
    head-on Lambertian surface of ``albedo`` (default: the grey workpiece's) at
    ``distance_mm`` (default mid-range)."""
    r = (distance_mm or mid_range_mm(probe)) * 1e-3
    return float(peak * math.pi * r * r * 4.0 * math.pi / albedo)


def angular_sigma_rad(probe) -> float:
    """Gaussian σ of the line across the laser plane, as an angle: (1/e² width / 4) / mid-range."""
    return probe.line_width_mm / 4.0 / mid_range_mm(probe)


def gobo_strength(n_x, sigma_rad: float) -> np.ndarray:
    """The gobo laser's strength for emission directions whose unit vector has ``n_x`` across
    the laser plane (light frame): exp(−n_x² / 2σ²), 1 on the plane."""
    n_x = np.asarray(n_x, dtype=np.float64)
    return np.exp(-(n_x * n_x) / (2.0 * sigma_rad * sigma_rad))

SPOT_STRETCH = 10.0  # the lights' scale along the line (s_y)
# (share of the peak, edge of the squeezed cone in line σ, half the spot's cone angle in
# degrees), largest share first; the shares sum to 1.
SPOT_COMPONENTS = (
    (0.54222166, 3.3046771, 69.207548),
    (0.25450513, 9.0996739, 87.202562),
    (0.11951640, 2.6841471, 63.673270),
    (0.06387746, 2.3246174, 57.956383),
    (0.01987872, 0.4632819, 73.953633),
)


def spot_mask(tan_scaled, half_angle_rad: float) -> np.ndarray:
    """Blender's spot light intensity (blend 1) for rays whose squeezed angle θ' has tangent ``tan_scaled``."""
    t = np.abs(np.asarray(tan_scaled, dtype=np.float64))
    c = math.cos(half_angle_rad)
    x = np.clip((1.0 / np.sqrt(1.0 + t * t) - c) / (1.0 - c), 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def spot_line_profile(v, along_rad: float = 0.0) -> np.ndarray:
    """The components' sum at ``v`` line σ from the laser plane (1 on the plane), at
    ``along_rad`` from the beam along the line; compare exp(−v²/2)."""
    v = np.asarray(v, dtype=np.float64)
    along = math.tan(along_rad) / SPOT_STRETCH
    total = np.zeros_like(v)
    for share, edge, half_angle_deg in SPOT_COMPONENTS:
        alpha = math.radians(half_angle_deg)
        total += share * spot_mask(np.hypot(v / edge * math.tan(alpha), along), alpha)
    return total


def spot_squeezes(sigma_rad: float) -> list[float]:
    """Per component, the light object's scale across the line (s_x) for a line of angular σ ``sigma_rad``.

    A ray at angle ψ across the laser plane has tan θ' = tan ψ / s_x; the component's edge
    (tan θ' = tan α) sits at ψ = edge · σ, so s_x = edge · σ / tan α (tan ψ ≈ ψ: σ is a few mrad).
    """
    if not (math.isfinite(sigma_rad) and 0 < sigma_rad < 0.1):
        raise ValueError(f"the line's angular σ must be in (0, 0.1) rad, got {sigma_rad}")
    return [edge * sigma_rad / math.tan(math.radians(half_angle_deg)) for _, edge, half_angle_deg in SPOT_COMPONENTS]
