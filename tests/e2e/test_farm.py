"""Sharded scans on a local Dask cluster: the same cloud as one process, whatever happens."""

import json
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from addon.core.config.scan import load_scan_config
from addon.core.errors import InputError
from addon.pipeline import run_scan
from headless import farm

pytest.importorskip("distributed", reason="the farm needs dask.distributed (installed by the README's set-up)")


@pytest.fixture(scope="module")
def config():
    return load_scan_config("step_block").with_overrides(frames=slice(None, None, 5))  # 20 frames


@pytest.fixture(scope="module")
def single(config):
    return run_scan(config, None, write_outputs=False)


def same_cloud(a, b):
    for name in ("points", "frame", "camera", "quality"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_two_workers_give_the_single_process_cloud_on_loopback_only(config, single, tmp_path):
    lines = []
    res = farm.run_farm(config, tmp_path / "out", workers=2, shard_frames=5, log=lines.append)
    same_cloud(res.cloud, single.cloud)
    f = res.report["farm"]
    assert (f["shards"], f["computed"], f["reused"], f["workers"]) == (4, 4, 0, 2)
    assert f["scheduler"].startswith("tcp://127.0.0.1:")
    assert len(f["worker_addresses"]) == 2 and all(a.startswith("tcp://127.0.0.1:") for a in f["worker_addresses"])
    assert res.report["column_codes"] == single.report["column_codes"]
    assert res.report["error_um"] == single.report["error_um"]
    # The Blender that rendered the shards is the workers', named as one process names its own.
    assert res.report["software"]["blender"] == single.report["software"]["blender"]
    assert {p.name for p in (tmp_path / "out").iterdir()} == {"cloud.ply", "report.json", "preview.png", "shards"}
    assert any("cell reused" in line for line in lines)  # a worker kept its scene between shards


def test_the_raycast_engine_on_the_farm_gives_its_single_process_cloud(config, tmp_path):
    rc = config.with_overrides(engine="raycast")
    alone = run_scan(rc, None, write_outputs=False)
    lines = []
    res = farm.run_farm(rc, tmp_path / "out", workers=2, shard_frames=5, log=lines.append)
    same_cloud(res.cloud, alone.cloud)
    assert res.report["points_fused"] == alone.report["points_fused"] > 0  # the shards carry their counters
    assert res.report["render_device"] == alone.report["render_device"] == "CPU (Embree ray casting)"
    assert any("cell reused" in line for line in lines)  # a worker kept its ray-cast scene between shards


def test_frames_from_one_path_entry_report_that_entrys_clearance_on_the_farm_and_alone(tmp_path):
    """--frames 150:154 picks the demo's sweep (path entry 1): one process and the farm both key
    its clearance by that entry (one process renumbered it 0)."""
    rc = load_scan_config("demo").with_overrides(engine="raycast", frames=slice(150, 154))
    alone = run_scan(rc, None, write_outputs=False)
    res = farm.run_farm(rc, tmp_path / "out", workers=1, shard_frames=2, log=lambda m: None)
    assert set(alone.report["clearance"]["per_path"]) == set(res.report["clearance"]["per_path"]) == {"1"}
    assert alone.report["clearance"]["per_path"] == res.report["clearance"]["per_path"]


def test_the_farm_commands_log_goes_to_stderr_and_stdout_keeps_the_summary(tmp_path):
    """A farm scan's running log (its shards, its cluster) is progress: on stderr, so that stdout
    piped on holds the results alone, as a one-process scan's does."""
    import subprocess
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[2]
    run = subprocess.run([sys.executable, "-m", "headless", "scan", "demo", "--engine", "raycast", "--frames", "0:6",
                          "--workers", "1", "--shard-frames", "3", "--out", str(tmp_path / "out")],
                         cwd=repo, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "farm: 6 frames in 2 shards" in run.stderr and "shard 1 done" in run.stderr
    assert "farm:" not in run.stdout and "shard" not in run.stdout.split("points")[0]
    assert run.stdout.lstrip().startswith("scan:") and "Port 8787" not in run.stderr


def _cli(*args, env=None):
    import subprocess
    import sys
    from pathlib import Path

    return subprocess.run([sys.executable, "-m", "headless", *args], cwd=Path(__file__).resolve().parents[2],
                          capture_output=True, text=True, env=env, timeout=300)


def test_a_scheduler_port_that_accepts_and_stays_silent_is_refused_not_waited_on(tmp_path):
    """A stopped scheduler (or another program) accepts connections and never answers: Dask's
    own handshake would wait for ever; the command refuses it in one line."""
    import socket
    import threading
    import time

    server = socket.create_server(("127.0.0.1", 0))
    held = []
    threading.Thread(target=lambda: [held.append(server.accept()) for _ in range(8)], daemon=True).start()
    port = server.getsockname()[1]
    t = time.monotonic()
    out = _cli("scan", "demo", "--engine", "raycast", "--frames", "0:4", "--scheduler", f"tcp://127.0.0.1:{port}",
               "--out", str(tmp_path / "out"))
    assert time.monotonic() - t < 60
    assert out.returncode == 2 and "Traceback" not in out.stderr, out.stderr[-2000:]
    assert "something accepts connections there but no Dask scheduler answered" in out.stderr.splitlines()[-1]
    assert not (tmp_path / "out").exists()
    server.close()


@contextmanager
def scheduler_and_worker(cwd, env, procs_out: list | None = None):
    """A Dask scheduler and one worker started as separate processes in ``cwd`` with ``env``
    (as on a cluster), stopped on leaving; yields the scheduler's address (and puts the two
    processes in ``procs_out``, where given)."""
    import socket
    import subprocess
    import sys
    import time

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    dask = str(Path(sys.executable).with_name("dask"))
    address = f"tcp://127.0.0.1:{port}"
    quiet = dict(cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                              **quiet)]
    try:
        time.sleep(3)
        procs.append(subprocess.Popen([dask, "worker", address, "--nthreads", "1", "--no-dashboard"], **quiet))
        time.sleep(4)
        if procs_out is not None:
            procs_out.extend(procs)
        yield address
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            p.wait(timeout=30)


def test_a_scheduler_that_stops_during_the_scan_is_one_line(tmp_path):
    """The scheduler killed after the first shard: the cancelled shards were taken for a dead
    worker's and the scan ended in a KeyError's traceback, exit 1 (a hunt, 4 runs in 5). A
    cluster gone is no fault of the scan: exit 75, try again later, as for a busy folder."""
    import os
    import subprocess
    import sys

    repo = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONPATH": str(repo)}
    procs = []
    with scheduler_and_worker(tmp_path, env, procs) as address:
        scan = subprocess.Popen([sys.executable, "-m", "headless", "scan", "demo", "--engine", "raycast", "--frames",
                                 "0:60", "--shard-frames", "5", "--scheduler", address, "--out", str(tmp_path / "out")],
                                cwd=repo, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        lines = []
        for line in scan.stderr:
            lines.append(line)
            if "shard 0 done" in line:
                procs[0].kill()
                break
        lines += scan.stderr.readlines()
        assert scan.wait(timeout=300) == 75, "".join(lines)[-2000:]
    err = "".join(lines)
    assert "Traceback" not in err and "stopped answering" in err, err[-2000:]


def test_a_cluster_that_cannot_import_the_scanner_is_named_in_one_line(tmp_path):
    """A scheduler and a worker started away from the repository without it on PYTHONPATH (as
    docs/farm.md warns): one line naming PYTHONPATH, exit 2, nothing written."""
    import os

    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    with scheduler_and_worker(tmp_path, env) as address:
        out = _cli("scan", "demo", "--engine", "raycast", "--frames", "0:4", "--scheduler", address,
                   "--out", str(tmp_path / "out"))
    assert out.returncode == 2 and "Traceback" not in out.stderr, out.stderr[-2000:]
    last = out.stderr.strip().splitlines()[-1]
    assert "cannot load the scanner's code" in last and "PYTHONPATH=" in last, last
    assert not (tmp_path / "out" / "cloud.ply").exists()


def test_a_relative_out_folder_names_the_same_folder_for_workers_started_elsewhere(tmp_path):
    """A scheduler's workers run in folders of their own (a docs trial: given --out out/cluster,
    they wrote the shards under their own folder, none came back, and the merge failed with a
    traceback): the shards' folder is made absolute before the shards go out."""
    import os
    import subprocess
    import sys

    repo = Path(__file__).resolve().parents[2]
    here, there = tmp_path / "here", tmp_path / "there"
    here.mkdir()
    there.mkdir()
    env = {**os.environ, "PYTHONPATH": str(repo)}
    with scheduler_and_worker(there, env) as address:
        out = subprocess.run([sys.executable, "-m", "headless", "scan", "demo", "--engine", "raycast", "--frames",
                              "0:8", "--shard-frames", "4", "--scheduler", address, "--out", "out/cluster"],
                             cwd=here, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert (here / "out" / "cluster" / "cloud.ply").exists() and len(list((here / "out" / "cluster" / "shards")
                                                                          .iterdir())) == 2
    assert not (there / "out").exists()


def test_a_local_cluster_starts_no_more_workers_than_shards(config, tmp_path):
    lines = []
    res = farm.run_farm(config.with_overrides(engine="raycast"), tmp_path / "out", workers=6, shard_frames=10,
                        log=lines.append)
    assert res.report["farm"]["shards"] == 2 and res.report["farm"]["workers"] == 2
    assert len(res.report["farm"]["worker_addresses"]) == 2 and any("2 workers" in line for line in lines)


def test_the_workers_a_local_scan_starts_are_no_more_than_its_shards():
    assert farm.local_workers(8, 8, None) == 2  # 4 frames a shard at least: 2 shards
    assert farm.local_workers(180, 2, None) == 2 and farm.local_workers(180, 64, 24) == 8
    assert farm.local_workers(180, 3, 1000) == 1


def test_a_cluster_lacking_a_package_or_the_code_is_told_which_and_a_local_one_is_not(monkeypatch):
    """Which import failed decides the line: the tool's own code (PYTHONPATH), another package
    (the project's set-up); a local cluster's workers import what this process does, so its
    failure is no set-up matter and is raised as it is."""
    from addon.core.errors import ScannerError

    def failing(name):
        def run(*args, **kwargs):
            raise Exception(f"ModuleNotFoundError(\"No module named '{name}'\")")
        return run

    for name, words in (("addon", "PYTHONPATH="), ("cv2.typing", "lacks the package 'cv2'")):
        monkeypatch.setattr(farm, "_run_on_cluster", failing(name))
        with pytest.raises(ScannerError, match=words):
            farm._compute_shards(None, None, [], None, "", None, 1, "tcp://127.0.0.1:1", None, None, None)
    monkeypatch.setattr(farm, "_run_on_cluster", failing("addon"))
    with pytest.raises(Exception, match="No module named 'addon'"):
        farm._compute_shards(None, None, [], None, "", None, 1, None, None, None, None)


def test_shard_task_keys_are_this_runs_and_a_worker_runs_one_shard_at_a_time(tmp_path, monkeypatch):
    """Two scans of one config on one scheduler into two folders shared task keys (Dask gave one
    scan's shards to the other, whose folder then lacked them); a worker with two threads ran
    two Cycles shards in one Blender at once, which crashed it."""
    import threading

    key = farm.shard_key("f" * 40, tmp_path / "a" / "shards", "pid 1 on host", 3, 0)
    assert key == farm.shard_key("f" * 40, tmp_path / "a" / "shards", "pid 1 on host", 3, 0)
    others = {farm.shard_key("f" * 40, tmp_path / "b" / "shards", "pid 1 on host", 3, 0),
              farm.shard_key("f" * 40, tmp_path / "a" / "shards", "pid 2 on host", 3, 0),
              farm.shard_key("f" * 40, tmp_path / "a" / "shards", "pid 1 on host", 4, 0),
              farm.shard_key("f" * 40, tmp_path / "a" / "shards", "pid 1 on host", 3, 1),
              farm.shard_key("e" * 40, tmp_path / "a" / "shards", "pid 1 on host", 3, 0)}
    assert key not in others and len(others) == 5

    inside, most = [0], [0]
    gate = threading.Lock()

    def slow(*args):
        with gate:
            inside[0] += 1
            most[0] = max(most[0], inside[0])
        threading.Event().wait(0.2)
        with gate:
            inside[0] -= 1
        return {}

    monkeypatch.setattr(farm, "_run_shard", slow)
    threads = [threading.Thread(target=farm.run_shard, args=(None, None, None, "", "")) for _ in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert most[0] == 1


def test_the_memory_check_counts_a_frame_and_a_blender_process_per_local_worker():
    from headless.preflight import WORKER_PROCESS_BYTES, RenderBudget, check_render_size

    budget = RenderBudget(1000, 1000, 100, 2, 1, 8)  # 100 MB a frame
    check_render_size(budget, memory=250_000_000, workers=1)
    room = 2 * (100_000_000 + WORKER_PROCESS_BYTES)
    check_render_size(budget, memory=room, workers=2)
    with pytest.raises(InputError, match=r"3 local workers, each a Blender process .* rendering a 1000x1000 frame "
                                         r"at once, need about 1.8 GB"):
        check_render_size(budget, memory=room, workers=3)


def test_with_motion_blur_a_shard_scans_its_frames_as_the_whole_path_does():
    """Motion blur samples the path around each frame; Cycles' samples also depend on the
    frame's number in Blender. A shard keyed from Blender frame 1 gave its frames up to 0.86 µm
    away from the whole path's (a farm user's trial); keyed at the path's own frame numbers,
    a shard's frames are the whole path's, bit for bit."""
    from addon.pipeline import ScanRun

    cfg = load_scan_config("cylinder_realistic").with_overrides(frames=slice(0, 6))
    assert cfg.sensor.motion_blur and cfg.render.engine == "cycles"

    def raw(frames=None):
        run = ScanRun(cfg, frames=frames)
        while not run.step():
            pass
        return run.acc.cloud()

    whole, shard = raw(), raw(range(3, 6))
    mine = whole.frame >= 3
    assert mine.sum() > 50 and len(shard) == mine.sum()
    for name in ("points", "frame", "camera", "quality"):
        np.testing.assert_array_equal(getattr(shard, name), getattr(whole, name)[mine])


def test_with_a_realistic_sensor_a_shard_reads_its_frames_as_the_whole_path_does():
    """The realistic sensor (noise, defocus, lens distortion) on frames 8-11 of 12: the whole
    path renders them in a band 57 rows high (the band follows the line from frame 0), a shard
    that starts at frame 8 in one of 55, and the sensor's image of a row depended on the band
    around it (defocus levels from the band's rows, distortion's dark fill beyond it): 114 of
    350 points of a farmed scan differed. Each frame is read on its own rows now."""
    from addon.pipeline import ScanRun

    cfg = load_scan_config("cylinder_realistic").with_overrides(frames=slice(0, 12))
    assert cfg.sensor.defocus and cfg.sensor.distortion and cfg.sensor.noise and cfg.leave_out.render_band

    def raw(frames=None):
        run = ScanRun(cfg, frames=frames)
        while not run.step():
            pass
        return run, run.acc.cloud()

    (whole_run, whole), (shard_run, shard) = raw(), raw(range(8, 12))
    mine = whole.frame >= 8
    assert mine.sum() > 50 and len(shard) == mine.sum()
    for name in ("points", "frame", "camera", "quality"):
        np.testing.assert_array_equal(getattr(shard, name), getattr(whole, name)[mine])


def test_a_shard_that_finishes_after_its_scan_stopped_writes_nothing(config, tmp_path):
    """A cluster cannot stop a task that is running: a shard still rendering when its scan is
    stopped finishes later, and the output folder is no longer the scan's. It writes only
    while the lock it was started under still stands."""
    from addon.core.files import OutputLock
    from addon.pipeline import plan_scan

    rc = config.with_overrides(engine="raycast")
    plan = plan_scan(rc)
    shard = farm.shards.split(len(plan.q), 5)[1]
    out = tmp_path / "out"
    with OutputLock(out):
        owner = farm.lock_holder(out)
        path = out / "shards" / shard.file_name()
        assert owner and farm.run_shard(rc, plan, shard, str(path), "fp", owner=owner)["written"] and path.exists()
        path.unlink()
    info = farm.run_shard(rc, plan, shard, str(path), "fp", owner=owner)  # the scan stopped: its lock is gone
    assert not info["written"] and info["points"] > 0 and not path.exists()
    with OutputLock(out):  # another scan's now (another process would say so: another pid)
        (out / ".scanner.lock").write_text("1 elsewhere\n")
        assert not farm.run_shard(rc, plan, shard, str(path), "fp", owner=owner)["written"]
        assert not path.exists()


def die_in_shard(index: int, marker: str):
    """A Dask worker plugin (the fault is the test's, not the farm's), defined here so that it
    travels to the workers by value: the worker that starts shard ``index`` dies after the
    shard's first chunk, once (``marker`` records it)."""
    from dask.distributed import WorkerPlugin

    class DieInShard(WorkerPlugin):
        def __init__(self, index: int, marker: str):
            self.index, self.marker = index, marker

        def setup(self, worker):
            import os
            from pathlib import Path

            from addon import pipeline
            from headless import farm as worker_farm

            run_shard, step = worker_farm.run_shard, pipeline.ScanRun.step
            armed = {"now": False}

            def doomed_run_shard(config, plan, shard, *args, **kwargs):
                armed["now"] = shard.index == self.index and not Path(self.marker).exists()
                return run_shard(config, plan, shard, *args, **kwargs)

            def doomed_step(run):
                done = step(run)
                if armed["now"]:
                    Path(self.marker).write_text(f"worker {os.getpid()} died in shard {self.index}\n")
                    os._exit(17)
                return done

            worker_farm.run_shard, pipeline.ScanRun.step = doomed_run_shard, doomed_step

    return DieInShard(index, marker)


def test_a_worker_killed_mid_shard_loses_nothing(config, single, tmp_path):
    from dask.distributed import Client, LocalCluster

    marker = tmp_path / "died.txt"
    with LocalCluster(n_workers=2, threads_per_worker=1, host="127.0.0.1", dashboard_address=None) as cluster, \
            Client(cluster) as client:
        client.register_plugin(die_in_shard(1, str(marker)), name="die-in-shard-1")
        res = farm.run_farm(config, tmp_path / "out", scheduler=cluster.scheduler_address, shard_frames=5,
                            log=lambda m: None, render_threads=1)
    assert marker.exists(), "the fault was not injected"
    same_cloud(res.cloud, single.cloud)  # nothing lost, nothing twice
    assert res.report["farm"]["computed"] == 4


def blind_to_the_folder():
    """A Dask worker plugin: the workers see no lock in the output folder, as a worker on
    another machine without the shared disk would see its own empty folder at that path."""
    from dask.distributed import WorkerPlugin

    class Blind(WorkerPlugin):
        def setup(self, worker):
            from headless import farm as worker_farm

            worker_farm.lock_holder = lambda folder: None

    return Blind()


def test_workers_that_cannot_see_the_output_folder_are_named_in_one_line(config, tmp_path):
    from dask.distributed import Client, LocalCluster

    from addon.core.errors import ScannerError
    from addon.core.files import OutputLock

    with LocalCluster(n_workers=1, threads_per_worker=1, host="127.0.0.1", dashboard_address=None) as cluster, \
            Client(cluster) as client, OutputLock(tmp_path / "out"):  # held as the command holds it
        client.register_plugin(blind_to_the_folder(), name="blind")
        with pytest.raises(ScannerError, match="cannot see the output folder .*a disk every worker shares"):
            farm.run_farm(config.with_overrides(engine="raycast"), tmp_path / "out", scheduler=cluster.scheduler_address,
                          shard_frames=10, log=lambda m: None, render_threads=1)
    assert not (tmp_path / "out" / "cloud.ply").exists()


def test_damaged_shards_are_found_and_recomputed(config, single, tmp_path):
    out = tmp_path / "out"
    farm.run_farm(config, out, workers=1, shard_frames=5, log=lambda m: None)
    files = sorted((out / "shards").iterdir())
    assert len(files) == 4
    files[0].write_bytes(files[0].read_bytes()[:200])                      # truncated
    data = bytearray(files[2].read_bytes())
    data[len(data) // 2] ^= 0xFF                                           # one byte flipped
    files[2].write_bytes(bytes(data))
    files[3].unlink()                                                      # missing
    lines = []
    res = farm.run_farm(config, out, workers=1, shard_frames=5, log=lines.append)
    text = "\n".join(lines)
    assert "1 valid from an earlier run (skipped), 3 to compute" in text
    assert "recomputing shard 0 (frames 0-4): unreadable" in text
    assert "recomputing shard 2 (frames 10-14)" in text
    assert "computing shard 3 (frames 15-19): missing" in text
    same_cloud(res.cloud, single.cloud)
    # The farm's rate counts the 15 frames computed, not the 5 reused (which took no time).
    f = res.report["farm"]
    assert f["profiles_per_s_wall"] == pytest.approx(15 / f["wall_s"], rel=1e-3)
    # Everything valid now: a third run computes nothing and starts no cluster; a shard file of
    # another split (another --shard-frames) is named, not read and not removed.
    (out / "shards" / "shard_000000_000009.npz").write_bytes(b"another split")
    lines = []
    again = farm.run_farm(config, out, workers=1, shard_frames=5, log=lines.append)
    assert "4 valid from an earlier run (skipped), 0 to compute" in lines[0]
    assert any("1 shard file in" in line and "shard_000000_000009.npz" in line for line in lines)
    assert (out / "shards" / "shard_000000_000009.npz").exists()
    assert again.report["farm"]["scheduler"] is None
    same_cloud(again.cloud, single.cloud)


def test_a_farm_manager_can_run_one_shard_per_task_then_merge(single, tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    from addon.core.geometry.cloud import load_ply

    repo = Path(__file__).resolve().parents[2]
    out = tmp_path / "job"
    base = [sys.executable, "-m", "headless", "scan", "step_block", "--frames", "::5", "--out", str(out),
            "--shard-frames", "10", "--quiet"]
    early = subprocess.run(base + ["--merge"], cwd=repo, capture_output=True, text=True)
    assert early.returncode == 2 and "2 of 2 shards are not ready" in early.stderr, early.stderr
    for k in (1, 0):  # tasks may run in any order
        # (shard 1 without --quiet: a task shows its progress, as a scan does; it printed none)
        task = subprocess.run(base[:-1] + ["--shard", str(k)] + (["--quiet"] if k == 0 else []), cwd=repo,
                              capture_output=True, text=True)
        assert task.returncode == 0, task.stderr[-2000:]
        assert f"shard {k} (frames {10 * k}-{10 * k + 9}) of 2" in task.stdout
        assert ("/10 frames" in task.stderr and "(100 %)" in task.stderr) if k == 1 else "frames" not in task.stderr, \
            task.stderr
    merged = subprocess.run(base + ["--merge"], cwd=repo, capture_output=True, text=True)
    assert merged.returncode == 0, merged.stderr[-2000:]
    cloud = load_ply(out / "cloud.ply")
    np.testing.assert_allclose(cloud.points, single.cloud.points, atol=1e-4)  # PLY holds float32
    report = json.loads((out / "report.json").read_text())
    assert report["farm"]["workers"] is None and report["farm"]["computed"] == 0  # the merge ran no worker
    assert report["software"]["blender"] == single.report["software"]["blender"]  # the tasks' Blender
    np.testing.assert_array_equal(cloud.frame, single.cloud.frame)
    # Merging with another split than the shards were made with names what is there.
    other = [a if a != "10" else "8" for a in base]
    wrong = subprocess.run(other + ["--merge"], cwd=repo, capture_output=True, text=True)
    assert wrong.returncode == 2 and "2 shard files of another split" in wrong.stderr \
        and "--shard-frames they were made with" in wrong.stderr, wrong.stderr


def cancel_shard_once(index: int, marker: str):
    """A Dask worker plugin: the first task of shard ``index`` cancels itself through the
    client, as the scheduler does when a dying worker takes the shard's scattered inputs
    with it (``marker`` records it)."""
    from dask.distributed import WorkerPlugin

    class CancelShard(WorkerPlugin):
        def __init__(self, index: int, marker: str):
            self.index, self.marker = index, marker

        def setup(self, worker):
            import time
            from pathlib import Path

            from headless import farm as worker_farm

            run_shard = worker_farm.run_shard
            plugin = self

            def cancelled_run_shard(config, plan, shard, *args, **kwargs):
                from dask.distributed import Future, get_client, get_worker

                if shard.index == plugin.index and not Path(plugin.marker).exists():
                    Path(plugin.marker).write_text(f"shard {shard.index} cancelled\n")
                    client = get_client()
                    client.cancel([Future(get_worker().get_current_task(), client)], force=True)
                    time.sleep(2.0)
                return run_shard(config, plan, shard, *args, **kwargs)

            worker_farm.run_shard = cancelled_run_shard

    return CancelShard(index, marker)


def test_a_shard_the_cluster_cancels_is_submitted_again(config, single, tmp_path):
    from dask.distributed import Client, LocalCluster

    marker = tmp_path / "cancelled.txt"
    lines = []
    with LocalCluster(n_workers=2, threads_per_worker=1, host="127.0.0.1", dashboard_address=None) as cluster, \
            Client(cluster) as client:
        client.register_plugin(cancel_shard_once(2, str(marker)), name="cancel-shard-2")
        res = farm.run_farm(config, tmp_path / "out", scheduler=cluster.scheduler_address, shard_frames=5,
                            log=lines.append, render_threads=1)
    assert marker.exists(), "the cancellation was not injected"
    assert any("cancelled by the cluster" in line for line in lines), lines
    same_cloud(res.cloud, single.cloud)
    assert res.report["farm"]["computed"] == 4


def always_die_in_shard(index: int):
    """A Dask worker plugin: a worker that starts shard ``index`` dies at once (os._exit), as
    one the out-of-memory killer takes every time would."""
    from dask.distributed import WorkerPlugin

    class DieInShard(WorkerPlugin):
        def __init__(self, index: int):
            self.index = index

        def setup(self, worker):
            import os

            from headless import farm as worker_farm

            run_shard = worker_farm.run_shard
            plugin = self

            def dying_run_shard(config, plan, shard, *args, **kwargs):
                if shard.index == plugin.index:
                    os._exit(9)
                return run_shard(config, plan, shard, *args, **kwargs)

            worker_farm.run_shard = dying_run_shard

    return DieInShard(index)


def test_workers_that_keep_dying_end_the_scan_in_one_line_and_keep_the_shards_finished(tmp_path):
    """Shard 1 kills every worker that takes it: the command ends with one line, exit 2 (it
    ended in a traceback: the cancellation raised from inside result(), or the scatter to a
    worker already gone), and nothing merged. (The scan sent again after a death, to workers
    gone meanwhile, stays 2: a cluster gone at the start is 75, try again later.)"""
    import re
    import subprocess
    import sys

    from dask.distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, host="127.0.0.1", dashboard_address=None,
                      silence_logs=50) as cluster, Client(cluster) as client:
        client.register_plugin(always_die_in_shard(1), name="always-die-in-shard-1")
        out = subprocess.run([sys.executable, "-m", "headless", "scan", "step_block", "--engine", "raycast",
                              "--frames", "::5", "--scheduler", cluster.scheduler_address, "--shard-frames", "5",
                              "--out", str(tmp_path / "out"), "--quiet"],
                             cwd=Path(__file__).resolve().parents[2], capture_output=True, text=True, timeout=600)
    assert out.returncode == 2 and "Traceback" not in out.stderr and "distributed." not in out.stderr, \
        out.stderr[-3000:]
    (line,) = [ln for ln in out.stderr.splitlines() if ln.startswith("error:")]
    # (the shard named is the one whose retries ran out: shard 1, or one whose inputs went
    # down with a worker that died in shard 1)
    assert re.search(r"shard \d \(frames|workers of the scheduler", line), line
    assert not (tmp_path / "out" / "cloud.ply").exists()


def test_the_time_check_counts_the_frames_rendered_here(tmp_path):
    """A farm task renders its shard, a merge nothing, a scheduler's workers elsewhere: the
    8-hour check counts those (it counted the whole path, and refused a job's 4-frame task as
    10 h unless --force)."""
    from headless.preflight import check_scan

    big = load_scan_config("demo").with_overrides(resolution=(1280, 1024), samples=32)
    with pytest.raises(InputError, match="more than 8 h"):
        check_scan(big, tmp_path / "a", farm=True)
    check_scan(big, tmp_path / "b", farm=True, frames=4)
    check_scan(big, tmp_path / "c", farm=True, frames=0)


def test_a_shard_changed_before_the_merge_is_named_in_one_line(config, tmp_path):
    # (A --shard task of another scan wrote over it, or it was removed: ShardInvalid came out
    # as a traceback.)
    from addon.core.errors import ScannerError

    out = tmp_path / "out"

    def spoil():
        next((out / "shards").glob("shard_*.npz")).unlink()

    with pytest.raises(ScannerError, match=r"shard \d \(frames .*changed after it was computed.*nothing merged"):
        farm.run_farm(config, out, workers=1, shard_frames=10, log=lambda m: None, render_threads=1,
                      measured=spoil)
    assert not (out / "cloud.ply").exists()


def test_a_shards_folder_that_cannot_be_written_is_refused_before_the_cluster_starts(tmp_path):
    from headless.preflight import check_scan

    out = tmp_path / "out"
    out.mkdir()
    (out / "shards").symlink_to("/proc")  # a folder nobody may make files in
    with pytest.raises(InputError, match="shards folder.*cannot be written"):
        check_scan(load_scan_config("demo"), out, farm=True)


def test_a_scheduler_without_workers_waits_for_one_to_join(config, single, tmp_path, monkeypatch):
    # (The log said the shards would wait; Dask's scatter gave up after 30 s: "No valid workers found".)
    import threading

    from dask.distributed import LocalCluster

    monkeypatch.setattr(farm, "WORKER_WAIT_S", 120.0)
    lines = []
    with LocalCluster(n_workers=0, threads_per_worker=1, host="127.0.0.1", dashboard_address=None,
                      silence_logs=50) as cluster:
        joins = threading.Timer(3.0, lambda: cluster.scale(1))
        joins.start()
        try:
            res = farm.run_farm(config, tmp_path / "out", scheduler=cluster.scheduler_address, shard_frames=10,
                                log=lines.append, render_threads=1)
        finally:
            joins.cancel()
    assert any("none yet" in line for line in lines), lines
    same_cloud(res.cloud, single.cloud)
    # The report counts the worker that joined and computed the shards (0 and [] before: read
    # before the wait).
    assert res.report["farm"]["workers"] == 1 and len(res.report["farm"]["worker_addresses"]) == 1


def test_a_run_resumed_with_other_workers_keeps_the_earlier_split_and_its_shards(config, single, tmp_path):
    """The split follows --workers: a stopped --workers 3 run resumed with --workers 2 read
    its finished shards as another split's and recomputed everything (a hunt)."""
    raycast = config.with_overrides(engine="raycast")
    out = tmp_path / "out"
    first = farm.run_farm(raycast, out, workers=1, log=lambda m: None)  # 20 frames: 4 shards of 5
    made = sorted((out / "shards").glob("shard_*.npz"))
    assert len(made) == 4
    made[0].unlink()  # as if stopped before the first shard finished (the split read from the others)
    lines = []
    res = farm.run_farm(raycast, out, workers=2, log=lines.append)  # would split into 4s
    assert any("keeping the split" in line for line in lines), lines
    assert res.report["farm"]["shard_frames"] == 5 and res.report["farm"]["computed"] == 1, res.report["farm"]
    assert res.report["farm"]["reused"] == 3
    same_cloud(res.cloud, first.cloud)
