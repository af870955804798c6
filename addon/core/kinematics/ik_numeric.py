"""Numeric inverse kinematics for any 6-joint DH arm (UR5 has no spherical wrist).

Damped least squares with adaptive damping (Levenberg–Marquardt):

    (JᵀJ + λ·tr(JᵀJ)/6·I) Δq = Jᵀe,     e = [(p* − p)/L ; ω(R* Rᵀ)]

L is the arm's length scale, so that position and orientation errors weigh alike
and λ is dimensionless; ω is the rotation vector of the remaining rotation. A step
that lowers |e| is taken and λ shrinks; one that does not is refused and λ grows,
so the solver moves between Gauss–Newton (quadratic near a solution) and gradient
descent (safe near singularities and for targets out of reach). Steps are
projected onto the joint limits.

Many problems run at once: every array carries a leading problem axis, so one
iteration costs a few dozen numpy calls whether it serves 1 target or 10 000, and
restarts from several random joint vectors run side by side. The seed is always
tried alone first, so a solution near the seed wins over a distant one; random
restarts (from a seeded generator, reproducible) only serve targets it missed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .transforms import rotation_vector

LAMBDA_START = 1e-3
LAMBDA_MIN = 1e-15
LAMBDA_MAX = 1e8
LAMBDA_DOWN = 10.0  # λ divisor after an accepted step
LAMBDA_UP = 4.0  # λ factor after a refused step
STALL_STEPS = 15  # steps without a real improvement before a start counts as stuck
STALL_GAIN = 1e-4  # relative cost decrease below which a step is "no real improvement"
MAX_STEP_RAD = 0.5  # largest change of any joint in one step (a sliding joint: this × the arm's length)


@dataclass
class NumericOutcome:
    """Per target: q (n, 6) best joint vector, pos_err_mm, rot_err_rad (n,),
    iterations (n,), starts (n,) tried, converged (n,) bool."""

    q: np.ndarray
    pos_err_mm: np.ndarray
    rot_err_rad: np.ndarray
    iterations: np.ndarray
    starts: np.ndarray
    converged: np.ndarray


def _evaluate(robot, T: np.ndarray, q: np.ndarray, L: float):
    """Error e (N, 6), scaled Jacobian J (N, 6, 6), |Δp| (N,) mm and |ω| (N,) rad for q (N, 6)."""
    X, Y, Z, P, zs, os_ = robot._fk_columns(q, with_tool=True, record_axes=True)
    dp = T[:, :3, 3] - P.T
    R = np.stack([X.T, Y.T, Z.T], axis=-1)
    w = rotation_vector(T[:, :3, :3] @ np.swapaxes(R, 1, 2))
    e = np.concatenate([dp / L, w], axis=1)
    # Column i: [z_{i-1} × (p − o_{i-1}) / L ; z_{i-1}].
    r = P[None] - os_
    J = np.empty((q.shape[0], 6, 6))
    J[:, 0, :] = (zs[:, 1] * r[:, 2] - zs[:, 2] * r[:, 1]).T / L
    J[:, 1, :] = (zs[:, 2] * r[:, 0] - zs[:, 0] * r[:, 2]).T / L
    J[:, 2, :] = (zs[:, 0] * r[:, 1] - zs[:, 1] * r[:, 0]).T / L
    J[:, 3:, :] = np.transpose(zs, (2, 1, 0))
    if robot.has_prismatic:  # a sliding joint moves the tool along z_{i-1} and turns nothing
        slides = robot._slides
        J[:, :3, slides] = np.transpose(zs[slides], (2, 1, 0)) / L
        J[:, 3:, slides] = 0.0
    return e, J, np.linalg.norm(dp, axis=1), np.linalg.norm(w, axis=1)


class _Problems:
    """Current joint vectors, errors and Jacobians of N problems; keeps only improving steps."""

    def __init__(self, robot, T: np.ndarray, q: np.ndarray):
        self.robot, self.T, self.L = robot, T, robot.length_scale_mm
        lo, hi = robot.q_min_rad, robot.q_max_rad
        self.lo, self.hi, self.full_turn = lo, hi, ((hi - lo) >= 2.0 * np.pi) & ~robot._slides
        self.q = _into_limits(np.array(q, dtype=np.float64), lo, hi, self.full_turn)
        self.e, self.J, self.pe, self.re = _evaluate(robot, T, self.q, self.L)
        self.cost = np.einsum("ij,ij->i", self.e, self.e)

    def converged(self, pos_tol: float, rot_tol: float, idx=slice(None)) -> np.ndarray:
        return (self.pe[idx] <= pos_tol) & (self.re[idx] <= rot_tol)

    def try_step(self, idx: np.ndarray, dq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Take q[idx] + dq (projected onto the limits) where it lowers the error.

        Returns (better (len(idx),) bool, relative cost decrease of the accepted steps).
        """
        qn = _into_limits(self.q[idx] + dq, self.lo, self.hi, self.full_turn)
        en, Jn, pen, ren = _evaluate(self.robot, self.T[idx], qn, self.L)
        costn = np.einsum("ij,ij->i", en, en)
        better = costn < self.cost[idx]
        acc = idx[better]
        gain = (self.cost[acc] - costn[better]) / np.maximum(self.cost[acc], 1e-300)
        self.q[acc], self.e[acc], self.J[acc] = qn[better], en[better], Jn[better]
        self.pe[acc], self.re[acc], self.cost[acc] = pen[better], ren[better], costn[better]
        return better, gain


def _into_limits(q: np.ndarray, lo: np.ndarray, hi: np.ndarray, full_turn: np.ndarray) -> np.ndarray:
    """Project q (N, 6) onto the limits; joints spanning a full turn wrap by 2π instead of sticking."""
    two_pi = 2.0 * np.pi
    wrapped = np.where(q > hi, q - two_pi * np.ceil((q - hi) / two_pi), q)
    wrapped = np.where(wrapped < lo, wrapped + two_pi * np.ceil((lo - wrapped) / two_pi), wrapped)
    return np.clip(np.where(full_turn, wrapped, q), lo, hi)


def levenberg_marquardt(robot, T: np.ndarray, q: np.ndarray, pos_tol: float, rot_tol: float,
                        max_iter: int = 100):
    """Run LM on N independent problems: targets T (N, 4, 4), starts q (N, 6).

    Returns q (N, 6), pos_err (N,), rot_err (N,), converged (N,), iterations (N,).
    A problem stops when it converges, when λ exceeds LAMBDA_MAX, or after
    STALL_STEPS steps without real progress.
    """
    P = _Problems(robot, T, q)
    N = P.q.shape[0]
    step_unit = np.where(robot._slides, P.L, 1.0)
    lam = np.full(N, LAMBDA_START)
    stall = np.zeros(N, dtype=int)
    iters = np.zeros(N, dtype=int)
    converged = P.converged(pos_tol, rot_tol)
    active = ~converged
    eye = np.eye(6)
    for _ in range(max_iter):
        idx = np.nonzero(active)[0]
        if idx.size == 0:
            break
        Ja, ea = P.J[idx], P.e[idx]
        JT = np.swapaxes(Ja, 1, 2)
        H = JT @ Ja
        g = np.einsum("nij,nj->ni", JT, ea)
        scale = lam[idx] * (np.trace(H, axis1=1, axis2=2) / 6.0 + 1e-300)
        dq = np.linalg.solve(H + scale[:, None, None] * eye, g[..., None])[..., 0]
        # Trust region: far from the solution a full Gauss-Newton step overshoots.
        big = np.max(np.abs(dq) / step_unit, axis=1)
        dq *= np.minimum(1.0, MAX_STEP_RAD / np.maximum(big, 1e-300))[:, None]
        better, gain = P.try_step(idx, dq)
        iters[idx] += 1
        acc, rej = idx[better], idx[~better]
        # Shrink λ fast after a good step: near a nearly-singular solution only an
        # almost undamped (Gauss-Newton) step converges quickly.
        lam[acc] = np.maximum(lam[acc] / LAMBDA_DOWN, LAMBDA_MIN)
        stall[acc] = np.where(gain < STALL_GAIN, stall[acc] + 1, 0)
        lam[rej] *= LAMBDA_UP
        stall[rej] += 1
        converged[idx] = P.converged(pos_tol, rot_tol, idx)
        active[idx] = ~converged[idx] & (lam[idx] <= LAMBDA_MAX) & (stall[idx] < STALL_STEPS)
    return P.q, P.pe, P.re, converged, iters


def gauss_newton_polish(robot, T: np.ndarray, q: np.ndarray, pos_tol: float, rot_tol: float,
                        steps: int = 8):
    """Undamped Gauss-Newton steps (SVD pseudo-inverse) on N problems, each kept only if it helps.

    Near a nearly singular solution damped steps crawl while undamped ones converge
    in a few steps; this finishes targets that LM left close to, but not within,
    tolerance. Returns q, pos_err, rot_err, converged, iterations like LM.
    """
    P = _Problems(robot, T, q)
    iters = np.zeros(P.q.shape[0], dtype=int)
    active = ~P.converged(pos_tol, rot_tol)
    for _ in range(steps):
        idx = np.nonzero(active)[0]
        if idx.size == 0:
            break
        dq = np.einsum("nij,nj->ni", np.linalg.pinv(P.J[idx], rcond=1e-12), P.e[idx])
        better, _ = P.try_step(idx, dq)
        iters[idx] += 1
        active[idx] = better & ~P.converged(pos_tol, rot_tol, idx)
    return P.q, P.pe, P.re, P.converged(pos_tol, rot_tol), iters


def solve_numeric(robot, T: np.ndarray, seeds: np.ndarray, pos_tol: float, rot_tol: float,
                  rng: np.random.Generator, max_starts: int = 121, starts_per_round: int = 8,
                  max_iter: int = 150) -> NumericOutcome:
    """Best joint vectors within limits for targets T (n, 4, 4), seeds (n, 6).

    Round 0 runs LM from each seed. Targets it misses get rounds of
    ``starts_per_round`` random starts side by side, up to ``max_starts`` starts in
    all; among converged starts the one nearest the seed wins, otherwise the one
    with the smallest error. Never raises for an unreachable target.
    """
    n = T.shape[0]
    lo, hi = robot.q_min_rad, robot.q_max_rad
    q, pe, re, conv, iters = levenberg_marquardt(robot, T, seeds.copy(), pos_tol, rot_tol, max_iter)
    L = robot.length_scale_mm
    best_cost = (pe / L) ** 2 + re ** 2
    starts = np.ones(n, dtype=int)
    while True:
        todo = np.nonzero(~conv & (starts + starts_per_round <= max_starts))[0]
        if todo.size == 0:
            break
        k = starts_per_round
        Tk = np.repeat(T[todo], k, axis=0)
        qk = rng.uniform(lo, hi, size=(todo.size * k, 6))
        qk, pek, rek, convk, itk = levenberg_marquardt(robot, Tk, qk, pos_tol, rot_tol, max_iter)
        qk, pek, rek, convk = (a.reshape((todo.size, k) + a.shape[1:]) for a in (qk, pek, rek, convk))
        iters[todo] += itk.reshape(todo.size, k).sum(axis=1)
        starts[todo] += k
        dist = np.linalg.norm((qk - seeds[todo, None, :]) / np.where(robot._slides, L, 1.0), axis=-1)
        costk = (pek / L) ** 2 + rek ** 2
        # Converged starts compete on distance to the seed, the rest on error.
        pick = np.where(convk.any(axis=1), np.argmin(np.where(convk, dist, np.inf), axis=1),
                        np.argmin(costk, axis=1))
        rows = np.arange(todo.size)
        got = convk[rows, pick]
        improve = got | (costk[rows, pick] < best_cost[todo])
        sel = todo[improve]
        r = rows[improve]
        q[sel] = qk[r, pick[improve]]
        pe[sel] = pek[r, pick[improve]]
        re[sel] = rek[r, pick[improve]]
        best_cost[sel] = costk[r, pick[improve]]
        conv[sel] = got[improve]
    left = np.nonzero(~conv)[0]
    if left.size:
        qp, pep, rep, convp, itp = gauss_newton_polish(robot, T[left], q[left], pos_tol, rot_tol)
        q[left], pe[left], re[left], conv[left] = qp, pep, rep, convp
        iters[left] += itp
    return NumericOutcome(q, pe, re, iters, starts, conv)
