"""FK and IK speed, IK success and accuracy, and false successes, for each robot.

Targets come from random joint vectors within the limits (reachable by
construction), from joint vectors next to the wrist and elbow singularities, and
from places no joint vector reaches (beyond the arm's total length, or for
spherical-wrist arms just beyond the stretched elbow, which the geometry decides).
A false success is a claimed success on an unreachable target, or a success
whose joint vector an independent forward-kinematics check does not confirm.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from addon.core.config.toml import RIGS_DIR
from addon.core.kinematics.ik import closed_form_arm, default_pos_tol
from addon.core.kinematics.ik_parallel import ParallelAxesArm
from addon.core.kinematics.robot import Robot
from addon.core.config.rigs import load_robot
from addon.core.kinematics.transforms import rot_x, rot_z, trans
from headless.bench.timing import fmt_time, median_seconds, median_single_call, per_call_seconds
from headless.bench import MAX_SEED, whole

# The three bundled DH tables, and the UR5 again from its URDF file (the same arm through
# the URDF loader: its DH form, base and tool, and the UR closed form).
DEFAULT_ROBOTS = ["adept_viper_s650", "puma560", "ur5", str(RIGS_DIR / "robots" / "urdf" / "ur5.urdf"),
                  str(RIGS_DIR / "robots" / "urdf" / "gantry.urdf")]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robots", nargs="+", default=DEFAULT_ROBOTS, metavar="ROBOT",
                        help="bundled robot names, rig file paths or URDF files (default: the three bundled robots, "
                             "the UR5's URDF and the gantry's)")
    parser.add_argument("--n", type=whole(), default=10_000, help="random reachable targets per robot (default 10000)")
    parser.add_argument("--near", type=whole(), default=1_000, help="near-singular targets per robot (default 1000)")
    parser.add_argument("--unreachable", type=whole(), default=1_000, help="unreachable targets per robot (default 1000)")
    parser.add_argument("--fk-batch", type=whole(), default=1_000_000, help="poses per batched FK call (default 1e6)")
    parser.add_argument("--seed", type=whole(0, MAX_SEED), default=0, help="random seed (default 0)")
    parser.set_defaults(run=run)


# -- target sets ---------------------------------------------------------------------

def elbow_straight_q3(robot: Robot, q: np.ndarray) -> float:
    """q3 that puts the wrist farthest from joint 2 (elbow fully stretched), by search on FK."""
    def reach(q3):
        qq = q.copy()
        qq[2] = q3
        f = robot.link_frames(qq)
        return np.linalg.norm(f[4, :3, 3] - f[1, :3, 3])

    grid = np.linspace(-np.pi, np.pi, 721)
    k = int(np.argmax([reach(v) for v in grid]))
    lo, hi = grid[k] - 0.01, grid[k] + 0.01
    g = (np.sqrt(5) - 1) / 2
    for _ in range(80):
        a, b = hi - g * (hi - lo), lo + g * (hi - lo)
        if reach(a) > reach(b):
            hi = b
        else:
            lo = a
    return 0.5 * (lo + hi)


def near_singular_q(robot: Robot, n: int, rng: np.random.Generator) -> np.ndarray:
    """Half wrist (q5 → 0), half elbow (stretched), offsets 10^U(−12, −3) rad either way."""
    qs = robot.random_q(n, rng)
    offsets = rng.choice([-1.0, 1.0], n) * 10 ** rng.uniform(-12, -3, n)
    straight = elbow_straight_q3(robot, qs[0])  # the same for every q: depends on DH lengths only
    half = n // 2
    qs[:half, 4] = offsets[:half]
    qs[half:, 2] = straight + offsets[half:]
    inside = robot.within_limits(qs)
    return qs[inside]


def unreachable_targets(robot: Robot, n: int, rng: np.random.Generator) -> np.ndarray:
    """Beyond the total reach (margins 1e-6..0.5 of it), plus, for spherical wrists,
    1 µm..10 mm beyond the stretched elbow where geometry shows no shoulder branch reaches,
    and for UR-type arms, the wrist nearer the base axis than the shoulder offset allows."""
    Ts = robot.fk(robot.random_q(n, rng))
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    radius = robot.reach_bound_mm * (1 + 10 ** rng.uniform(-6, np.log10(0.5), n))
    Ts[:, :3, 3] = robot.shoulder_world + dirs * radius[:, None]
    arm, _ = closed_form_arm(robot)
    if arm is None or not robot._base_is_identity or not robot._tool_is_identity:
        return Ts
    if isinstance(arm, ParallelAxesArm):
        return np.concatenate([Ts[: n // 2], wrist_inside_offset_cylinder(robot, n - n // 2, rng)])
    boundary = []
    straight = elbow_straight_q3(robot, np.zeros(6))
    for q in robot.random_q(4 * n, rng):
        q[2] = straight
        f = robot.link_frames(q)
        out = f[4, :3, 3] - f[1, :3, 3]
        T = robot.fk(q)
        T[:3, 3] += out / np.linalg.norm(out) * 10 ** rng.uniform(-3, 1)
        if _wrist_beyond_both_shoulders(robot, T):
            boundary.append(T)
        if len(boundary) == n - n // 2:
            break
    return np.concatenate([Ts[: n // 2], np.array(boundary).reshape(-1, 4, 4)])


def wrist_inside_offset_cylinder(robot: Robot, n: int, rng: np.random.Generator) -> np.ndarray:
    """Tool poses (n, 4, 4) that no UR-type arm (three parallel axes, base and tool at identity)
    reaches, by geometry: every joint vector puts the wrist point o5 = p − d6·z6 at
    o5·z1 = d2 + d3 + d4 =: D along the horizontal axis z1, so o5 lies at least |D| from the
    base axis; these poses put it at 0.01–0.99 |D|, at heights within the arm's reach."""
    D = abs(robot.d_mm[1] + robot.d_mm[2] + robot.d_mm[3])
    Ts = robot.fk(robot.random_q(n, rng))
    angle = rng.uniform(0, 2 * np.pi, n)
    radius = D * rng.uniform(0.01, 0.99, n)
    height = robot.d_mm[0] + rng.uniform(-0.5, 0.5, n) * robot.reach_bound_mm
    o5 = np.column_stack([radius * np.cos(angle), radius * np.sin(angle), height])
    Ts[:, :3, 3] = o5 + robot.d_mm[5] * Ts[:, :3, 2]
    return Ts


def _wrist_beyond_both_shoulders(robot: Robot, T: np.ndarray) -> bool:
    w = T[:3, 3] - robot.d_mm[5] * T[:3, 2]
    D = robot.d_mm[1] + robot.d_mm[2]
    if robot.a_mm[0] != 0 and D != 0:
        return False  # no simple geometric certificate for this arm
    phi = np.arctan2(w[1], w[0])
    reach = np.hypot(robot.a_mm[1] + np.hypot(robot.a_mm[2], robot.d_mm[3]), D)
    return all(np.linalg.norm(w - [s * robot.a_mm[0] * np.cos(phi), s * robot.a_mm[0] * np.sin(phi), robot.d_mm[0]]) > reach
               for s in (1.0, -1.0))


def literal_fk(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Eq. 1–3 from elementary transforms: the independent check of claimed successes (a
    sliding joint adds q to d instead of θ)."""
    T = robot.base
    for i in range(6):
        slides = robot.prismatic[i]
        theta = robot.theta_offset_rad[i] + (0.0 if slides else q[i])
        d = robot.d_mm[i] + (q[i] if slides else 0.0)
        T = T @ rot_z(theta) @ trans(robot.a_mm[i], 0, d) @ rot_x(robot.alpha_rad[i])
    return T @ robot.tool


# -- running -------------------------------------------------------------------------

def _quality(robot: Robot, batch, Ts: np.ndarray) -> dict:
    ok = batch.success
    bad = 0
    for i in np.nonzero(ok)[0]:
        T = literal_fk(robot, batch.q[i])
        if (np.linalg.norm(T[:3, 3] - Ts[i, :3, 3]) > default_pos_tol(robot) * 1.01
                or np.max(np.abs(T[:3, :3] - Ts[i, :3, :3])) > 2e-9 or not robot.within_limits(batch.q[i])):
            bad += 1
    return dict(rate=ok.mean() if len(ok) else float("nan"), n=len(ok), fails=int((~ok).sum()),
                pos_max=batch.pos_err_mm[ok].max() if ok.any() else float("nan"),
                pos_med=np.median(batch.pos_err_mm[ok]) if ok.any() else float("nan"),
                rot_max=batch.rot_err_rad[ok].max() if ok.any() else float("nan"), unconfirmed=bad)


def bench_robot(robot: Robot, args, rng: np.random.Generator) -> list[dict]:
    rows = []
    qs = robot.random_q(args.n, rng)
    Ts = robot.fk(qs)
    q_fk = robot.random_q(args.fk_batch, rng)
    single_fk = per_call_seconds(lambda: robot.fk(qs[0]), 2000)
    batch_fk = median_seconds(lambda: robot.fk(q_fk), 5)
    near = robot.fk(near_singular_q(robot, args.near, rng))
    unreach = unreachable_targets(robot, args.unreachable, rng)
    arm, _ = closed_form_arm(robot)
    methods = (["analytic"] if arm is not None else []) + ["numeric"]
    for method in methods:
        t = time.perf_counter()
        batch = robot.ik_batch(Ts, method=method, seed=args.seed)
        batch_time = (time.perf_counter() - t) / args.n
        if method == "analytic":
            batch_time = median_seconds(lambda: robot.ik_batch(Ts, method=method), 3) / args.n
        single = median_single_call(lambda T: robot.ik(T, method=method), Ts[: 200 if method == "analytic" else 50])
        # The same single targets through the batch path (one-row arrays), interleaved with the
        # float path so that both see the same machine load: their ratio is the float path's gain.
        single_batch = float("nan")
        if method == "analytic":
            pairs = [(median_single_call(lambda T: robot.ik(T), Ts[k:k + 20]),
                      median_single_call(lambda T: robot.ik_batch(T[None]), Ts[k:k + 20]))
                     for k in range(0, min(200, len(Ts)), 20)]
            single = float(np.median([p[0] for p in pairs]))
            single_batch = float(np.median([p[1] for p in pairs]))
        near_b = robot.ik_batch(near, method=method, seed=args.seed + 1)
        un_b = robot.ik_batch(unreach, method=method, seed=args.seed + 2)
        rows.append(dict(robot=robot.name, method=method, single_fk=single_fk, batch_fk=batch_fk / args.fk_batch,
                         ik_batch=batch_time, ik_single=single, ik_single_batch=single_batch, random=_quality(robot, batch, Ts),
                         near=_quality(robot, near_b, near), unreach_n=len(unreach),
                         false_success=int(un_b.success.sum()),
                         unreach_reasons=dict(zip(*np.unique(un_b.reasons, return_counts=True)))))
    return rows


def run(args: argparse.Namespace) -> int:
    rng = np.random.default_rng(args.seed)
    robots = [load_robot(r) for r in args.robots]
    print(f"Kinematics benchmark: {args.n} random reachable targets, {args.near} near-singular, "
          f"{args.unreachable} unreachable per robot; batched FK of {args.fk_batch} poses; medians of repeats.\n")
    all_rows = []
    for robot in robots:
        t = time.perf_counter()
        rows = bench_robot(robot, args, rng)
        all_rows += rows
        print(f"  {robot.name}: done in {time.perf_counter() - t:.1f} s", flush=True)
    print()
    print("Speed")
    hdr = (f"{'robot':<22}{'IK method':<10}{'FK single':>11}{'FK batch':>14}{'IK batch/solve':>16}{'IK single':>12}"
           f"{'via batch path':>16}")
    print(hdr + "\n" + "-" * len(hdr))
    for r in all_rows:
        via = r["ik_single_batch"]
        via = f"{fmt_time(via)} ({via / r['ik_single']:.1f}x)" if np.isfinite(via) else ""
        print(f"{r['robot']:<22}{r['method']:<10}{fmt_time(r['single_fk']):>11}"
              f"{1 / r['batch_fk']:>10.3g} /s  {fmt_time(r['ik_batch']):>14}{fmt_time(r['ik_single']):>12}{via:>22}")
    print()
    print("IK success and accuracy (successful solves; errors measured by FK of the returned q)")
    hdr = (f"{'robot':<22}{'IK method':<10}{'targets':<10}{'success':>10}{'fails':>7}{'pos err max':>13}"
           f"{'pos err med':>13}{'rot err max':>13}{'unconfirmed':>13}")
    print(hdr + "\n" + "-" * len(hdr))
    for r in all_rows:
        for label in ("random", "near"):
            qd = r[label]
            print(f"{r['robot']:<22}{r['method']:<10}{label:<10}{qd['rate'] * 100:>9.3f}%{qd['fails']:>7}"
                  f"{qd['pos_max']:>10.1e} mm{qd['pos_med']:>10.1e} mm{qd['rot_max']:>9.1e} rad{qd['unconfirmed']:>13}")
    print()
    print("Unreachable targets: a success here would be a false success")
    hdr = f"{'robot':<22}{'IK method':<10}{'targets':>8}{'false successes':>17}   reasons reported"
    print(hdr + "\n" + "-" * len(hdr))
    for r in all_rows:
        reasons = ", ".join(f"{k} {v}" for k, v in sorted(r["unreach_reasons"].items()))
        print(f"{r['robot']:<22}{r['method']:<10}{r['unreach_n']:>8}{r['false_success']:>17}   {reasons}")
    print()
    print("Goals: closed-form IK ≤ 20 µs per solve, ≤ 0.5 ms per single call; batch FK ≥ 1e6 poses/s; "
          "numeric IK ≥ 99.9 % success with position error ≤ 1e-6 mm; zero false successes.")
    return 0
