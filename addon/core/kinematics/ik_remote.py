"""Inverse kinematics from a robot controller over TCP/IP (line-delimited JSON).

The paper's simulator can ask the real controller for IK instead of its own solver;
the controller's answers differ slightly (the branch it picks depends on the seed).
This is the client; ``python -m headless ik-server`` serves the project's own IK
with the same protocol, so a team can put an adapter for its controller behind it.

Protocol, version 1: one JSON object per line, UTF-8, each way.

Request ``{"op": "ik", "id": 7, "target_mm": [[4 × 4]], "seed_rad": [6], "tool_mm": [[4 × 4]]}``:
the tool pose to reach in the world frame (the robot's base frame unless its rig gives [base]; mm), the joints to start from, and
the tool frame in the flange frame (the paper's T_L^6). Answer
``{"id": 7, "joints_rad": [6], "success": true, "reason": "ok"}``; on failure
``success`` is false and ``reason`` says why in words (``joints_rad`` may be the best
attempt or absent). ``{"op": "ping", "id": 1}`` answers ``{"id": 1, "protocol": 1,
"robot": "<name>"}``. A request the server cannot read answers
``{"id": ..., "success": false, "reason": "malformed request: ..."}``.

The client keeps one connection, waits ``timeout_s`` for each answer, and tries once
more (on a new connection) after a timeout or a dropped connection; every failure is
one line naming the host and port. A controller's answer counts as reaching the
target only when this cell's own forward kinematics confirm it.
"""

from __future__ import annotations

import json
import math
import socket
import time
from dataclasses import dataclass

import numpy as np

from ..errors import InputError, ScannerError
from .ik import REASONS, ROT_TOL_RAD, IKResult, default_pos_tol, pose_errors

PROTOCOL = 1
DEFAULT_PORT = 5757
FAILURE_CODES = tuple(r for r in REASONS if r != "ok")  # an answer's "code" when it failed



def _finite(v) -> bool:
    """A JSON number that is a finite float (an integer of 400 digits is not: math.isfinite
    overflows on it)."""
    try:
        return math.isfinite(v)
    except OverflowError:
        return False

class ControllerError(ScannerError):
    """The IK controller could not be reached or answered something unreadable."""


@dataclass(frozen=True)
class Controller:
    host: str = "127.0.0.1"
    port: int = DEFAULT_PORT
    timeout_s: float = 2.0

    def __post_init__(self) -> None:
        try:  # a name a resolver can take (not empty, labels of 1-63 characters)
            ok = isinstance(self.host, str) and 0 < len(self.host.encode("idna")) <= 253
        except UnicodeError:
            ok = False
        if not ok:
            raise InputError(f"{self.host!r} is not a host name or address (1-253 characters, each dot-separated "
                             f"part 1-63)")

    @property
    def where(self) -> str:
        return f"{self.host}:{self.port}"


class ControllerIK:
    """The client: ``solve(robot, T_target, q0)`` gives an IKResult, as the local solver does."""

    def __init__(self, controller: Controller):
        self.controller = controller
        self._sock: socket.socket | None = None
        self._buffer = b""
        self._next_id = 0

    def __repr__(self) -> str:
        return f"ControllerIK({self.controller.where})"

    def __getstate__(self) -> dict:  # a farm ships configs to its workers: each connects anew
        return {"controller": self.controller}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["controller"])

    # -- the connection -------------------------------------------------------------
    def close(self) -> None:
        if self._sock is not None:
            try:
                self._sock.close()
            finally:
                self._sock = None
                self._buffer = b""

    def _connect(self) -> socket.socket:
        if self._sock is None:
            c = self.controller
            self._sock = socket.create_connection((c.host, c.port), timeout=c.timeout_s)
            self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        return self._sock

    def _exchange(self, line: bytes) -> bytes:
        sock = self._connect()
        sock.settimeout(self.controller.timeout_s)  # the last answer may have left it shorter
        sock.sendall(line)
        # The timeout holds for the whole answer, not for each piece of it: a controller that
        # sends a byte now and then and never ends its line would otherwise hold the scan.
        deadline = time.monotonic() + self.controller.timeout_s
        while b"\n" not in self._buffer:
            left = deadline - time.monotonic()
            if left <= 0:
                raise socket.timeout("no whole answer in time")
            sock.settimeout(left)
            chunk = sock.recv(65536)
            if not chunk:
                raise ConnectionResetError("the controller closed the connection")
            self._buffer += chunk
            if len(self._buffer) > 1_000_000:
                raise ControllerError(f"IK controller at {self.controller.where}: an answer longer than 1 MB")
        answer, self._buffer = self._buffer.split(b"\n", 1)
        return answer

    def call(self, request: dict) -> dict:
        """Send one request and return its answer (a dict), retrying once on a new connection."""
        self._next_id += 1
        request = {**request, "id": self._next_id}
        line = (json.dumps(request) + "\n").encode("utf-8")
        where = self.controller.where
        for attempt in (1, 2):
            try:
                raw = self._exchange(line)
                break
            except socket.timeout:
                self.close()
                if attempt == 2:
                    raise ControllerError(f"IK controller at {where}: no answer within "
                                          f"{self.controller.timeout_s:g} s (on a retry over a new connection too)") from None
            except ConnectionRefusedError:
                self.close()
                if attempt == 2:
                    raise ControllerError(f"IK controller at {where}: nothing is listening there (connection "
                                          "refused, on a retry too); start it, e.g. python -m headless ik-server") from None
            except OSError as exc:
                self.close()
                if attempt == 2:
                    raise ControllerError(f"IK controller at {where}: {exc.strerror or exc} (on a retry over a new connection too)") from None
        try:
            answer = json.loads(raw.decode("utf-8"))
        except (UnicodeDecodeError, ValueError, RecursionError):  # (JSONDecodeError; a number past
            # Python's 4 300 digits; nested too deep for the parser)
            self.close()
            raise ControllerError(f"IK controller at {where}: the answer is not JSON this client can read: "
                                  f"{raw[:80]!r}") from None
        if not isinstance(answer, dict):
            self.close()
            raise ControllerError(f"IK controller at {where}: the answer is not a JSON object: {raw[:80]!r}")
        rid = answer.get("id")
        if not isinstance(rid, int) or isinstance(rid, bool) or rid != request["id"]:
            self.close()
            raise ControllerError(f"IK controller at {where}: the answer is for request {rid!r}, not for request "
                                  f"{request['id']}: {raw[:80]!r}")
        return answer

    def served_robot(self) -> str | None:
        """The robot the controller says it serves (its ping's ``robot``), asked once; None
        where it does not say or cannot be asked."""
        if not hasattr(self, "_served"):
            try:
                name = self.ping().get("robot")
            except ControllerError:
                name = None
            self._served = name if isinstance(name, str) else None
        return self._served

    def _other_robot(self, robot) -> str:
        """Words for a failed solve where the controller serves another robot than this cell's."""
        served = self.served_robot()
        return f" (the controller serves the robot {served!r}; this cell's is {robot.name!r})" \
            if served and served != robot.name else ""

    def ping(self) -> dict:
        answer = self.call({"op": "ping"})
        if answer.get("protocol") != PROTOCOL:
            raise ControllerError(f"IK controller at {self.controller.where} speaks protocol "
                                  f"{answer.get('protocol')!r}, this client {PROTOCOL}")
        return answer

    # -- IK -------------------------------------------------------------------------
    def solve(self, robot, T_target, q0) -> IKResult:
        """IK for ``robot`` (its tool included) from the controller, checked with this cell's FK."""
        T = np.asarray(T_target, dtype=np.float64)
        seed = np.asarray(q0, dtype=np.float64).reshape(6)
        answer = self.call({"op": "ik", "target_mm": T.tolist(), "seed_rad": seed.tolist(),
                            # T_L^6, in the flange's frame, as the controller's with_tool takes it (robot.tool
                            # holds the flange's own pose too: a URDF arm's got it twice before)
                            "tool_mm": robot.tool2flange.tolist()})
        where = self.controller.where
        success, reason = answer.get("success"), answer.get("reason", "")
        if not isinstance(success, bool) or not isinstance(reason, str):
            raise ControllerError(f"IK controller at {where}: the answer lacks 'success' (true/false) and "
                                  f"'reason' (text): {json.dumps(answer)[:120]}")
        joints = answer.get("joints_rad")
        q = None
        if joints is not None:
            if not (isinstance(joints, list) and len(joints) == 6 and all(
                    isinstance(v, (int, float)) and not isinstance(v, bool) and _finite(v) for v in joints)):
                raise ControllerError(f"IK controller at {where}: 'joints_rad' must be 6 finite numbers, got "
                                      f"{json.dumps(joints)[:120]}")
            q = np.array(joints, dtype=np.float64)
        if not success:
            # The answer's optional "code" is the solver's reason code; a controller that
            # sends none (or one outside the four) reads as out of reach.
            code = answer.get("code")
            code = code if code in FAILURE_CODES else "out_of_reach"
            return IKResult(seed if q is None else q, False, math.inf, math.inf, 0,
                            f"the controller at {where} found no solution: {reason}{self._other_robot(robot)}",
                            "controller", code)
        if q is None:
            raise ControllerError(f"IK controller at {where}: a successful answer without 'joints_rad'")
        pos_err, rot_err = pose_errors(robot, q[None, :], T[None])
        pos, rot = float(pos_err[0]), float(rot_err[0])
        inside = bool(robot.within_limits(q))
        ok = pos <= default_pos_tol(robot) and rot <= ROT_TOL_RAD and inside
        if ok:
            return IKResult(q, True, pos, rot, 0, "ok", "controller", "ok")
        why = ("outside this cell's joint limits" if not inside else
               f"{pos:.3g} mm and {math.degrees(rot):.3g}° from the target in this cell's kinematics")
        why += self._other_robot(robot)
        return IKResult(q, False, pos, rot, 0, f"the controller at {where} answered joints {why}", "controller",
                        "joint_limits" if not inside else "numerical")
