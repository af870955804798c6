"""``ik-server``: serve this project's IK over TCP/IP with the controller protocol.

``python -m headless ik-server [--robot RIG | --config CONFIG] [--host 127.0.0.1] [--port 5757]`` answers
line-delimited JSON requests (see addon/core/kinematics/ik_remote.py) with the robot
rig's own solver, one thread per connection, until Ctrl-C. A scan config then takes its
IK from it with ``[robot] ik = "controller"``; a controller adapter speaking the same
protocol can stand in its place. ``--port 0`` picks a free port (printed).
"""

from __future__ import annotations

import argparse
import json
import socketserver
import sys
import threading

import numpy as np

from addon.core.kinematics.ik_remote import DEFAULT_PORT, PROTOCOL


def _matrix(value, name: str) -> np.ndarray:
    T = np.asarray(value, dtype=np.float64)
    if T.shape != (4, 4) or not np.isfinite(T).all():
        raise ValueError(f"{name} must be a 4 x 4 matrix of finite numbers")
    return T


def _plain(rid) -> bool:
    """An id the answer can carry: none, or a whole number of at most 64 bits."""
    return rid is None or (isinstance(rid, int) and not isinstance(rid, bool) and -(2 ** 63) <= rid < 2 ** 63)


def answer(robot, request) -> dict:
    """The answer to one decoded request (never raises)."""
    rid = request.get("id") if isinstance(request, dict) else None
    if not _plain(rid):
        return {"id": None, "success": False, "reason": "malformed request: id must be a whole number that fits "
                                                         "in 64 bits"}
    try:
        if not isinstance(request, dict):
            raise ValueError("a request is a JSON object")
        op = request.get("op")
        if op == "ping":
            return {"id": rid, "protocol": PROTOCOL, "robot": robot.name}
        if op != "ik":
            raise ValueError(f"unknown op {op!r} (ik, ping)")
        T = _matrix(request.get("target_mm"), "target_mm")
        tool = _matrix(request.get("tool_mm", np.eye(4).tolist()), "tool_mm")
        seed = np.asarray(request.get("seed_rad"), dtype=np.float64)
        if seed.shape != (6,) or not np.isfinite(seed).all():
            raise ValueError("seed_rad must be 6 finite numbers")
    except (ValueError, TypeError, OverflowError) as exc:  # (an integer of 400 digits overflows a float)
        return {"id": rid if _plain(rid) else None, "success": False, "reason": f"malformed request: {exc}"}
    try:
        with np.errstate(all="ignore"):  # (numbers near 1e308 overflow on the way: the answer says so)
            res = robot.with_tool(tool).ik(T, seed)
    except Exception as exc:  # the solver's own refusal of a target (a non-rigid matrix, say)
        return {"id": rid, "success": False, "reason": f"malformed request: {exc}"}
    q = [float(v) for v in res.q] if np.isfinite(res.q).all() else None
    return {"id": rid, "joints_rad": q, "success": bool(res.success), "reason": res.message, "code": res.reason}


MAX_REQUEST_BYTES = 1 << 20  # a request line longer than this is refused (as the client caps its answers)
IDLE_TIMEOUT_S = 600.0  # a connection that sends nothing for this long is closed (its thread freed)


class _Handler(socketserver.StreamRequestHandler):
    timeout = IDLE_TIMEOUT_S

    def handle(self) -> None:
        while True:
            try:
                raw = self.rfile.readline(MAX_REQUEST_BYTES + 1)
            except OSError:  # idle past the timeout, or the client went away
                return
            if not raw:
                return
            if len(raw) > MAX_REQUEST_BYTES and not raw.endswith(b"\n"):
                self.wfile.write((json.dumps({"id": None, "success": False, "reason": (
                    f"malformed request: a line longer than {MAX_REQUEST_BYTES} bytes")}) + "\n").encode("utf-8"))
                return  # the rest of that line cannot be told from the next request
            try:
                request = json.loads(raw.decode("utf-8"))
            except json.JSONDecodeError as exc:
                reply = {"id": None, "success": False, "reason": f"malformed request: not JSON ({exc.msg})"}
            except UnicodeDecodeError:
                reply = {"id": None, "success": False, "reason": "malformed request: not UTF-8 text"}
            except ValueError:  # a number past Python's 4 300 digits
                reply = {"id": None, "success": False, "reason": "malformed request: a number too long to read"}
            except RecursionError:
                reply = {"id": None, "success": False, "reason": "malformed request: JSON nested too deep"}
            else:
                reply = answer(self.server.robot, request)
            try:
                self.wfile.write((json.dumps(reply) + "\n").encode("utf-8"))
                self.wfile.flush()
            except OSError:  # the client went away before its answer
                return


class IKServer(socketserver.ThreadingTCPServer):
    daemon_threads = True
    allow_reuse_address = True
    request_queue_size = 128  # a burst of clients (a farm's workers) waits in the queue, not a second's retry

    def __init__(self, robot, host: str = "127.0.0.1", port: int = DEFAULT_PORT):
        self.robot = robot
        super().__init__((host, port), _Handler)

    @property
    def port(self) -> int:
        return self.server_address[1]

    def start(self) -> "IKServer":
        """Serve in a background thread (tests, benchmarks); ``shutdown()`` stops it."""
        threading.Thread(target=self.serve_forever, name="ik-server", daemon=True).start()
        return self


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", help="robot rig (name or path) whose IK to serve (default adept_viper_s650)")
    parser.add_argument("--config", metavar="CONFIG",
                        help="serve the robot of this scan config instead, as its [robot] table gives it (a URDF "
                             "arm's base_link, tool_link and package_dirs included)")
    parser.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=DEFAULT_PORT, help=f"TCP port (default {DEFAULT_PORT}; 0: any)")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from addon.core.config.rigs import load_robot

    if not 0 <= args.port <= 65535:
        print(f"error: --port must be in 0..65535, got {args.port}", file=sys.stderr)
        return 2
    if args.robot and args.config:
        print("error: give --robot or --config, not both (--config serves its config's robot)", file=sys.stderr)
        return 2
    if args.config:
        from dataclasses import replace

        from addon.core.config.scan import load_scan_config

        # the config's own robot, solved here (its ik = "controller" would ask this very server)
        robot = replace(load_scan_config(args.config, path_required=False).robot, ik_via=None)
    else:
        robot = load_robot(args.robot or "adept_viper_s650")
    try:
        server = IKServer(robot, args.host, args.port)
    except OSError as exc:
        print(f"error: cannot listen on {args.host}:{args.port}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    print(f"ik-server: {robot.name} on {args.host}:{server.port} (protocol {PROTOCOL}); Ctrl-C stops it", flush=True)
    try:
        server.serve_forever()
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM through the command's stop handling
        print("ik-server: stopped", flush=True)
        return getattr(exc, "exit_code", 130)
    finally:
        server.server_close()
    return 0
