"""Inverse kinematics: one entry point, one result type, success only when verified.

``solve(robot, T_target, q0)`` uses the closed form for spherical-wrist arms
(:mod:`addon.core.kinematics.ik_analytic`) and for UR-type arms with three parallel
axes (:mod:`addon.core.kinematics.ik_parallel`), and damped least squares otherwise
(:mod:`addon.core.kinematics.ik_numeric`). Whatever the method, a result claims success only
after forward kinematics of the returned joint vector lands on the target within
the tolerances *and* every joint is inside its limits. An unreachable target can
therefore never come back as a success; the result then carries the best attempt,
how far it is from the target, and the reason in words and as a code.

Default tolerances: position min(1e-6 mm, 1e-9 × the arm's length scale), so that
a millimetre-sized arm gets a proportionally tight bound; orientation 1e-9 rad.

Everything runs vectorised over targets (``solve_batch``); ``solve`` is a batch
of one.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError, UnreachablePose
from ..tolerances import TOL
from .ik_analytic import branches, branches_one, flange_targets, spherical_wrist_arm
from .ik_parallel import ParallelAxesArm, parallel_axes_arm, parallel_branches, parallel_branches_one
from .ik_numeric import levenberg_marquardt, solve_numeric
from .robot import FEW_POSES
from .transforms import check_transform, rotation_angle

ROT_TOL_RAD = TOL.ik_rotation_rad
LIMIT_TOL_RAD = TOL.joint_limit_rad
_TURNS = np.array([0.0, -2.0 * np.pi, 2.0 * np.pi])
METHODS = ("auto", "analytic", "numeric")
# IKResult.reason values: success; farther than any joint vector reaches; reachable
# only with joints outside their limits; closed form off by rounding at a singularity
# even after polishing; numeric solver found nothing within tolerance.
REASONS = ("ok", "out_of_reach", "joint_limits", "numerical", "not_converged")


@dataclass(frozen=True)
class IKResult:
    """Outcome of one IK solve.

    q : (6,) rad. On success, a joint vector inside the limits that reaches the
        target; on failure, the best attempt (for diagnosis, not for motion).
    success : FK(q) is within the tolerances of the target and q is within limits.
    pos_err_mm, rot_err_rad : measured distance of FK(q) from the target.
    iterations : solver iterations (0 for the closed form).
    message : "ok" or why it failed, in words.
    method : "analytic" or "numeric".
    reason : machine-readable outcome, one of REASONS.
    """

    q: np.ndarray
    success: bool
    pos_err_mm: float
    rot_err_rad: float
    iterations: int
    message: str
    method: str
    reason: str = "ok"


@dataclass(frozen=True)
class IKBatch:
    """Outcome of n solves: q (n, 6), success, pos_err_mm, rot_err_rad, iterations (n,),
    messages and reasons (lists of n str), and the method. ``batch[i]`` is an IKResult."""

    q: np.ndarray
    success: np.ndarray
    pos_err_mm: np.ndarray
    rot_err_rad: np.ndarray
    iterations: np.ndarray
    messages: list
    reasons: list
    method: str

    def __len__(self) -> int:
        return len(self.q)

    def __getitem__(self, i: int) -> IKResult:
        return IKResult(self.q[i].copy(), bool(self.success[i]), float(self.pos_err_mm[i]),
                        float(self.rot_err_rad[i]), int(self.iterations[i]), self.messages[i],
                        self.method, self.reasons[i])


# -- helpers ----------------------------------------------------------------------

def default_pos_tol(robot) -> float:
    return min(TOL.ik_position_mm, TOL.ik_position_rel * robot.length_scale_mm)


def default_seed(robot) -> np.ndarray:
    """q = 0 moved inside the limits: the seed used when the caller gives none."""
    return np.minimum(np.maximum(0.0, robot.q_min_rad), robot.q_max_rad)


def wrap_to_limits(robot, q: np.ndarray, seed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shift each joint of q (..., 6) by whole turns into its limits, nearest to ``seed``.

    Returns (q_wrapped, inside) with inside (...,) True where every joint fits.
    A joint that fits in no turn keeps the turn nearest to its limits.
    """
    lo, hi = robot.q_min_rad, robot.q_max_rad
    two_pi = 2.0 * np.pi
    seed = np.broadcast_to(seed, q.shape)
    # The turn nearest the seed is the answer whenever it fits; otherwise one of its
    # neighbours does if any turn does (with the seed inside the limits, the nearest turn
    # lies within π of them), and where none fits the neighbour nearest the limits is kept.
    # Seeds outside the limits get the exhaustive search.
    c0 = q + two_pi * np.round((seed - q) / two_pi)
    fits = (c0 >= lo - LIMIT_TOL_RAD) & (c0 <= hi + LIMIT_TOL_RAD)
    if fits.all():  # the usual case, kept short: a single solve is mostly numpy call overhead
        return np.minimum(np.maximum(c0, lo), hi), np.ones(q.shape[:-1], dtype=bool)
    cands = c0[..., None] + _TURNS  # (..., 6, 3): this turn, one less, one more
    lo3, hi3 = lo[:, None], hi[:, None]
    inside = (cands >= lo3 - LIMIT_TOL_RAD) & (cands <= hi3 + LIMIT_TOL_RAD)
    violation = np.maximum(lo3 - cands, 0.0) + np.maximum(cands - hi3, 0.0)
    score = np.where(inside, np.abs(cands - seed[..., None]), 1e9 + violation)
    out = c0 + _TURNS[score.argmin(axis=-1)]
    fits = inside.any(axis=-1)
    if not fits.all() and not ((seed >= lo - LIMIT_TOL_RAD) & (seed <= hi + LIMIT_TOL_RAD))[~fits].all():
        bad = ~fits
        joint = np.broadcast_to(np.arange(6), q.shape)[bad]
        l, h = lo[joint], hi[joint]
        turns = np.arange(-4, 5, dtype=np.float64)
        k0 = np.round((0.5 * (l + h) - q[bad]) / two_pi)
        cands = q[bad][:, None] + (k0[:, None] + turns) * two_pi
        inside = (cands >= l[:, None] - LIMIT_TOL_RAD) & (cands <= h[:, None] + LIMIT_TOL_RAD)
        dist = np.where(inside, np.abs(cands - seed[bad][:, None]), np.inf)
        violation = np.maximum(l[:, None] - cands, 0.0) + np.maximum(cands - h[:, None], 0.0)
        pick = np.where(inside.any(1), np.argmin(dist, 1), np.argmin(violation, 1))
        out[bad] = cands[np.arange(len(pick)), pick]
        fits[bad] = inside.any(1)
    out = np.where(fits, np.minimum(np.maximum(out, lo), hi), out)
    return out, fits.all(axis=-1)


def pose_errors(robot, q: np.ndarray, T_targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position (mm) and orientation (rad) distance of FK(q) from targets; q (..., 6)."""
    shape = q.shape[:-1]
    flat = q.reshape(-1, 6)
    Tq = (robot._fk_chain(flat, True) if len(flat) <= FEW_POSES else robot.fk(flat)).reshape(shape + (4, 4))
    d = Tq[..., :3, 3] - T_targets[..., :3, 3]
    pos = np.sqrt((d * d).sum(axis=-1))
    rel = np.swapaxes(T_targets[..., :3, :3], -1, -2) @ Tq[..., :3, :3]
    return pos, rotation_angle(rel)


@functools.lru_cache(maxsize=64)
def closed_form_arm(robot):
    """(the closed form's parameters, "") for an arm with one (a spherical wrist:
    ik_analytic; three parallel middle axes and an offset wrist, UR-type: ik_parallel),
    else (None, why not)."""
    if robot.has_prismatic:
        return None, f"no closed form for {robot.name}: it has a prismatic joint"
    arm, spherical = spherical_wrist_arm(robot)
    if arm is not None:
        return arm, ""
    arm, parallel = parallel_axes_arm(robot)
    if arm is not None:
        return arm, ""
    return None, f"{spherical}; {parallel.split(': ', 1)[-1]} for the parallel-axes (UR-type) form"


def _check_method(robot, method: str):
    if method not in METHODS:
        raise InputError(f"IK method {method!r} is not one of: {', '.join(METHODS)}")
    arm, reason = closed_form_arm(robot)
    if method == "analytic" and arm is None:
        raise InputError(reason + "; use method='numeric' or 'auto'")
    return arm if method in ("auto", "analytic") else None


def _check_tols(robot, pos_tol_mm, rot_tol_rad) -> tuple[float, float]:
    pos_tol = default_pos_tol(robot) if pos_tol_mm is None else float(pos_tol_mm)
    rot_tol = ROT_TOL_RAD if rot_tol_rad is None else float(rot_tol_rad)
    for name, v in (("pos_tol_mm", pos_tol), ("rot_tol_rad", rot_tol)):
        if not math.isfinite(v) or v <= 0:
            raise InputError(f"{name} must be a positive finite number, got {v}")
    return pos_tol, rot_tol


def _check_seeds(robot, q0, n: int) -> np.ndarray:
    if q0 is None:
        return np.tile(default_seed(robot), (n, 1))
    q0 = robot.check_q(q0, "q0")
    q0 = np.broadcast_to(q0, (n, 6)) if q0.ndim == 1 else q0
    if q0.shape != (n, 6):
        raise InputError(f"q0 must have shape (6,) or ({n}, 6), got {q0.shape}")
    return np.array(q0)


# -- solving ----------------------------------------------------------------------

def solve(robot, T_target, q0=None, *, method: str = "auto", pos_tol_mm: float | None = None,
          rot_tol_rad: float | None = None, raise_on_failure: bool = False, seed: int = 0,
          max_starts: int = 121, explain_limits: bool = True) -> IKResult:
    """Joint vector (6,) rad that puts the tool at ``T_target`` (4, 4, mm, world frame).

    q0 : (6,) seed; among several solutions the one nearest q0 wins (default: q = 0
        clipped into the limits). Angles beyond ±2π are fine.
    method : "auto" (closed form when the arm has one, else numeric),
        "analytic" or "numeric".
    raise_on_failure : raise UnreachablePose (carrying the result) instead of
        returning success=False.
    seed, max_starts : random restarts of the numeric solver (reproducible).
    explain_limits : where the numeric solver misses, solve again without the turning joints'
        limits and name the limits in the way in the message (a second, smaller solve).
    """
    T = check_transform(T_target, "IK target pose")
    if T.shape != (4, 4):
        raise InputError(f"IK target pose must have shape (4, 4), got {T.shape}; use ik_batch for many")
    if q0 is not None and np.shape(q0) != (6,):
        raise InputError(f"q0 must have shape (6,), got {np.shape(q0)}")
    result = None
    if method != "numeric":
        arm = _check_method(robot, method)
        if arm is not None:
            pos_tol, rot_tol = _check_tols(robot, pos_tol_mm, rot_tol_rad)
            result = _solve_one(robot, arm, T, default_seed(robot) if q0 is None else robot.check_q(q0, "q0"),
                                pos_tol, rot_tol)
    if result is None:
        result = _solve_checked(robot, T[None], None if q0 is None else np.asarray(q0)[None], method, pos_tol_mm,
                                rot_tol_rad, seed, max_starts, explain_limits)[0]
    if raise_on_failure and not result.success:
        raise UnreachablePose(f"{robot.name}: {result.message}", result)
    return result


def solve_batch(robot, T_targets, q0=None, *, method: str = "auto", pos_tol_mm: float | None = None,
                rot_tol_rad: float | None = None, seed: int = 0, max_starts: int = 121,
                explain_limits: bool = True) -> IKBatch:
    """IK for targets (n, 4, 4). q0: (6,) for all or (n, 6) per target. See :func:`solve`."""
    T = check_transform(T_targets, "IK target poses")
    if T.ndim != 3:
        raise InputError(f"IK target poses must have shape (n, 4, 4), got {T.shape}")
    return _solve_checked(robot, T, q0, method, pos_tol_mm, rot_tol_rad, seed, max_starts, explain_limits)


def _solve_checked(robot, T, q0, method, pos_tol_mm, rot_tol_rad, seed, max_starts,
                   explain_limits: bool = True) -> IKBatch:
    """solve_batch for targets T (n, 4, 4) already checked to be rigid transforms."""
    n = T.shape[0]
    q0 = _check_seeds(robot, q0, n)
    pos_tol, rot_tol = _check_tols(robot, pos_tol_mm, rot_tol_rad)
    arm = _check_method(robot, method)
    name = "analytic" if arm is not None else "numeric"

    q = q0.copy()
    success = np.zeros(n, dtype=bool)
    iterations = np.zeros(n, dtype=int)
    reasons = ["ok"] * n
    messages = ["ok"] * n

    # Farther from the shoulder than the sum of the link lengths: no solver needed.
    d = T[:, :3, 3] - robot.shoulder_world
    dist = np.sqrt((d * d).sum(axis=1))
    bound = robot.reach_bound_mm
    far = dist > bound * (1.0 + 1e-12)
    if far.any():
        for i in np.nonzero(far)[0]:
            reasons[i] = "out_of_reach"
            messages[i] = (f"target is out of reach: {dist[i]:.6g} mm from the shoulder, and no joint vector "
                           f"places the tool farther than {bound:.6g} mm")
        todo = np.nonzero(~far)[0]
    else:
        todo = slice(None)  # every target: plain slicing, no copies

    pos = np.full(n, np.inf)
    rot = np.full(n, np.inf)
    checked = np.zeros(n, dtype=bool)  # pos and rot are already FK of the returned q
    rows = np.arange(n)[todo]
    if rows.size and arm is not None:
        qa, ok, why, text, pa, ra = _solve_analytic(robot, arm, T[todo], q0[todo], pos_tol, rot_tol)
        q[todo], success[todo], pos[todo], rot[todo], checked[todo] = qa, ok, pa, ra, True
        for j, i in enumerate(rows):
            reasons[i], messages[i] = why[j], text[j]
        # Rounding at a singularity can leave every branch a hair outside tolerance:
        # polish the best branch with a few damped least-squares steps.
        polish = np.array([i for i in rows if reasons[i] == "numerical"], dtype=int)
        if polish.size:
            qp, _, _, conv, its = levenberg_marquardt(robot, T[polish], q[polish], pos_tol, rot_tol, 50)
            iterations[polish] += its
            for j, i in enumerate(polish):
                if conv[j]:
                    q[i], success[i], reasons[i], messages[i], checked[i] = qp[j], True, "ok", "ok", False
    elif rows.size:
        out = solve_numeric(robot, T[todo], q0[todo], pos_tol, rot_tol, np.random.default_rng(seed),
                            max_starts=max_starts)
        q[todo], success[todo], iterations[todo] = out.q, out.converged, out.iterations
        hinted = False
        for j, i in enumerate(rows):
            if not out.converged[j]:
                reasons[i] = "not_converged"
                messages[i] = (f"no joint vector within limits reaches the target: the best of "
                               f"{out.starts[j]} starts stays {out.pos_err_mm[j]:.3g} mm and "
                               f"{out.rot_err_rad[j]:.3g} rad away; the pose is outside the workspace "
                               "or needs joints beyond their limits")
                if explain_limits and not hinted:  # the first miss (a refusal quotes it) says which limit
                    hinted = True
                    blocked = _limits_in_the_way(robot, T[i], q0[i], pos_tol, rot_tol, seed)
                    if blocked:
                        messages[i] = (f"no joint vector within limits reaches the target (the best of "
                                       f"{out.starts[j]} starts stays {out.pos_err_mm[j]:.3g} mm away); without "
                                       f"the limits it is reached with {blocked}")

    again = ~checked
    if again.any():
        pos[again], rot[again] = pose_errors(robot, q[again], T[again])
    # Success is re-checked here, from FK of the returned q, for every method (the closed
    # form's errors above are FK of the very joint vectors it returns).
    verified = success & (pos <= pos_tol) & (rot <= rot_tol) & robot.within_limits(q, LIMIT_TOL_RAD)
    for i in np.nonzero(success & ~verified)[0]:
        reasons[i], messages[i] = "numerical", f"solution failed verification ({pos[i]:.3g} mm, {rot[i]:.3g} rad)"
    return IKBatch(q, verified, pos, rot, iterations, messages, reasons, name)


def _solve_analytic(robot, arm, T, q0, pos_tol, rot_tol):
    """Closed form for T (m, 4, 4), seeds q0 (m, 6): (q, success, reasons, messages, and the
    position and rotation errors of q by FK)."""
    m = T.shape[0]
    q, inside, pos, rot, geom_ok = all_branches(robot, arm, T, q0)
    ok = inside & (pos <= pos_tol) & (rot <= rot_tol)
    d = q - q0[:, None, :]
    dist2 = (d * d).sum(axis=-1)
    success = ok.any(axis=1)
    pick = np.where(ok, dist2, np.inf).argmin(axis=1)
    reasons, messages = ["ok"] * m, ["ok"] * m
    if not success.all():
        # For failures return the branch nearest to success: inside the limits first, then smallest error.
        err = pos + rot * robot.length_scale_mm
        pick = np.where(success, pick, np.where(inside, err, err + 1e300).argmin(axis=1))
        geom = geom_ok()
        for i in np.nonzero(~success)[0]:
            reasons[i], messages[i] = _analytic_failure(robot, q[i], geom[i], pos[i], rot[i], pos_tol, rot_tol)
    rows = np.arange(m)
    return q[rows, pick], success, reasons, messages, pos[rows, pick], rot[rows, pick]


def _solve_one(robot, arm, T: np.ndarray, q0: np.ndarray, pos_tol: float, rot_tol: float) -> IKResult | None:
    """One target's closed form on Python floats, for ``solve``: the eight branches
    (``branches_one``, ``parallel_branches_one``), each joint shifted by whole turns into its
    limits nearest the seed as ``wrap_to_limits`` does, tried nearest to the seed first, and
    the first that forward kinematics confirms returned. That is the batch path's answer
    (the nearest confirmed branch) at a third of its cost. None, for the batch path to
    answer and explain, where the target is singular, the seed lies outside the limits, or
    no branch is confirmed."""
    thetas = (parallel_branches_one if isinstance(arm, ParallelAxesArm) else branches_one)(
        arm, flange_targets(robot, T[None])[0])
    if thetas is None:
        return None
    lo, hi = robot.q_min_rad.tolist(), robot.q_max_rad.tolist()
    seed, offset = q0.tolist(), robot.theta_offset_rad.tolist()
    tol, two_pi = LIMIT_TOL_RAD, 2.0 * math.pi
    if any(not (l - tol <= s <= h + tol) for s, l, h in zip(seed, lo, hi)):
        return None
    candidates = []
    for theta in thetas:
        if theta is None:
            continue
        q, dist2 = [], 0.0
        for t, o, s, l, h in zip(theta, offset, seed, lo, hi):
            c = t - o
            c += two_pi * round((s - c) / two_pi)
            if not l - tol <= c <= h + tol:  # the turn nearest the seed does not fit: one either side may
                below, above = c - two_pi, c + two_pi
                fit_below, fit_above = l - tol <= below <= h + tol, l - tol <= above <= h + tol
                if fit_below and not (fit_above and abs(above - s) < abs(below - s)):
                    c = below
                elif fit_above:
                    c = above
                else:
                    break
            c = l if c < l else (h if c > h else c)
            q.append(c)
            dist2 += (c - s) * (c - s)
        else:
            candidates.append((dist2, q))
    candidates.sort(key=lambda item: item[0])
    for _, q in candidates:
        pos, rot = (float(e[0]) for e in pose_errors(robot, np.array([q]), T[None]))
        if pos <= pos_tol and rot <= rot_tol:
            return IKResult(np.array(q), True, pos, rot, 0, "ok", "analytic", "ok")
    return None


def all_branches(robot, arm, T: np.ndarray, q0: np.ndarray):
    """Every closed-form branch for targets T (n, 4, 4), wrapped into limits near q0 (n, 6).

    Returns q (n, 8, 6), inside (n, 8), pos_err (n, 8) mm, rot_err (n, 8) rad, and
    geometry_ok, a function giving (n, 8) bool (False where the link lengths could not reach
    and values were clamped), called only where a failure needs explaining.
    """
    F = flange_targets(robot, T)
    br = (parallel_branches if isinstance(arm, ParallelAxesArm) else branches)(arm, F, q0 + robot.theta_offset_rad)
    q_raw = br.theta - robot.theta_offset_rad
    q, inside = wrap_to_limits(robot, q_raw, q0[:, None, :])
    pos, rot = pose_errors(robot, q, T[:, None])
    return q, inside, pos, rot, br.geometry_ok


def _analytic_failure(robot, q, geom_ok, pos, rot, pos_tol, rot_tol) -> tuple[str, str]:
    """(reason, message) for a target none of whose 8 branches succeeded."""
    reach = (pos <= pos_tol) & (rot <= rot_tol)
    if reach.any():
        cands = np.nonzero(reach)[0]
        fewest = min((robot.limit_violations(q[k]) for k in cands), key=len)
        return "joint_limits", (f"reachable only outside the joint limits ({len(cands)} of 8 solutions reach "
                                f"it): the nearest has {'; '.join(fewest)}")
    if not geom_ok.any():
        return "out_of_reach", ("target is out of reach: links 2–3 cannot place the wrist centre where "
                                f"the pose needs it (best attempt {pos.min():.6g} mm away)")
    k = int(np.argmin(pos + rot * robot.length_scale_mm))
    return "numerical", (f"no closed-form solution within tolerance: best is {pos[k]:.3g} mm and "
                         f"{rot[k]:.3g} rad away (rounding at a singularity)")


def solve_all(robot, T_target, *, pos_tol_mm: float | None = None, rot_tol_rad: float | None = None) -> np.ndarray:
    """Every distinct closed-form solution (k, 6), k ≤ 8, inside the limits and verified by FK.

    Raises InputError for arms without a closed form.
    """
    T = check_transform(T_target, "IK target pose")
    if T.shape != (4, 4):
        raise InputError(f"IK target pose must have shape (4, 4), got {T.shape}")
    arm = _check_method(robot, "analytic")
    pos_tol, rot_tol = _check_tols(robot, pos_tol_mm, rot_tol_rad)
    q, inside, pos, rot, _ = all_branches(robot, arm, T[None], default_seed(robot)[None])
    ok = inside[0] & (pos[0] <= pos_tol) & (rot[0] <= rot_tol)
    sols: list[np.ndarray] = []
    for k in np.nonzero(ok)[0]:
        if all(np.max(np.abs(q[0, k] - s)) > 1e-6 for s in sols):
            sols.append(q[0, k])
    return np.array(sols).reshape(-1, 6)


LIMIT_HINT_STARTS = 41  # starts for the solve without limits that names the limit in the way


def _limits_in_the_way(robot, T: np.ndarray, q0: np.ndarray, pos_tol: float, rot_tol: float, seed) -> str:
    """Which joint limits keep target T (4, 4) out of reach: solved again with every turning
    joint free over a full turn either way (sliding joints keep theirs), the joints of the
    solution found that lie beyond the robot's limits ("J3 = -28.6° outside [-17.2°, 11.5°]");
    "" where even that finds none (the pose is outside the workspace)."""
    from dataclasses import replace

    slides = robot._slides
    free = replace(robot, q_min_rad=np.where(slides, robot.q_min_rad, np.minimum(robot.q_min_rad, -2 * np.pi)),
                   q_max_rad=np.where(slides, robot.q_max_rad, np.maximum(robot.q_max_rad, 2 * np.pi)), ik_via=None)
    out = solve_numeric(free, T[None], np.clip(q0, free.q_min_rad, free.q_max_rad)[None], pos_tol, rot_tol,
                        np.random.default_rng(seed), max_starts=LIMIT_HINT_STARTS)
    if not out.converged[0]:
        return ""
    # Each turning joint by whole turns into its limits where a turn fits: only what no turn
    # mends is blamed (a wrist at 183° is fine as −177°).
    wrapped, _ = wrap_to_limits(robot, out.q, np.asarray(q0, dtype=np.float64)[None])
    return "; ".join(robot.limit_violations(np.where(slides, out.q[0], wrapped[0])))
