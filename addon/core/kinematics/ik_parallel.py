"""Closed-form inverse kinematics for 6R arms with three parallel middle axes and an offset
wrist: the Universal Robots family (UR3/5/10/16/20/30, their e-Series) and their kin.

Applies to standard-DH arms with α1 = ±90°, α2 = α3 = 0 (joints 2, 3 and 4 parallel),
α4 = ±90°, α5 = ±90°, α6 = 0, and a4 = a5 = a6 = 0. a1, d1, d2, d3, d4, d5 and d6 may be
anything; a2 and a3 must not be 0. Angles below are DH angles θ = q + offset; sαk is
sin αk = ±1. Frames follow T_i^{i−1} = R_Z(θi)·T_Z(di)·T_X(ai)·R_X(αi).

Derivation, for a flange pose (R, p) in DH frame 0 (z6 = R·ẑ, and so on):

1. Joint 6 turns about z5 = z6, so the origin of frame 5 is o5 = p − d6·z6. The axes
   z1 = z2 = z3 (joints 2–4) are parallel, z1 = sα1·(sin θ1, −cos θ1, 0), and every
   offset along them adds up: o5·z1 = d2 + d3 + d4 =: D (the a's and d5 lie across
   z1). So o5x sin θ1 − o5y cos θ1 = sα1·D: two solutions for θ1 (shoulder left and
   right), none when the wrist is nearer the base axis than |D|.
2. In frame 4, z1 = (0, sα4, 0) and z6 = sα5·(sin θ5, −cos θ5, 0), so
   z1·z6 = −sα4 sα5 cos θ5: two solutions for θ5 (wrist up and down).
3. In frame 6, z1 = (sα4 sin θ5 cos θ6, −sα4 sin θ5 sin θ6, ·): θ6 from the flange's
   x and y axes against z1. At sin θ5 = 0 (wrist singularity: axis 6 lines up with
   axes 2–4) only θ2 + θ3 + θ4 + θ6 is defined: frame 4 is taken from the seed's
   θ2 + θ3 + θ4 (turned, where that leaves the elbow short, to the middle of its
   reach), and θ6 follows from the flange's x axis.
4. With θ5 and θ6 known, frame 4 is known: x4 = R·(cos θ5 cos θ6, −cos θ5 sin θ6,
   sα5 sin θ5), z4 = R·(sα5 sin θ6, sα5 cos θ6, 0), o4 = o5 − d5·z4. In frame 1,
   o4 is reached by the planar arm a2, a3 (law of cosines: θ3 elbow up and down,
   then θ2), and x4 lies in that plane at the angle θ2 + θ3 + θ4.

Up to 2 × 2 × 2 = 8 solutions per target, in the same layout as the spherical-wrist
closed form (addon.core.kinematics.ik_analytic.Branches). The caller wraps them into
the joint limits and verifies every one by forward kinematics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..tolerances import TOL
from .ik_analytic import COS_SLACK, Branches, shoulder_angles, wrist_and_shoulder_one

SINGULAR = TOL.singular


@dataclass(frozen=True)
class ParallelAxesArm:
    """The numbers the closed form needs, taken from a Robot's DH table (mm, ±1 signs)."""

    a1: float
    d1: float
    a2: float
    a3: float
    offset: float  # D = d2 + d3 + d4: the wrist's distance from the shoulder plane, along z1
    d5: float
    d6: float
    s1: float
    s4: float
    s5: float
    scale: float


def parallel_axes_arm(robot) -> tuple[ParallelAxesArm | None, str]:
    """The closed-form parameters of ``robot``, or (None, reason) when it does not qualify."""
    ca, sa = np.asarray(robot._ca), np.asarray(robot._sa)
    a, d = robot.a_mm, robot.d_mm
    scale = robot.length_scale_mm
    tol = 1e-12

    def right_angle(i):
        return abs(ca[i]) <= tol and abs(abs(sa[i]) - 1.0) <= tol

    def zero_angle(i):
        return abs(sa[i]) <= tol and ca[i] > 0

    checks = [
        (right_angle(0), "α1 must be ±90°"),
        (zero_angle(1) and zero_angle(2), "α2 and α3 must be 0 (joints 2, 3 and 4 parallel)"),
        (right_angle(3), "α4 must be ±90°"),
        (right_angle(4), "α5 must be ±90°"),
        (zero_angle(5), "α6 must be 0"),
        (max(abs(a[3]), abs(a[4]), abs(a[5])) <= tol * scale, "a4, a5 and a6 must be 0"),
        (abs(a[1]) > tol * scale and abs(a[2]) > tol * scale, "a2 and a3 must not be 0"),
    ]
    for ok, reason in checks:
        if not ok:
            return None, f"no parallel-axes closed form for {robot.name}: {reason}"
    return ParallelAxesArm(a1=float(a[0]), d1=float(d[0]), a2=float(a[1]), a3=float(a[2]),
                           offset=float(d[1] + d[2] + d[3]), d5=float(d[4]), d6=float(d[5]),
                           s1=float(np.sign(sa[0])), s4=float(np.sign(sa[3])), s5=float(np.sign(sa[4])),
                           scale=scale), ""


# Branch b = 4·shoulder + 2·elbow + wrist: the sign each choice puts on its half-angle.
_SHOULDER = np.repeat([1.0, -1.0], 4)
_ELBOW = np.tile(np.repeat([1.0, -1.0], 2), 2)
_WRIST = np.tile([1.0, -1.0], 4)


def parallel_branches(arm: ParallelAxesArm, F: np.ndarray, seed_theta: np.ndarray) -> Branches:
    """Closed-form DH angles (n, 8, 6) for flange poses F (n, 4, 4) in DH frame 0; branch =
    4·shoulder + 2·elbow + wrist as in ik_analytic. ``seed_theta`` (n, 6) fills the joints a
    singularity leaves undetermined (θ1 with the wrist on the base axis, θ6 with sin θ5 = 0).
    Every quantity is an (n, 8) array, one column per branch: few operations, so that one
    target costs little more than the numpy calls themselves."""
    n = F.shape[0]
    R = F[:, :3, :3]
    o5 = F[:, :3, 3] - arm.d6 * R[:, :, 2]

    # -- θ1: o5x sin θ1 − o5y cos θ1 = sα1·D ----------------------------------------
    phi, g, shoulder_ok = shoulder_angles(o5[:, 0], o5[:, 1], arm.offset * arm.s1, arm.scale, seed_theta[:, 0])
    th1 = phi[:, None] + np.where(_SHOULDER > 0, 0.0, np.pi) + _SHOULDER * g[:, None]  # (n, 8)
    c1, s1 = np.cos(th1), np.sin(th1)
    z1x, z1y = arm.s1 * s1, -arm.s1 * c1  # z1 = sα1 (sin θ1, −cos θ1, 0)

    def dot_z1(column: int) -> np.ndarray:
        return z1x * R[:, 0, column, None] + z1y * R[:, 1, column, None]

    # -- θ5: z1·z6 = −sα4 sα5 cos θ5 -----------------------------------------------------
    # From both its sine (|z1 × z6|, the in-plane part) and its cosine: arccos of a cosine that
    # rounds to 1 − 1 ulp gave 1.5e-8 rad, not singular, and θ6 then came from rounding noise
    # (a reachable target with the wrist straight was called out of reach).
    th5 = _WRIST * np.arctan2(np.hypot(dot_z1(0), dot_z1(1)), -arm.s4 * arm.s5 * dot_z1(2))
    s5, c5 = np.sin(th5), np.cos(th5)

    # -- θ6: in frame 6, z1 = (sα4 s5 c6, −sα4 s5 s6, ·) ----------------------------------
    singular = np.abs(s5) <= SINGULAR
    k = arm.s4 * np.where(singular, 1.0, s5)
    th6 = np.arctan2(-dot_z1(1) / k, dot_z1(0) / k)
    if singular.any():
        # Axis 6 lines up with axes 2-4: only θ2 + θ3 + θ4 + θ6 is fixed. Frame 4 is taken
        # from the seed's θ2 + θ3 + θ4 =: t (x4 = cos t·x1 + sin t·y1, z4 = sα4·x4 × z1), and
        # θ6 from the flange's x axis, which is then x6 = c5 c6·x4 + sα5 s6·z4.
        t = np.broadcast_to((seed_theta[:, 1] + seed_theta[:, 2] + seed_theta[:, 3])[:, None], c1.shape)
        # In frame 1's plane, o4 = P5 − d5·sα4·(sin t, −cos t) with P5 the wrist point there;
        # where the seed's t leaves o4 outside the elbow's reach, t is moved (the nearer of two
        # choices) to put |o4|² at a2² + a3², the middle of that reach.
        X5 = c1 * o5[:, 0, None] + s1 * o5[:, 1, None] - arm.a1
        Y5 = arm.s1 * (o5[:, 2, None] - arm.d1)
        P2 = X5 * X5 + Y5 * Y5
        ox, oy = X5 - arm.d5 * arm.s4 * np.sin(t), Y5 + arm.d5 * arm.s4 * np.cos(t)
        short = np.abs((ox * ox + oy * oy - arm.a2 ** 2 - arm.a3 ** 2) / (2.0 * arm.a2 * arm.a3)) > 1.0
        if arm.d5 != 0.0 and (short & singular).any():
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = (P2 + arm.d5 ** 2 - arm.a2 ** 2 - arm.a3 ** 2) / (2.0 * arm.d5 * arm.s4 * np.sqrt(P2))
            g = np.arcsin(np.clip(np.nan_to_num(ratio), -1.0, 1.0))
            psi = np.arctan2(Y5, X5)
            both = np.stack([psi + g, psi + np.pi - g])
            nearer = np.argmin(np.abs(np.angle(np.exp(1j * (both - t)))), axis=0)
            t = np.where(short, np.take_along_axis(both, nearer[None], 0)[0], t)
        x4s = [c1 * np.cos(t), s1 * np.cos(t), np.broadcast_to(arm.s1 * np.sin(t), c1.shape)]
        z4s = [-arm.s4 * x4s[2] * z1y, arm.s4 * x4s[2] * z1x, arm.s4 * (x4s[0] * z1y - x4s[1] * z1x)]
        along_x4 = sum(R[:, i, 0, None] * x4s[i] for i in range(3))
        along_z4 = sum(R[:, i, 0, None] * z4s[i] for i in range(3))
        th6 = np.where(singular, np.arctan2(arm.s5 * along_z4, c5 * along_x4), th6)
    c6, s6 = np.cos(th6), np.sin(th6)

    # -- frame 4: x4 = R (c5 c6, −c5 s6, sα5 s5), z4 = R (sα5 s6, sα5 c6, 0), o4 = o5 − d5 z4
    a, b, c = c5 * c6, -c5 * s6, arm.s5 * s5
    x4 = [R[:, i, 0, None] * a + R[:, i, 1, None] * b + R[:, i, 2, None] * c for i in range(3)]
    o4 = [o5[:, i, None] - arm.d5 * arm.s5 * (R[:, i, 0, None] * s6 + R[:, i, 1, None] * c6) for i in range(3)]

    # -- the planar arm a2, a3 in frame 1 (x1 = (c1, s1, 0), y1 = (0, 0, sα1)) ------------
    x = c1 * o4[0] + s1 * o4[1] - arm.a1
    y = arm.s1 * (o4[2] - arm.d1)
    K = (x * x + y * y - arm.a2 ** 2 - arm.a3 ** 2) / (2.0 * arm.a2 * arm.a3)
    # At a singular wrist the seed's frame 4 may leave the elbow short of its reach while
    # another would not: those branches go to the caller's polish, not to "out of reach".
    elbow_ok = (np.abs(K) <= COS_SLACK) | singular
    th3 = _ELBOW * np.arccos(np.clip(K, -1.0, 1.0))
    th2 = np.arctan2(y, x) - np.arctan2(arm.a3 * np.sin(th3), arm.a2 + arm.a3 * np.cos(th3))
    th4 = np.arctan2(arm.s1 * x4[2], c1 * x4[0] + s1 * x4[1]) - th2 - th3  # x4 at θ2 + θ3 + θ4 in frame 1

    theta = np.empty((n, 8, 6))
    for j, angle in enumerate((th1, th2, th3, th4, th5, th6)):
        theta[:, :, j] = angle
    return Branches(theta=theta, shoulder_ok=shoulder_ok, elbow_ok=elbow_ok)


def parallel_branches_one(arm: ParallelAxesArm, F: np.ndarray) -> list[tuple[float, ...] | None] | None:
    """The eight branches of :func:`parallel_branches` for one flange pose F (4, 4), in the
    same order, on Python floats (a single target's solve is otherwise mostly numpy's cost
    per call); a branch the geometry gives no real solution is None. None for the whole
    target where it is singular (the wrist on the base axis, sin θ5 = 0) or the shoulder
    cannot reach it: :func:`parallel_branches` handles those with the seed."""
    start = wrist_and_shoulder_one(F, arm.d6, arm.offset, arm.s1, arm.scale)
    if start is None:
        return None
    ((r00, r01, r02), (r10, r11, r12), (r20, r21, r22)), (ox, oy, oz), phi, g = start
    sa1, sa4, sa5 = arm.s1, arm.s4, arm.s5
    out = []
    for th1 in (phi + g, phi + math.pi - g):
        c1, s1 = math.cos(th1), math.sin(th1)
        z1x, z1y = sa1 * s1, -sa1 * c1
        d0, d1, d2 = (z1x * r00 + z1y * r10, z1x * r01 + z1y * r11, z1x * r02 + z1y * r12)
        acos5 = math.atan2(math.hypot(d0, d1), -sa4 * sa5 * d2)  # (as in the batched form)
        wrist = []
        for th5 in (acos5, -acos5):
            s5, c5 = math.sin(th5), math.cos(th5)
            if abs(s5) <= SINGULAR:
                return None
            th6 = math.atan2(-d1 / (sa4 * s5), d0 / (sa4 * s5))
            c6, s6 = math.cos(th6), math.sin(th6)
            a, b, c = c5 * c6, -c5 * s6, sa5 * s5
            x4 = (r00 * a + r01 * b + r02 * c, r10 * a + r11 * b + r12 * c, r20 * a + r21 * b + r22 * c)
            k = arm.d5 * sa5
            o4 = (ox - k * (r00 * s6 + r01 * c6), oy - k * (r10 * s6 + r11 * c6), oz - k * (r20 * s6 + r21 * c6))
            x = c1 * o4[0] + s1 * o4[1] - arm.a1
            y = sa1 * (o4[2] - arm.d1)
            K = (x * x + y * y - arm.a2 ** 2 - arm.a3 ** 2) / (2.0 * arm.a2 * arm.a3)
            wrist.append((th5, th6, x4, x, y, math.acos(max(-1.0, min(1.0, K))) if abs(K) <= COS_SLACK else None))
        for elbow in (1.0, -1.0):
            for th5, th6, x4, x, y, acos3 in wrist:
                if acos3 is None:  # the elbow cannot reach this branch's wrist
                    out.append(None)
                    continue
                th3 = elbow * acos3
                th2 = math.atan2(y, x) - math.atan2(arm.a3 * math.sin(th3), arm.a2 + arm.a3 * math.cos(th3))
                th4 = math.atan2(sa1 * x4[2], c1 * x4[0] + s1 * x4[1]) - th2 - th3
                out.append((th1, th2, th3, th4, th5, th6))
    return out
