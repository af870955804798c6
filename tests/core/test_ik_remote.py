"""IK from a controller over TCP/IP, on loopback: the protocol, each failure as one line naming
host and port, and a scan planned through the bridge giving the local joints."""

import json
import re
import socket
import threading
from dataclasses import replace

import numpy as np
import pytest

from addon.core.config.rigs import load_robot
from addon.core.config.scan import load_scan_config
from addon.core.kinematics.ik_remote import Controller, ControllerError, ControllerIK
from headless.ik_server import IKServer


@pytest.fixture(scope="module")
def server():
    srv = IKServer(load_robot("adept_viper_s650"), "127.0.0.1", 0).start()
    yield srv
    srv.shutdown()
    srv.server_close()


def _client(port, timeout=2.0):
    return ControllerIK(Controller("127.0.0.1", port, timeout))


def test_the_bridge_answers_as_the_local_solver_and_fk_confirms(server):
    robot = load_robot("adept_viper_s650")
    remote = replace(robot, ik_via=_client(server.port))
    assert remote.ik_via.ping()["robot"] == robot.name
    rng = np.random.default_rng(3)
    q = robot.random_q(20, rng)
    T = robot.fk(q)
    seeds = robot.random_q(20, rng)
    for i in range(20):
        loc, rem = robot.ik(T[i], seeds[i]), remote.ik(T[i], seeds[i])
        assert rem.success and loc.success and rem.method == "controller"
        np.testing.assert_allclose(rem.q, loc.q, atol=1e-9)
        np.testing.assert_allclose(robot.fk(rem.q), T[i], atol=1e-6)


def test_a_urdf_arm_with_a_tool_gets_its_own_joints_through_the_bridge():
    """A URDF arm's flange (ROS's tool0) is not DH frame 6: the controller is sent the tool in
    the flange's frame (T_L^6), as it mounts it, and answers the local solver's joints (the
    flange's pose was sent in the tool as well, and every target missed)."""
    from addon.core.kinematics.transforms import make_pose, rot_x

    arm = load_robot("rigs/robots/urdf/ur5.urdf")
    assert not np.allclose(arm.flange, np.eye(4))
    robot = arm.with_tool(make_pose(rot_x(0.3)[:3, :3], [0.0, 20.0, 100.0]))
    srv = IKServer(arm, "127.0.0.1", 0).start()
    try:
        remote = replace(robot, ik_via=_client(srv.port))
        rng = np.random.default_rng(11)
        q = robot.random_q(8, rng)
        T = robot.fk(q)
        for i in range(8):
            loc, rem = robot.ik(T[i], q[i]), remote.ik(T[i], q[i])
            assert loc.success and rem.success, rem.message
            np.testing.assert_allclose(robot.fk(rem.q), T[i], atol=1e-6)
    finally:
        srv.shutdown()
        srv.server_close()


def test_a_batch_goes_to_the_controller_too(server):
    """ik_batch asks the controller where the robot names one, as ik does (a review: it always
    solved locally); an unreachable target among them fails alone."""
    robot = load_robot("adept_viper_s650")
    remote = replace(robot, ik_via=_client(server.port))
    rng = np.random.default_rng(5)
    q = robot.random_q(6, rng)
    T = robot.fk(q)
    T[3][:3, 3] += 1e5  # far out of reach
    batch = remote.ik_batch(T, robot.random_q(6, rng))
    assert batch.method == "controller" and len(batch) == 6
    assert batch.success.tolist() == [True, True, True, False, True, True]
    ok = batch.success
    np.testing.assert_allclose(robot.fk(batch.q[ok]), T[ok], atol=1e-6)


def test_an_unreachable_target_is_a_failed_solve_with_the_controllers_reason(server):
    robot = load_robot("adept_viper_s650")
    far = np.eye(4)
    far[:3, 3] = [5000.0, 0.0, 0.0]
    res = replace(robot, ik_via=_client(server.port)).ik(far, np.zeros(6))
    assert not res.success and "found no solution" in res.message and f":{server.port}" in res.message
    # raise_on_failure holds through the controller as for the local solver (it was ignored)
    from addon.core.errors import UnreachablePose

    with pytest.raises(UnreachablePose, match="found no solution"):
        replace(robot, ik_via=_client(server.port)).ik(far, np.zeros(6), raise_on_failure=True)


def test_a_failed_solve_through_the_bridge_keeps_the_solvers_reason_code(server):
    """The reason code came back out_of_reach for every failure (a hunt: a pose reachable
    only with J5 at 150°, outside the Viper's ±120°, is joint_limits locally): the server's
    answer carries the code and the client keeps it."""
    robot = load_robot("adept_viper_s650")
    wide = replace(robot, q_min_rad=np.full(6, -np.pi), q_max_rad=np.full(6, np.pi))
    q = np.radians([10.0, 40.0, -30.0, 20.0, 150.0, -10.0])
    assert not robot.within_limits(q) and wide.within_limits(q)
    T = wide.fk(q)
    local = robot.ik(T, np.zeros(6))
    remote = replace(robot, ik_via=_client(server.port)).ik(T, np.zeros(6))
    assert local.reason == "joint_limits" and not remote.success
    assert remote.reason == local.reason, remote.message


def test_a_controller_serving_another_robot_is_named_when_its_joints_miss(server):
    puma = load_robot("puma560")  # this cell's robot; the server solves for the Viper
    T = puma.fk(np.radians([10.0, -30.0, 20.0, 0.0, 40.0, 0.0]))
    res = replace(puma, ik_via=_client(server.port)).ik(T, np.zeros(6))
    assert not res.success, res.message
    assert f"serves the robot {load_robot('adept_viper_s650').name!r}" in res.message and puma.name in res.message


def test_nothing_listening_is_one_line_naming_host_and_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # a port nothing listens on once closed
    with pytest.raises(ControllerError, match=f"127.0.0.1:{port}: nothing is listening"):
        _client(port).ping()


def _serving(talk):
    """A server on loopback that runs ``talk(conn, stop)`` for each connection, until stopped."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen()
    stop = threading.Event()

    def serve():
        srv.settimeout(0.2)
        while not stop.is_set():
            try:
                conn, _ = srv.accept()
            except OSError:
                continue
            with conn:
                talk(conn, stop)

    threading.Thread(target=serve, daemon=True).start()
    return srv, stop


def _fake_server(reply):
    """A server that answers every line with ``reply(line)`` (None: never answers)."""
    def talk(conn, stop):
        buf = b""
        conn.settimeout(0.2)
        while not stop.is_set():
            try:
                chunk = conn.recv(4096)
            except OSError:
                continue
            if not chunk:
                break
            buf += chunk
            while b"\n" in buf:
                line, buf = buf.split(b"\n", 1)
                out = reply(json.loads(line))
                if out is not None:
                    conn.sendall(out)

    return _serving(talk)


@pytest.mark.parametrize("reply, message", [
    (lambda req: b"this is not json\n", "the answer is not JSON"),
    (lambda req: (json.dumps({"id": req["id"], "joints_rad": [0, 1], "success": True, "reason": "ok"}) + "\n")
     .encode(), "'joints_rad' must be 6 finite numbers"),
    (lambda req: (json.dumps({"id": req["id"]}) + "\n").encode(), "lacks 'success'"),
    (lambda req: None, "no answer within 0.3 s (on a retry over a new connection too)"),
    (lambda req: b"[" * 200_000 + b"\n", "the answer is not JSON"),  # nested deeper than any parser goes
    # Numbers Python's float cannot take (an integer of 400 digits; one past its 4 300-digit limit):
    # a traceback from the scan before.
    (lambda req: (json.dumps({"id": req["id"], "joints_rad": [10 ** 400, 0, 0, 0, 0, 0], "success": False,
                              "reason": "x"}) + "\n").encode(), "'joints_rad' must be 6 finite numbers"),
    (lambda req: b'{"id": ' + str(req["id"]).encode() + b', "success": true, "joints_rad": [' + b"9" * 5000
     + b', 0, 0, 0, 0, 0], "reason": ""}\n', "the answer is not JSON this client can read"),
    (lambda req: (json.dumps({"id": req["id"] + 1, "success": True, "reason": ""}) + "\n").encode(),
     "the answer is for request"),
])
def test_bad_answers_and_silence_are_one_line_naming_host_and_port(reply, message):
    srv, stop = _fake_server(reply)
    port = srv.getsockname()[1]
    robot = replace(load_robot("adept_viper_s650"), ik_via=_client(port, 0.3))
    try:
        with pytest.raises(ControllerError, match=re.escape(f"127.0.0.1:{port}") + ".*" + re.escape(message)):
            robot.ik(robot.fk(np.zeros(6)), np.zeros(6))
    finally:
        stop.set()
        srv.close()


def test_a_scan_planned_through_the_bridge_gets_the_local_joints(server, tmp_path):
    from addon.core.scan.plan import plan_scan

    text = open(load_scan_config("demo").source).read()
    f = tmp_path / "bridge.toml"
    f.write_text(text.replace('start_deg = [0.0, 30.0, -15.0, 0.0, 75.0, 90.0]   # the probe over the table, looking down (the Scanner starts here)',
                              'start_deg = [0.0, 30.0, -15.0, 0.0, 75.0, 90.0]\nik = "controller"\n'
                              f'[robot.controller]\nport = {server.port}\n'))
    bridged = load_scan_config(f).with_overrides(frames=slice(None, None, 6))
    local = load_scan_config("demo").with_overrides(frames=slice(None, None, 6))
    assert bridged.robot.ik_via is not None
    a, b = plan_scan(bridged), plan_scan(local)
    np.testing.assert_allclose(a.q, b.q, atol=1e-9)


def test_a_controller_that_trickles_an_answer_it_never_ends_times_out_as_silence():
    """A byte every 0.1 s and never a line's end: the 0.3 s are for the whole answer, not for
    each byte (a QA trial's fake controller held the scan for as long as it kept sending)."""
    import time

    def trickle(conn, stop):
        while not stop.is_set():
            try:
                conn.sendall(b" ")
            except OSError:
                break
            time.sleep(0.1)

    srv, stop = _serving(trickle)
    port = srv.getsockname()[1]
    robot = replace(load_robot("adept_viper_s650"), ik_via=_client(port, 0.3))
    t = time.monotonic()
    try:
        with pytest.raises(ControllerError, match="no answer within 0.3 s"):
            robot.ik(robot.fk(np.zeros(6)), np.zeros(6))
    finally:
        stop.set()
        srv.close()
    assert time.monotonic() - t < 5.0


@pytest.mark.parametrize("line, reason", [(b"\xff\xfe not text\n", "not UTF-8"),
                                          (b"[" * 200_000 + b"\n", "nested too deep"),
                                          (b"{not json\n", "not JSON"),
                                          (b'{"id": 1, "op": "ik", "target_mm": [[1' + b"0" * 400 + b', 0, 0, 0], '
                                           b'[0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], "seed_rad": [0, 0, 0, 0, 0, 0]}\n',
                                           "malformed request"),
                                          (b'{"id": 1' + b"0" * 5000 + b', "op": "ping"}\n', "too long to read")])
def test_the_server_answers_an_unreadable_request_and_goes_on(server, line, reason):
    with socket.create_connection(server.server_address, timeout=5.0) as conn:
        reader = conn.makefile("rb")
        conn.sendall(line)
        reply = json.loads(reader.readline())
        assert reply["success"] is False and reply["reason"].startswith("malformed request") and reason in reply["reason"]
        conn.sendall((json.dumps({"id": 7, "op": "ping"}) + "\n").encode())  # the same connection still serves
        assert json.loads(reader.readline())["id"] == 7


def test_the_server_refuses_a_line_past_its_limit_and_frees_the_connection(server):
    """A request line without end was kept in memory whole (150 MB held until its newline)."""
    from headless.ik_server import MAX_REQUEST_BYTES

    with socket.create_connection(server.server_address, timeout=10.0) as conn:
        reader = conn.makefile("rb")
        conn.sendall(b"x" * (MAX_REQUEST_BYTES + 10))
        reply = json.loads(reader.readline())
        assert reply["success"] is False and "longer than" in reply["reason"]
        assert reader.readline() == b""  # the connection is closed: the rest cannot be told from a request


def test_ik_server_serves_a_configs_urdf_robot_with_its_tool_link(tmp_path):
    """ik-server took only --robot: a config's URDF arm with tool_link (or base_link,
    package_dirs) could not be served, and every solve through it missed by the links
    between (a hunt: 80 mm). --config serves the config's own chain."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[2]
    text = (repo / "rigs" / "scenes" / "ur5_urdf.toml").read_text()
    text = text.replace('urdf = "../robots/urdf/ur5.urdf"', f'urdf = "{repo}/rigs/robots/urdf/ur5.urdf"\n'
                                                           'tool_link = "wrist_3_link"')
    config = tmp_path / "ur5_wrist.toml"
    config.write_text(text)
    robot = load_scan_config(config).robot
    proc = subprocess.Popen([sys.executable, "-m", "headless", "ik-server", "--config", str(config), "--port", "0"],
                            cwd=repo, env={**os.environ, "PYTHONPATH": str(repo)}, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        port = int(re.search(r":(\d+) \(protocol", line).group(1))
        remote = replace(robot, ik_via=_client(port, timeout=10.0))
        q = np.radians([10.0, -70.0, 80.0, -100.0, -80.0, 20.0])
        res = remote.ik(robot.fk(q), q + 0.05)
        assert res.success, res.message
    finally:
        proc.terminate()
        proc.wait(timeout=30)
    both = subprocess.run([sys.executable, "-m", "headless", "ik-server", "--config", str(config), "--robot", "ur5"],
                          cwd=repo, env={**os.environ, "PYTHONPATH": str(repo)}, capture_output=True, text=True,
                          timeout=120)
    assert both.returncode == 2 and "not both" in both.stderr and "Traceback" not in both.stderr
