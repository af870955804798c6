"""Inverse kinematics: round trips, all branches, seeds, singular and extreme cases, honesty.

Unreachable targets are made unreachable by geometry (triangle inequality on the
link lengths), never by asking the solver.
"""

from dataclasses import replace

import numpy as np
import pytest

from addon.core.errors import InputError, UnreachablePose
from addon.core.kinematics.ik import IKResult, default_pos_tol
from addon.core.kinematics.robot import Robot
from addon.core.config.rigs import load_robot
from addon.core.kinematics.transforms import trans

SPHERICAL = ["adept_viper_s650", "puma560"]


def assert_reaches(robot, res: IKResult, T, tol_scale=1.0):
    assert res.success, res.message
    assert res.reason == "ok"
    assert robot.within_limits(res.q)
    Tq = robot.fk(res.q)
    tol = default_pos_tol(robot) * tol_scale
    assert np.linalg.norm(Tq[:3, 3] - T[:3, 3]) <= tol
    assert np.max(np.abs(Tq[:3, :3] - T[:3, :3])) <= 2e-9
    assert res.pos_err_mm <= tol and res.rot_err_rad <= 1e-9


def assert_finite(res: IKResult):
    assert np.all(np.isfinite(res.q)) and np.isfinite(res.pos_err_mm) and np.isfinite(res.rot_err_rad)


def unlimited(robot: Robot) -> Robot:
    return replace(robot, q_min_rad=np.full(6, -2 * np.pi), q_max_rad=np.full(6, 2 * np.pi))


def stretched_q(robot: Robot, q: np.ndarray) -> np.ndarray:
    """q with the elbow fully stretched: θ3 = β puts link 3's wrist leg in line with link 2."""
    beta = np.arctan2(robot.d_mm[3] * np.sign(robot._sa[2]), robot.a_mm[2])
    q = q.copy()
    q[2] = beta - robot.theta_offset_rad[2]
    return q


# -- round trips ------------------------------------------------------------------

@pytest.mark.parametrize("name", SPHERICAL)
def test_closed_form_round_trip_random(name):
    robot = load_robot(name)
    rng = np.random.default_rng(11)
    qs = robot.random_q(2000, rng)
    Ts = robot.fk(qs)
    batch = robot.ik_batch(Ts)
    assert batch.method == "analytic"
    assert batch.success.all()
    assert batch.pos_err_mm.max() < 1e-9 and batch.rot_err_rad.max() < 1e-12
    assert robot.within_limits(batch.q).all()
    for i in range(0, 2000, 97):  # each reported result really reaches its target
        np.testing.assert_allclose(robot.fk(batch.q[i]), Ts[i], atol=1e-9)


@pytest.mark.parametrize("name", SPHERICAL + ["ur5"])
def test_numeric_round_trip_random(name):
    robot = load_robot(name)
    rng = np.random.default_rng(12)
    qs = robot.random_q(300, rng)
    Ts = robot.fk(qs)
    batch = robot.ik_batch(Ts, method="numeric")
    assert batch.method == "numeric"
    # A local solver may miss a target whose basin is tiny (workspace corners, near
    # singular solutions); the goal is ≥ 99.9 % (bench), and a miss must be honest.
    ok = batch.success
    assert ok.mean() >= 0.99, [m for m in batch.messages if m != "ok"][:3]
    assert batch.pos_err_mm[ok].max() <= 1e-6 and batch.rot_err_rad[ok].max() <= 1e-9
    assert robot.within_limits(batch.q).all()
    for i in np.nonzero(~ok)[0]:
        assert batch.reasons[i] == "not_converged"
        assert batch.pos_err_mm[i] > 1e-6 or batch.rot_err_rad[i] > 1e-9


def test_all_eight_closed_form_solutions():
    # Wrist centre close enough to the base axis that both shoulder branches reach it.
    robot = unlimited(load_robot("adept_viper_s650"))
    q_true = np.radians([30, 10, -120, 20, 60, -10])
    T = robot.fk(q_true)
    assert_eight_distinct_solutions(robot, T, q_true)


def assert_eight_distinct_solutions(robot, T, q_true) -> np.ndarray:
    """ik_all gives eight configurations, each reaching T, distinct (not the same angles
    shifted by whole turns), q_true among them; returns them."""
    sols = robot.ik_all(T)
    assert sols.shape == (8, 6)
    for q in sols:
        np.testing.assert_allclose(robot.fk(q), T, atol=1e-9)
    wrapped = np.round(np.mod(sols + np.pi, 2 * np.pi) - np.pi, 6)
    assert len({tuple(w) for w in wrapped}) == 8
    d = np.abs(np.mod(sols - q_true + np.pi, 2 * np.pi) - np.pi).max(axis=1)
    assert d.min() < 1e-9
    return sols


def test_limits_cut_solutions_and_each_is_inside():
    robot = load_robot("puma560")
    T = robot.fk(np.radians([30, 50, -40, 20, 60, -10]))
    sols = robot.ik_all(T)
    assert 1 <= len(sols) <= 8
    assert robot.within_limits(sols).all()


def test_seed_picks_the_nearest_solution():
    robot = unlimited(load_robot("adept_viper_s650"))
    q_true = np.radians([30, 10, -120, 20, 60, -10])
    T = robot.fk(q_true)
    for q in robot.ik_all(T):
        res = robot.ik(T, q0=q + 0.01)
        np.testing.assert_allclose(res.q, q, atol=1e-9)


def test_numeric_prefers_solution_near_seed():
    robot = load_robot("ur5")
    q_true = np.radians([20, -70, 80, -100, -80, 30])
    res = robot.ik(robot.fk(q_true), q0=q_true + 0.05)
    np.testing.assert_allclose(res.q, q_true, atol=1e-6)


def test_seed_beyond_two_pi_and_result_wrapped_into_limits():
    robot = load_robot("adept_viper_s650")
    q_true = np.radians([10, 60, -80, 30, 40, 50])
    res = robot.ik(robot.fk(q_true), q0=q_true + 2 * np.pi * np.array([3, 0, 0, -2, 0, 1]))
    assert_reaches(robot, res, robot.fk(q_true))


# -- singular and extreme cases ------------------------------------------------------

@pytest.mark.parametrize("name,method", [(n, "analytic") for n in SPHERICAL] + [(n, "numeric") for n in SPHERICAL + ["ur5"]])
@pytest.mark.parametrize("q5", [0.0, 1e-12, 1e-9, -1e-6])
def test_wrist_singularity(name, method, q5):
    robot = load_robot(name)
    q = np.radians([25, 35, -50, 40, 0, 70])
    q[4] = q5
    T = robot.fk(q)
    res = robot.ik(T, method=method)
    assert_finite(res)
    assert_reaches(robot, res, T)
    # A target 1e-9 mm away from the singular pose is just as solvable.
    res = robot.ik(trans(1e-9, -1e-9, 1e-9) @ T, method=method)
    assert_finite(res)
    assert_reaches(robot, res, trans(1e-9, -1e-9, 1e-9) @ T)


def viper_shoulder_singular_q():
    """Viper q with the wrist centre on the joint-1 axis, found by bisection on q2 using FK only."""
    robot = load_robot("adept_viper_s650")

    def wrist_x(q2):
        q = np.radians([0.0, 0.0, -150.0, 30.0, 45.0, 10.0])
        q[1] = q2
        return robot.link_frames(q)[4][0, 3]

    lo, hi = np.radians(0.0), np.radians(60.0)
    assert np.sign(wrist_x(lo)) != np.sign(wrist_x(hi))
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if np.sign(wrist_x(mid)) == np.sign(wrist_x(lo)):
            lo = mid
        else:
            hi = mid
    q = np.radians([0.0, 0.0, -150.0, 30.0, 45.0, 10.0])
    q[1] = 0.5 * (lo + hi)
    return robot, q


@pytest.mark.parametrize(
    "method,offset_mm",
    [("analytic", 0.0), ("analytic", 1e-9), ("analytic", 1e-3), ("numeric", 0.0), ("numeric", 1e-9)],
)
def test_shoulder_singularity_wrist_on_base_axis(method, offset_mm):
    # (A local solver is not asked for 1e-3 mm off the axis: there the solution lies
    # along a long curved valley that damped steps cross only very slowly.)
    robot, q = viper_shoulder_singular_q()
    w = robot.link_frames(q)[4][:3, 3]
    assert np.hypot(w[0], w[1]) < 1e-9  # really on the axis
    T = trans(offset_mm, offset_mm, 0) @ robot.fk(q)
    res = robot.ik(T, q0=np.radians([40, 10, -140, 0, 30, 0]), method=method)
    assert_finite(res)
    assert_reaches(robot, res, T)


@pytest.mark.parametrize("name", SPHERICAL)
@pytest.mark.parametrize("method", ["analytic", "numeric"])
def test_elbow_fully_stretched_and_just_beyond(name, method):
    robot = load_robot(name)
    q = stretched_q(robot, np.radians([20, 30, 0, 30, 50, -20]))
    assert robot.within_limits(q)
    frames = robot.link_frames(q)
    T = robot.fk(q)
    # Outward = from joint 2's axis point towards the wrist centre, in the arm's plane.
    out = frames[4][:3, 3] - frames[1][:3, 3]
    out /= np.linalg.norm(out)
    for delta, reachable in [(0.0, True), (-1e-9, True), (1e-9, True), (1e-3, False), (1.0, False)]:
        Td = T.copy()
        Td[:3, 3] += delta * out
        res = robot.ik(Td, q0=q, method=method)
        assert_finite(res)
        if reachable:
            # 1e-9 mm beyond the boundary is within tolerance of the reachable boundary.
            assert res.success, (delta, res.message)
            assert res.pos_err_mm <= max(default_pos_tol(robot), abs(delta) * 1.01)
        else:
            assert not res.success, (delta, res.message)
            assert res.pos_err_mm == pytest.approx(delta, rel=0.05), res.message
            assert res.reason in ("out_of_reach", "not_converged")


@pytest.mark.parametrize("name", SPHERICAL + ["ur5"])
def test_never_claims_success_beyond_reach(name):
    robot = load_robot(name)
    rng = np.random.default_rng(13)
    n = 60
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    radius = robot.reach_bound_mm * (1 + rng.uniform(1e-3, 0.5, n))
    Ts = robot.fk(robot.random_q(n, rng))
    Ts[:, :3, 3] = robot.shoulder_world + dirs * radius[:, None]
    batch = robot.ik_batch(Ts)
    assert not batch.success.any()
    assert set(batch.reasons) == {"out_of_reach"}
    assert np.isfinite(batch.q).all()
    assert "out of reach" in batch.messages[0] and "mm" in batch.messages[0]


def wrist_centre_unreachable(robot: Robot, T: np.ndarray) -> bool:
    """Geometry only: is the wrist centre of tool pose T beyond links 2–3 from both shoulder branches?

    For these arms (d2 + d3 = D, spherical wrist, α1 = ±90°) joint 2's axis point is
    (±a1 cos φ, ±a1 sin φ, d1) with φ the wrist centre's azimuth when D = 0, and the
    wrist centre must lie within √((a2 + L3)² + D²) of it.
    """
    w = T[:3, 3] - robot.d_mm[5] * T[:3, 2]
    phi = np.arctan2(w[1], w[0])
    D = robot.d_mm[1] + robot.d_mm[2]
    assert robot.a_mm[0] == 0 or D == 0  # the two bundled arms: PUMA (a1 = 0), Viper (D = 0)
    reach = np.hypot(robot.a_mm[1] + np.hypot(robot.a_mm[2], robot.d_mm[3]), D)
    joint2 = [np.array([s * robot.a_mm[0] * np.cos(phi), s * robot.a_mm[0] * np.sin(phi), robot.d_mm[0]]) for s in (1, -1)]
    return min(np.linalg.norm(w - o) for o in joint2) > reach


@pytest.mark.parametrize("name", SPHERICAL)
def test_never_claims_success_just_outside_the_stretched_boundary(name):
    """Targets 1 µm–10 mm beyond the stretched-arm boundary, within the loose reach bound."""
    robot = load_robot(name)
    rng = np.random.default_rng(14)
    Ts = []
    for q in robot.random_q(80, rng):
        q = stretched_q(robot, q)
        frames = robot.link_frames(q)
        out = frames[4][:3, 3] - frames[1][:3, 3]
        T = robot.fk(q)
        T[:3, 3] += out / np.linalg.norm(out) * 10 ** rng.uniform(-3, 1)
        if wrist_centre_unreachable(robot, T):
            Ts.append(T)
    assert len(Ts) >= 30
    Ts = np.array(Ts)
    for method in ("analytic", "numeric"):
        batch = robot.ik_batch(Ts, method=method)
        assert not batch.success.any(), method
        assert np.isfinite(batch.q).all()


def test_reachable_only_outside_joint_limits():
    robot = load_robot("adept_viper_s650")
    T = robot.fk(np.radians([10, 60, -80, 30, 150, 50]))  # J5 = 150° is beyond ±120°
    every = unlimited(robot).ik_all(T)
    assert len(every) > 0 and not robot.within_limits(every).any()  # precondition, by FK-verified branches
    res = robot.ik(T)
    assert not res.success
    assert res.reason == "joint_limits"
    assert "outside" in res.message and "J5" in res.message
    with pytest.raises(UnreachablePose, match="J5") as info:
        robot.ik(T, raise_on_failure=True)
    assert info.value.result.reason == "joint_limits"
    assert not robot.ik(T, method="numeric").success


@pytest.mark.parametrize("scale_to", [1e-3, 1e5])
@pytest.mark.parametrize("name", SPHERICAL + ["ur5"])
def test_link_lengths_from_a_micron_to_a_hundred_metres(name, scale_to):
    base = load_robot(name)
    lengths = np.abs(np.r_[base.a_mm, base.d_mm])
    lengths = lengths[lengths > 0]
    factor = scale_to / (lengths.min() if scale_to < 1 else lengths.max())
    robot = base.scaled(factor)
    rng = np.random.default_rng(15)
    qs = robot.random_q(40, rng)
    batch = robot.ik_batch(robot.fk(qs))
    assert batch.success.all()
    assert batch.pos_err_mm.max() <= default_pos_tol(robot)
    assert np.isfinite(batch.q).all()


def test_mixed_link_lengths_in_one_arm():
    viper = load_robot("adept_viper_s650")
    robot = replace(viper, a_mm=np.array([1e-3, 1e5, 1e-3, 0, 0, 0]), d_mm=np.array([1e5, 0, 0, 1e5, 0, 1e-3]))
    rng = np.random.default_rng(16)
    qs = robot.random_q(200, rng)
    for method in ("analytic", "numeric"):
        batch = robot.ik_batch(robot.fk(qs[:100] if method == "numeric" else qs), method=method)
        assert batch.success.all(), method
        assert batch.pos_err_mm.max() <= default_pos_tol(robot)


# -- inputs -------------------------------------------------------------------------

@pytest.mark.parametrize(
    "kwargs,fragment",
    [
        (dict(T_target=np.full((4, 4), np.nan)), "NaN"),
        (dict(T_target=np.diag([1, 1, 2, 1.0])), "orthonormal"),
        (dict(T_target=np.eye(4), q0=[0, 0, 0]), "q0"),
        (dict(T_target=np.eye(4), q0=[0, 0, np.nan, 0, 0, 0]), "finite"),
        (dict(T_target=np.eye(4), method="magic"), "magic"),
        (dict(T_target=np.eye(4), pos_tol_mm=-1), "pos_tol_mm"),
    ],
)
def test_bad_ik_inputs(kwargs, fragment):
    with pytest.raises(InputError, match=fragment):
        load_robot("puma560").ik(**kwargs)


def test_analytic_refused_for_arm_without_a_closed_form():
    ur5 = load_robot("ur5")
    odd = replace(ur5, name="odd", alpha_rad=ur5.alpha_rad + np.radians([0, 0, 0, 0, 0, 30]))
    with pytest.raises(InputError, match="closed form.*α3.*α6 must be 0.*UR-type"):
        odd.ik(np.eye(4), method="analytic")
    assert odd.ik(odd.fk(np.full(6, 0.3))).method == "numeric"


# -- the UR-type closed form (three parallel axes, offset wrist) ---------------------------

def test_ur_closed_form_round_trip_ten_thousand():
    robot = load_robot("ur5")
    rng = np.random.default_rng(21)
    qs = robot.random_q(10000, rng)
    batch = robot.ik_batch(robot.fk(qs))
    assert batch.method == "analytic" and batch.success.all()
    assert batch.pos_err_mm.max() < 1e-9 and batch.rot_err_rad.max() < 1e-12
    assert robot.within_limits(batch.q).all()


def test_ur_all_eight_solutions_and_the_seed_picks_each():
    robot = load_robot("ur5")  # every joint ±360°: all eight fit
    q_true = np.radians([10, -90, 60, -60, 45, 10])
    T = robot.fk(q_true)
    sols = assert_eight_distinct_solutions(robot, T, q_true)
    for q in sols:
        np.testing.assert_allclose(robot.ik(T, q0=q + 0.01).q, q, atol=1e-9)


def test_ur_closed_form_finds_what_a_numeric_search_finds():
    """Where fewer than eight solutions exist (one shoulder side cannot reach), the numeric
    solver from 60 random seeds finds no configuration the closed form missed."""
    robot = load_robot("ur5")
    T = robot.fk(np.radians([30, -60, 70, -100, 50, 20]))
    closed = robot.ik_all(T)
    assert 1 <= len(closed) < 8

    def same(a, b):
        return np.abs(np.mod(a - b + np.pi, 2 * np.pi) - np.pi).max() < 1e-4

    for q0 in robot.random_q(60, np.random.default_rng(24)):
        res = robot.ik(T, q0=q0, method="numeric")
        if res.success:
            assert any(same(res.q, c) for c in closed), res.q


@pytest.mark.parametrize("q5", [0.0, 1e-12, 1e-7, np.pi])
def test_ur_wrist_singularity(q5):
    robot = load_robot("ur5")
    q = np.radians([10, -80, 60, -40, 0, 30])
    q[4] = q5
    T = robot.fk(q)
    res = robot.ik(T, q0=q + 0.02)
    assert res.method == "analytic"
    assert_reaches(robot, res, T, tol_scale=10)


def test_ur_wrist_exactly_straight_is_solved_for_random_arms():
    """q5 = 0 or π exactly, the rest random within the limits: the closed form reaches every
    target (about 0.5 % were called out of reach: θ5 from arccos of a cosine one ulp under 1
    came out 1.5e-8 rad, not singular, and θ6 from rounding noise)."""
    rng = np.random.default_rng(5)
    from addon.core.config.toml import RIGS_DIR

    for name in ("ur5", RIGS_DIR / "robots" / "urdf" / "ur5.urdf"):
        robot = load_robot(name)
        qs = robot.random_q(400, rng)
        qs[:, 4] = np.where(rng.random(400) < 0.5, 0.0, np.pi)
        qs = qs[[not robot.limit_violations(q) for q in qs]]
        failed = [q for q in qs if not robot.ik(robot.fk(q), q0=q).success]
        assert len(qs) > 100 and not failed, (name, len(failed), failed[:2])


def test_ur_shoulder_offset_cylinder_is_unreachable():
    """o5 = p − d6·z6 satisfies o5·z1 = d2 + d3 + d4 with z1 horizontal, whatever the joints:
    poses whose o5 lies nearer the base axis than that are out of reach, by geometry."""
    robot = load_robot("ur5")
    rng = np.random.default_rng(22)
    D = abs(robot.d_mm[1] + robot.d_mm[2] + robot.d_mm[3])
    Ts = robot.fk(robot.random_q(200, rng))
    angle = rng.uniform(0, 2 * np.pi, 200)
    o5 = np.column_stack([D * rng.uniform(0, 0.99, 200) * np.cos(angle),
                          D * rng.uniform(0, 0.99, 200) * np.sin(angle), rng.uniform(-500, 700, 200)])
    Ts[:, :3, 3] = o5 + robot.d_mm[5] * Ts[:, :3, 2]
    batch = robot.ik_batch(Ts)
    assert batch.method == "analytic" and not batch.success.any()
    assert np.isfinite(batch.q).all()
    assert not robot.ik_batch(Ts[:10], method="numeric").success.any()


def test_ur_closed_form_respects_narrow_limits():
    robot = load_robot("ur5")
    narrow = replace(robot, q_min_rad=np.radians([-90, -180, -150, -180, -170, -180]),
                     q_max_rad=np.radians([90, 0, 150, 0, 170, 180]))
    rng = np.random.default_rng(23)
    qs = narrow.random_q(500, rng)
    batch = narrow.ik_batch(narrow.fk(qs))
    assert batch.success.all() and narrow.within_limits(batch.q).all()


# -- a single target: the float path gives the batch path's answer -------------------------

@pytest.mark.parametrize("name", SPHERICAL + ["ur5"])
def test_single_target_branches_on_floats_match_the_batch_branches(name):
    """branches_one / parallel_branches_one compute the same eight branches as the
    vectorised forms (same order, angles equal modulo 2π); None exactly where the batch
    form says the geometry has no real solution."""
    from addon.core.kinematics.ik import closed_form_arm
    from addon.core.kinematics.ik_analytic import branches, branches_one, flange_targets
    from addon.core.kinematics.ik_parallel import ParallelAxesArm, parallel_branches, parallel_branches_one

    robot = load_robot(name)
    arm, _ = closed_form_arm(robot)
    parallel = isinstance(arm, ParallelAxesArm)
    rng = np.random.default_rng(31)
    F = flange_targets(robot, robot.fk(robot.random_q(400, rng)))
    batch = (parallel_branches if parallel else branches)(arm, F, np.zeros((400, 6)))
    geometry_ok = batch.geometry_ok()
    one = parallel_branches_one if parallel else branches_one
    compared = 0
    for i in range(400):
        thetas = one(arm, F[i])
        assert thetas is not None and len(thetas) == 8
        for k, theta in enumerate(thetas):
            assert (theta is not None) == geometry_ok[i, k], (i, k)
            if theta is not None:
                wrapped = np.mod(np.array(theta) - batch.theta[i, k] + np.pi, 2 * np.pi) - np.pi
                assert np.abs(wrapped).max() < 1e-12
                compared += 1
    assert compared >= 400 * 4


@pytest.mark.parametrize("limits", ["bundled", "lopsided"])
@pytest.mark.parametrize("name", SPHERICAL + ["ur5"])
def test_single_solve_gives_the_batch_answer(name, limits):
    """robot.ik (one target, the float path) and robot.ik_batch agree on random reachable
    targets with random seeds, on targets beyond reach, at the wrist singularity and with
    a seed outside the limits (the last three fall back to the batch path). Lopsided
    limits (-250°..200°) make the turn nearest the seed miss them, so that a neighbouring
    turn is taken."""
    robot = load_robot(name)
    if limits == "lopsided":
        robot = replace(robot, q_min_rad=np.full(6, np.radians(-250.0)), q_max_rad=np.full(6, np.radians(200.0)))
    rng = np.random.default_rng(32)
    qs = robot.random_q(300, rng)
    T = robot.fk(qs)
    seeds = np.clip(qs + rng.normal(0.0, 0.8, qs.shape), robot.q_min_rad, robot.q_max_rad)
    far = T[:20].copy()
    far[:, :3, 3] *= 3.0 * robot.reach_bound_mm / np.linalg.norm(far[:, :3, 3], axis=1, keepdims=True)
    q_singular = qs[:5].copy()
    q_singular[:, 4] = 0.0
    T_all = np.concatenate([T, far, robot.fk(q_singular)])
    seeds_all = np.concatenate([seeds, seeds[:20], seeds[:5]])
    batch = robot.ik_batch(T_all, seeds_all)
    for i in range(len(T_all)):
        one = robot.ik(T_all[i], q0=seeds_all[i])
        assert one.success == batch.success[i] and one.reason == batch.reasons[i], i
        np.testing.assert_allclose(one.q, batch.q[i], atol=1e-12)
    assert batch.success[:300].all() and not batch.success[300:320].any()
    outside = robot.q_max_rad + 0.5
    np.testing.assert_allclose(robot.ik(T[0], q0=outside).q, robot.ik_batch(T[:1], outside).q[0], atol=1e-12)


@pytest.mark.parametrize("name", SPHERICAL + ["ur5"])
def test_straight_elbow_keeps_the_seed_that_reaches_the_target(name):
    """With the elbow exactly straight the elbow's cosine computes a few ulps past 1: the
    one-target solve dropped that branch and swung the arm to another (J1 by 150-200°, a
    hunt's finding on a third of the UR5's straight-elbow poses), where the batch solve
    kept it. Seeded with the very joints that reach the target, both must return them."""
    robot = load_robot(name)
    rng = np.random.default_rng(7)
    moved = []
    for q in robot.random_q(150, rng):
        q = stretched_q(robot, q) if name in SPHERICAL else np.where(np.arange(6) == 2, 0.0, q)
        if not robot.within_limits(q):
            continue
        T = robot.fk(q)
        one = robot.ik(T, q0=q)
        batch = robot.ik_batch(T[None], q[None])
        assert one.success and batch.success[0]
        turn = np.abs(np.mod(one.q - q + np.pi, 2 * np.pi) - np.pi).max()
        moved.append(turn)
        np.testing.assert_allclose(one.q, batch.q[0], atol=1e-9)
    assert len(moved) >= 50 and max(moved) < 1e-6, (len(moved), max(moved))
