"""Closed-form inverse kinematics for 6R arms with a spherical wrist (Viper s650, Puma 560).

Applies to standard-DH arms with α1 = ±90°, α2 = 0 (joints 2 and 3 parallel),
α3, α4, α5 = ±90°, α6 = 0, and a4 = a5 = a6 = d5 = 0 (axes 4, 5, 6 meet in the
wrist centre). a1 (shoulder forward offset), d2 + d3 (shoulder side offset), a3
(elbow offset) and d6 (flange distance) may be anything. All DH angles below are
θ = q + offset.

Derivation, for a flange pose (R, p) in DH frame 0:

1. Wrist centre w = p − d6·z6 depends on θ1..θ3 only.
2. In frame 1 the wrist centre has z = d2 + d3 whatever θ2, θ3 (both rotate about
   axes parallel to z1). With z1 = sin α1·(sin θ1, −cos θ1, 0) that gives
   w_x sin θ1 − w_y cos θ1 = (d2 + d3)·sin α1: two solutions for θ1
   (shoulder left/right). The wrist on the joint-1 axis is the shoulder singularity.
3. In frame 1 the remaining (x, y) is a planar two-link arm a2, L3 = √(a3² + d4²)
   with the second link rotated by β = atan2(d4 sin α3, a3): law of cosines gives
   two solutions for θ3 (elbow up/down), then θ2. |cos| = 1 is the stretched elbow.
4. M = R_3^0ᵀ R = R_Z(θ4)R_X(α4)R_Z(θ5)R_X(α5)R_Z(θ6). Its third column is
   (sα5 sin θ5 cos θ4, sα5 sin θ5 sin θ4, −sα4 sα5 cos θ5) with sαk = sin αk = ±1,
   giving θ5 (two signs of sin θ5: the wrist flip) and then θ4. θ6 is read from
   what θ4 and θ5 leave over, which keeps the rotation exact near the wrist
   singularity sin θ5 = 0; there only θ4 ± θ6 is defined and θ4 is taken from the seed.

Up to 2 × 2 × 2 = 8 solutions per target. The caller wraps them into joint limits
and verifies every one by forward kinematics; nothing here decides success.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..tolerances import TOL

# A unit-vector component below this is treated as exactly zero (singular wrist,
# wrist centre on the joint-1 axis).
SINGULAR = TOL.singular
# A cosine this far past ±1 is rounding, not a pose out of reach: a straight elbow (θ3 = 0)
# computes K a few ulps over 1, and both the batched and the one-target solves must keep it.
COS_SLACK = 1.0 + TOL.singular
# The two choices of each of shoulder, elbow and wrist, as a sign and as a half turn.
_SHOULDER_SIGN = np.array([1.0, -1.0])
_SHOULDER_TURN = np.array([0.0, np.pi])


@dataclass(frozen=True)
class SphericalWristArm:
    """The numbers the closed form needs, taken from a Robot's DH table (mm, ±1 signs)."""

    a1: float
    d1: float
    a2: float
    a3: float
    d4: float
    d6: float
    shoulder_offset: float  # d2 + d3: the wrist centre's z in frame 1
    s1: float  # sin α1 (±1)
    s3: float  # sin α3
    s4: float  # sin α4
    s5: float  # sin α5
    L3: float  # √(a3² + d4²): elbow-to-wrist length
    beta: float  # atan2(d4·sin α3, a3): angle of the elbow-to-wrist link in frame 3
    scale: float  # characteristic length, for relative thresholds


def spherical_wrist_arm(robot) -> tuple[SphericalWristArm | None, str]:
    """The closed-form parameters of ``robot``, or (None, reason) when it does not qualify."""
    ca, sa = np.asarray(robot._ca), np.asarray(robot._sa)
    a, d = robot.a_mm, robot.d_mm
    scale = robot.length_scale_mm
    tol = 1e-12

    def right_angle(i):
        return abs(ca[i]) <= tol and abs(abs(sa[i]) - 1.0) <= tol

    checks = [
        (right_angle(0), "α1 must be ±90°"),
        (abs(sa[1]) <= tol and ca[1] > 0, "α2 must be 0 (joints 2 and 3 parallel)"),
        (right_angle(2), "α3 must be ±90°"),
        (right_angle(3), "α4 must be ±90°"),
        (right_angle(4), "α5 must be ±90°"),
        (abs(sa[5]) <= tol and ca[5] > 0, "α6 must be 0"),
        (max(abs(a[3]), abs(a[4]), abs(a[5]), abs(d[4])) <= tol * scale,
         "a4, a5, a6 and d5 must be 0 (wrist axes meeting in one point)"),
        (abs(a[1]) > tol * scale, "a2 must not be 0"),
        (np.hypot(a[2], d[3]) > tol * scale, "a3 and d4 must not both be 0"),
    ]
    for ok, reason in checks:
        if not ok:
            return None, f"no closed form for {robot.name}: {reason}"
    s3 = float(np.sign(sa[2]))
    return SphericalWristArm(
        a1=float(a[0]), d1=float(d[0]), a2=float(a[1]), a3=float(a[2]), d4=float(d[3]), d6=float(d[5]),
        shoulder_offset=float(d[1] + d[2]),
        s1=float(np.sign(sa[0])), s3=s3, s4=float(np.sign(sa[3])), s5=float(np.sign(sa[4])),
        L3=float(np.hypot(a[2], d[3])), beta=float(np.arctan2(d[3] * s3, a[2])), scale=scale,
    ), ""


@dataclass
class Branches:
    """All closed-form branches for n targets.

    theta : (n, 8, 6) DH angles (θ, not q), branch = 4·shoulder + 2·elbow + wrist
    shoulder_ok : (n,) and elbow_ok : (n, 2) (one per shoulder) or (n, 8) bool, False where
        the geometry had no real solution and a clamped (best-effort) value was used;
        :meth:`geometry_ok` spreads them over the eight branches (only failures need it)
    """

    theta: np.ndarray
    shoulder_ok: np.ndarray
    elbow_ok: np.ndarray

    def geometry_ok(self) -> np.ndarray:
        """(n, 8) bool: both the shoulder's and the elbow's equations had a real solution."""
        n = len(self.shoulder_ok)
        elbow = np.repeat(self.elbow_ok, 8 // self.elbow_ok.shape[1], axis=1)
        return self.shoulder_ok[:, None] & elbow.reshape(n, 8)


def flange_targets(robot, T_world: np.ndarray) -> np.ndarray:
    """Tool targets (n, 4, 4) in the world -> flange poses (n, 4, 4) in DH frame 0."""
    F = T_world
    if not robot._base_is_identity:
        F = robot._base_inverse @ F
    if not robot._tool_is_identity:
        F = F @ robot._tool_inverse
    return F


def shoulder_angles(px, py, Ds, scale: float, seed1):
    """The shoulder equation px sin θ1 − py cos θ1 = Ds of both closed forms (the wrist point's
    offset from the plane of the arm, along the joint-2 axis): θ1 = φ + g or φ + π − g.
    Returns (φ, g, solvable); on the joint-1 axis φ is the seed's θ1."""
    r = np.hypot(px, py)
    on_axis = r <= SINGULAR * scale
    phi = np.where(on_axis, seed1, np.arctan2(py, px))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(on_axis, np.where(abs(Ds) <= SINGULAR * scale, 0.0, np.inf), Ds / r)
    return phi, np.arcsin(np.clip(ratio, -1.0, 1.0)), np.abs(ratio) <= COS_SLACK


def branches(arm: SphericalWristArm, F: np.ndarray, seed_theta: np.ndarray) -> Branches:
    """Closed-form DH angles for flange poses F (n, 4, 4) in DH frame 0.

    seed_theta : (n, 6) DH angles used where a joint is undetermined (θ1 with the
    wrist centre on the joint-1 axis, θ4 at the wrist singularity).
    """
    n = F.shape[0]
    R = F[:, :3, :3]
    w = F[:, :3, 3] - arm.d6 * R[:, :, 2]
    px, py, pz = w[:, 0], w[:, 1], w[:, 2]

    # -- θ1 (shoulder): w_x sin θ1 − w_y cos θ1 = D·sin α1 --------------------
    phi, g, shoulder_ok = shoulder_angles(px, py, arm.shoulder_offset * arm.s1, arm.scale, seed_theta[:, 0])
    th1 = phi[:, None] + _SHOULDER_TURN + _SHOULDER_SIGN * g[:, None]  # (n, 2): φ + g, φ + π − g

    # -- θ2, θ3 (planar arm in frame 1) ----------------------------------------
    c1, s1 = np.cos(th1), np.sin(th1)
    x = c1 * px[:, None] + s1 * py[:, None] - arm.a1
    y = np.broadcast_to((arm.s1 * (pz - arm.d1))[:, None], x.shape)
    K = (x * x + y * y - arm.a2 ** 2 - arm.L3 ** 2) / (2.0 * arm.a2 * arm.L3)
    elbow_ok = np.abs(K) <= COS_SLACK
    delta0 = np.arccos(np.clip(K, -1.0, 1.0))
    delta = delta0[:, :, None] * _SHOULDER_SIGN  # (n, 2, 2): elbow up and down
    xx, yy = x[:, :, None], y[:, :, None]
    th3 = arm.beta + delta
    th2 = np.arctan2(yy, xx) - np.arctan2(arm.L3 * np.sin(delta), arm.a2 + arm.L3 * np.cos(delta))

    # -- wrist -----------------------------------------------------------------
    # M = R_3^0ᵀ R, needed in columns 0 and 2 only. With cos α = 0 the columns of
    # R_3^0 = R_Z(θ1)R_X(α1)R_Z(θ2+θ3)R_X(α3) are, in closed form,
    #   (c1 c23, s1 c23, sα1 s23),  sα1 sα3 (s1, −c1, 0),  sα3 (c1 s23, s1 s23, −sα1 c23).
    c1, s1 = c1[:, :, None], s1[:, :, None]
    th23 = th2 + th3
    c23, s23 = np.cos(th23), np.sin(th23)
    sa1, sa3, sa4, sa5 = arm.s1, arm.s3, arm.s4, arm.s5

    def m_column(k):
        rx, ry, rz = (R[:, j, k][:, None, None] for j in range(3))
        m0 = c1 * c23 * rx + s1 * c23 * ry + sa1 * s23 * rz
        m1 = sa1 * sa3 * (s1 * rx - c1 * ry)
        m2 = sa3 * (c1 * s23 * rx + s1 * s23 * ry - sa1 * c23 * rz)
        return m0, m1, m2

    m00, m10, m20 = m_column(0)
    m02, m12, m22 = m_column(2)
    c5 = -m22 * sa5 * sa4
    h = np.hypot(m02, m12)
    singular = h <= SINGULAR
    th5 = np.arctan2(h[..., None] * _SHOULDER_SIGN, c5[..., None])  # (n, 2, 2, 2): wrist up and down
    th4_up = np.arctan2(sa5 * m12, sa5 * m02)
    seed4 = np.broadcast_to(seed_theta[:, 3, None, None], th4_up.shape)
    th4_up = np.where(singular, seed4, th4_up)
    th4 = np.where(singular[..., None], seed4[..., None], th4_up[..., None] + _SHOULDER_TURN)
    # θ6 from what θ4 and θ5 leave: N = (R_Z(θ4)R_X(α4)R_Z(θ5)R_X(α5))ᵀ M = R_Z(θ6), and
    # that product's first two columns are (c4 c5, s4 c5, sα4 s5) and sα4 sα5 (s4, −c4, 0).
    c4, s4 = np.cos(th4), np.sin(th4)
    c5b, s5b = np.cos(th5), np.sin(th5)
    m00, m10, m20 = m00[..., None], m10[..., None], m20[..., None]
    n00 = c4 * c5b * m00 + s4 * c5b * m10 + sa4 * s5b * m20
    n10 = sa4 * sa5 * (s4 * m00 - c4 * m10)
    th6 = np.arctan2(n10, n00)

    theta = np.empty((n, 2, 2, 2, 6))  # filled by broadcasting: few numpy calls per target
    theta[..., 0] = th1[:, :, None, None]
    theta[..., 1] = th2[..., None]
    theta[..., 2] = th3[..., None]
    theta[..., 3], theta[..., 4], theta[..., 5] = th4, th5, th6
    return Branches(theta=theta.reshape(n, 8, 6), shoulder_ok=shoulder_ok, elbow_ok=elbow_ok)


def wrist_and_shoulder_one(F: np.ndarray, d6: float, offset: float, s1: float, scale: float):
    """For one flange pose F (4, 4): (rotation rows as floats, the wrist point p − d6·z6, and
    the shoulder equation's φ and g as in :func:`shoulder_angles`), or None where the wrist
    point lies on the joint-1 axis or nearer it than the offset allows (the batch forms
    handle those)."""
    (r00, r01, r02, px), (r10, r11, r12, py), (r20, r21, r22, pz) = F[:3].tolist()
    w = (px - d6 * r02, py - d6 * r12, pz - d6 * r22)
    r = math.hypot(w[0], w[1])
    if r <= SINGULAR * scale or abs(offset * s1) > r:
        return None
    rows = ((r00, r01, r02), (r10, r11, r12), (r20, r21, r22))
    return rows, w, math.atan2(w[1], w[0]), math.asin(offset * s1 / r)


def branches_one(arm: SphericalWristArm, F: np.ndarray) -> list[tuple[float, ...] | None] | None:
    """The eight branches of :func:`branches` for one flange pose F (4, 4), in the same order,
    computed on Python floats: for a single target numpy's cost per call outweighs the
    arithmetic several times over. A branch the geometry gives no real solution is None.
    None for the whole target where it is singular (the wrist centre on the joint-1 axis,
    sin θ5 = 0) or the shoulder cannot reach it: :func:`branches` handles those with the
    seed."""
    start = wrist_and_shoulder_one(F, arm.d6, arm.shoulder_offset, arm.s1, arm.scale)
    if start is None:
        return None
    ((r00, _, r02), (r10, _, r12), (r20, _, r22)), (px, py, pz), phi, g = start
    sa1, sa3, sa4, sa5 = arm.s1, arm.s3, arm.s4, arm.s5
    out = []
    for th1 in (phi + g, phi + math.pi - g):
        c1, s1 = math.cos(th1), math.sin(th1)
        x = c1 * px + s1 * py - arm.a1
        y = sa1 * (pz - arm.d1)
        K = (x * x + y * y - arm.a2 ** 2 - arm.L3 ** 2) / (2.0 * arm.a2 * arm.L3)
        if abs(K) > COS_SLACK:  # the elbow cannot reach this shoulder's wrist centre
            out.extend([None] * 4)
            continue
        delta0 = math.acos(max(-1.0, min(1.0, K)))
        for delta in (delta0, -delta0):
            th3 = arm.beta + delta
            th2 = math.atan2(y, x) - math.atan2(arm.L3 * math.sin(delta), arm.a2 + arm.L3 * math.cos(delta))
            c23, s23 = math.cos(th2 + th3), math.sin(th2 + th3)
            # Columns 0 and 2 of M = R_3^0ᵀ R, as in branches().
            m00 = c1 * c23 * r00 + s1 * c23 * r10 + sa1 * s23 * r20
            m10 = sa1 * sa3 * (s1 * r00 - c1 * r10)
            m20 = sa3 * (c1 * s23 * r00 + s1 * s23 * r10 - sa1 * c23 * r20)
            m02 = c1 * c23 * r02 + s1 * c23 * r12 + sa1 * s23 * r22
            m12 = sa1 * sa3 * (s1 * r02 - c1 * r12)
            m22 = sa3 * (c1 * s23 * r02 + s1 * s23 * r12 - sa1 * c23 * r22)
            h = math.hypot(m02, m12)
            if h <= SINGULAR:
                return None
            c5 = -m22 * sa5 * sa4
            th4_up = math.atan2(sa5 * m12, sa5 * m02)
            for sign, turn in ((1.0, 0.0), (-1.0, math.pi)):
                th5 = math.atan2(h * sign, c5)
                th4 = th4_up + turn
                c4, s4, c5b, s5b = math.cos(th4), math.sin(th4), math.cos(th5), math.sin(th5)
                n00 = c4 * c5b * m00 + s4 * c5b * m10 + sa4 * s5b * m20
                n10 = sa4 * sa5 * (s4 * m00 - c4 * m10)
                out.append((th1, th2, th3, th4, th5, math.atan2(n10, n00)))
    return out
