"""IK from a controller over TCP/IP against the local solver: agreement, branches, latency.

An ``ik-server`` for the Viper s650 runs on loopback in this process; for random
reachable tool poses, each seeded from a few joint vectors, the remote answer is
compared with the local solver's: the largest joint difference where both succeed,
how often the two succeed differently, how often a different seed gives a different
branch (the controller's answer depends on its initial estimate, as the paper found),
and the round trip's latency (median and 95th percentile) against a local solve.
"""

from __future__ import annotations

import argparse
import time
from headless.bench import whole


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--targets", type=whole(), default=500, help="random reachable tool poses (default 500)")
    parser.add_argument("--seeds", type=whole(), default=3, help="seeds per target (default 3)")
    parser.add_argument("--robot", default="adept_viper_s650", help="robot rig")
    parser.add_argument("--readme", action="store_true", help="put the figures into docs/safety.md")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from dataclasses import replace

    from addon.core.config.rigs import load_robot
    from addon.core.kinematics.ik_remote import Controller, ControllerIK
    from headless.ik_server import IKServer

    robot = load_robot(args.robot)
    server = IKServer(robot, "127.0.0.1", 0).start()
    remote = ControllerIK(Controller("127.0.0.1", server.port, 5.0))
    bridged = replace(robot, ik_via=remote)
    rng = np.random.default_rng(0)
    q_true = robot.random_q(args.targets, rng)
    targets = robot.fk(q_true)
    seeds = [robot.random_q(args.targets, rng) for _ in range(args.seeds)]
    diffs, mismatched, local_ms, remote_ms, branch_changes, both = [], 0, [], [], 0, 0
    try:
        remote.ping()
        for i in range(args.targets):
            answers = []
            for seed in seeds:
                t = time.perf_counter()
                loc = robot.ik(targets[i], seed[i])
                local_ms.append((time.perf_counter() - t) * 1e3)
                t = time.perf_counter()
                rem = bridged.ik(targets[i], seed[i])
                remote_ms.append((time.perf_counter() - t) * 1e3)
                if loc.success != rem.success:
                    mismatched += 1
                elif loc.success:
                    both += 1
                    diffs.append(float(np.max(np.abs(loc.q - rem.q))))
                if rem.success:
                    answers.append(rem.q)
            if len(answers) > 1 and any(np.max(np.abs(a - answers[0])) > 1e-3 for a in answers[1:]):
                branch_changes += 1
    finally:
        remote.close()
        server.shutdown()
        server.server_close()
    n = args.targets * args.seeds
    lat = np.array(remote_ms)
    body = "\n".join([
        f"IK over TCP/IP against the local solver (python -m headless bench ik-bridge --targets {args.targets} "
        f"--seeds {args.seeds}; {robot.name}, ik-server on loopback in the same process):",
        "",
        "| what | figure |",
        "|---|---|",
        f"| solves | {n} ({args.targets} reachable poses × {args.seeds} random seeds) |",
        f"| both succeed / succeed differently | {both} / {mismatched} |",
        f"| largest joint difference where both succeed | {max(diffs) if diffs else float('nan'):.2e} rad |",
        f"| poses whose branch changes with the seed (remote) | {branch_changes} of {args.targets} |",
        f"| round trip, median / p95 | {np.median(lat):.2f} / {np.percentile(lat, 95):.2f} ms |",
        f"| local solve, median | {np.median(local_ms):.2f} ms |",
    ])
    print(body)
    if args.readme:
        from headless.bench import readme

        readme.update("ik-bridge", body)
    return 0
