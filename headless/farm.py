"""Sharded scans on Dask distributed: a local cluster by default, or any running scheduler.

The coordinator (this process) plans the whole path once (so every refusal comes
before anything starts), cuts it into shards by frame range and sends each shard
to a worker. A worker process imports bpy once, builds the cell once per scan and
reuses it for every shard it gets; each shard renders, detects and triangulates
its frames and writes one checksummed shard file (addon.core.scan.shards) atomically.
When all shards are there, the coordinator checks and merges them into the
cloud, the report and the preview, exactly as a single process would.

Shard files stay in ``<out>/shards``: running the same scan again skips the valid
ones and computes only what is missing, truncated, altered or from another
config, and says which. A worker that dies mid-shard leaves no file; Dask
reschedules its shard on another worker.

Local clusters listen on 127.0.0.1 only. Each of their N worker processes runs one
task at a time (bpy is process-global) and renders with cores / N threads.
"""

from __future__ import annotations

import hashlib
import logging
import os
import re
import shlex
import tempfile
import threading
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Callable

from addon.core.scan import shards
from addon.core.errors import InputError, ScannerError, TemporaryFailure, check_whole
from addon.core.machine import usable_cpus

# Times a shard is submitted again after the cluster cancels it (its scattered inputs lost
# with a dying worker) before the farm gives up.
SHARD_RETRIES = 3
MAX_WORKERS = 1024  # --workers at most

# A worker process's cell, kept between shards of the same scan: {fingerprint: SceneCell}.
_WORKER_CELL: dict = {}
# One shard at a time in a worker process: a worker started with more than one thread (Dask's
# default on a many-core node) ran two Cycles shards in one Blender, which crashed it (signal
# 11, again and again, and the scan ended blaming dying workers).
_SHARD_LOCK = threading.Lock()


def scan_fingerprint(config, plan) -> str:
    """What decides the scan's result: the plan and the whole config, field by field (every
    field of ScanConfig counts but its name, file and description), and this simulator's
    release (shards another release made are computed again, not merged with this one's)."""
    from addon.core.scan.outputs import simulator_version

    return shards.fingerprint([shards.FORMAT, simulator_version(), plan.q, plan.table_rad, plan.predicted_rows,
                               tuple(plan.cameras), config, config.detect_params])


def _clean_sys_path() -> None:
    """A worker started by a process that had imported bpy inherits Blender's script folders
    on sys.path, where a ``bpy`` package that only works inside Blender would shadow the bpy
    module; drop them until the real bpy is imported (it puts them back itself)."""
    import sys

    if "bpy" not in sys.modules:
        sys.path[:] = [p for p in sys.path if "/scripts/" not in p.replace("\\", "/") or "bpy" not in p]


def run_shard(config, plan, shard: shards.Shard, path: str, fingerprint: str, threads: int | None = None,
              owner: str | None = None, progress=None) -> dict:
    """On a worker: scan the shard's frames and write its file. Returns a short summary.
    ``owner``: the output folder's lock as the scan that asked for the shard holds it; a shard
    that finishes once that scan has stopped (the lock gone, or another scan's) writes
    nothing: a cluster cannot stop a task that is running, and the folder is no longer its."""
    with _SHARD_LOCK:
        return _run_shard(config, plan, shard, path, fingerprint, threads, owner, progress)


def _run_shard(config, plan, shard: shards.Shard, path: str, fingerprint: str, threads: int | None,
               owner: str | None, progress=None) -> dict:
    _clean_sys_path()
    from addon.core.scan.outputs import blender_version
    from addon.pipeline import ScanRun

    t = time.perf_counter()
    cell = _WORKER_CELL.get(fingerprint)  # (Blender cell, raycast renderer) built for an earlier shard
    run = ScanRun(config, progress=progress, plan=plan, frames=shard.frames, threads=threads,
                  scene_cell=None if cell is None else cell[0], raycaster=None if cell is None else cell[1])
    _WORKER_CELL.clear()
    _WORKER_CELL[fingerprint] = (run.scene_cell, run.raycaster)
    while not run.step():
        pass
    run.timing.update(run.stage_times())
    cloud = run.acc.cloud()
    written = owner is None or lock_holder(Path(path).parent.parent) == owner
    if written:
        shards.write(path, shard, cloud, run.stats, run.timing, fingerprint, run.render_device,
                     blender_version() if run.raycaster is None else None)
    return {"shard": shard.index, "points": len(cloud), "seconds": time.perf_counter() - t, "pid": os.getpid(),
            "reused_cell": cell is not None, "written": written}


def shard_key(fingerprint: str, folder: Path, owner: str | None, index: int, tries: int) -> str:
    """The cluster's task key for a shard: this scan's (its fingerprint), this run's (its shards'
    folder and the lock it holds), the shard's and its try's. Two scans of one config on one
    scheduler into two folders shared keys, and Dask handed one scan's shards to the other."""
    run = hashlib.sha1(f"{Path(folder).resolve()}|{owner}".encode()).hexdigest()[:10]
    return f"scan-shard-{fingerprint[:12]}-{run}-{index}-{tries}"


def lock_holder(folder: Path) -> str | None:
    """What the output folder's lock says (the process and host of the scan holding it), or
    None where no scan holds it."""
    from addon.core.files import LOCK_NAME

    try:
        return (Path(folder) / LOCK_NAME).read_text()
    except OSError:
        return None


@contextmanager
def workers_deaf_to_ctrl_c():
    """While the local cluster runs, its worker processes (those its nannies start again too) start
    with Ctrl-C ignored, a
    disposition a new program keeps (its Python through a small launcher that ignores SIGINT
    and execs it). A Ctrl-C at the terminal reaches every process of its group, and each
    worker's KeyboardInterrupt printed a traceback of its own; this process hears the stop
    and closes the cluster. This process's own Ctrl-C is untouched (blocking it here lost it
    to native threads, which the kernel may hand a process's signal)."""
    import multiprocessing.spawn as mp_spawn

    python = mp_spawn.get_executable()
    if os.name != "posix" or not os.path.exists("/bin/sh") or not python:
        yield
        return
    python = os.fsdecode(python)  # bytes in Python 3.13
    with tempfile.TemporaryDirectory(prefix="scanner-workers-") as folder:
        launcher = Path(folder) / "python"
        # (The resource tracker starts this way too; stopped with the cluster half started, it
        # warned of the semaphores left: the stop itself says what was left.)
        launcher.write_text("#!/bin/sh\ntrap '' INT\n"
                            "PYTHONWARNINGS=\"ignore:resource_tracker:UserWarning"
                            "${PYTHONWARNINGS:+,$PYTHONWARNINGS}\"\n"
                            f"export PYTHONWARNINGS\nexec {shlex.quote(python)} \"$@\"\n")
        launcher.chmod(0o755)
        mp_spawn.set_executable(str(launcher))
        try:
            yield
        finally:
            mp_spawn.set_executable(python)


@contextmanager
def cluster_client(workers: int, scheduler: str | None):
    """A Dask client: on the scheduler at ``scheduler``, or on a local cluster of ``workers`` processes."""
    from dask.distributed import Client, LocalCluster

    if scheduler:
        # The client's own log (a lost worker's "Couldn't gather", a dead scheduler's 45-line
        # traceback) would run into the command's output; what matters is said in one line.
        names = ["distributed"] + [n for n in logging.root.manager.loggerDict if n.startswith("distributed.")]
        levels = {n: logging.getLogger(n).level for n in names}  # each has its own (dask's config sets them)
        for n in names:
            logging.getLogger(n).setLevel(logging.CRITICAL)
        try:
            try:
                client = Client(scheduler, timeout="30s")
            except Exception as exc:  # whatever answers there is not a Dask scheduler (or stopped answering)
                raise ScannerError(f"--scheduler {scheduler}: no Dask scheduler answered there "
                                   f"({type(exc).__name__}: {str(exc)[:120]})") from None
            try:
                yield client
            finally:
                client.close()
        finally:
            for n, level in levels.items():
                logging.getLogger(n).setLevel(level)
        return
    # For the cluster's whole life, not only its start: a worker that dies is started again by
    # its nanny in this process, and the new one must be as deaf as the first.
    with workers_deaf_to_ctrl_c():
        # The dashboard on a free loopback port: None means Dask's 8787, and where another cluster
        # holds that every run warned of it.
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                               dashboard_address="127.0.0.1:0", silence_logs=logging.CRITICAL)
        client = Client(cluster)
        try:
            yield client
        finally:
            client.close()
            cluster.close()


def local_workers(n_frames: int, workers: int, shard_frames: int | None) -> int:
    """The workers a local cluster starts for a scan of ``n_frames``: ``workers``, but no more
    than it has shards (``_compute_shards`` starts none without one); what the memory check
    before the scan counts."""
    if n_frames < 1:
        return 1
    size = shard_frames or shards.default_shard_frames(n_frames, workers)
    return max(1, min(int(workers), len(shards.split(n_frames, int(size)))))


def check_scheduler(address: str) -> str:
    if not (isinstance(address, str) and address.startswith(("tcp://", "tls://")) and ":" in address[6:]):
        raise InputError(f"--scheduler {address!r}: expected an address like tcp://HOST:PORT")
    return address


def run_one_shard(config, out_dir: str | Path, shard_frames: int, index: int, progress=None) -> dict:
    """Compute shard ``index`` in this process, no Dask (one task of a render-farm manager's job);
    ``progress(stage, done, total)`` as a scan's."""
    from addon.pipeline import plan_scan

    plan = plan_scan(config)
    parts = shards.split(len(plan.q), shard_frames)
    if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(parts):
        raise InputError(f"--shard {index!r}: this scan has shards 0-{len(parts) - 1} at {shard_frames} frames each")
    s = parts[index]
    path = Path(out_dir) / "shards" / s.file_name()
    info = run_shard(config, plan, s, str(path), scan_fingerprint(config, plan), progress=progress)
    return {**info, "path": str(path), "describe": s.describe(), "of": len(parts)}


def run_farm(config, out_dir: str | Path, *, workers: int = 2, scheduler: str | None = None,
             shard_frames: int | None = None, log: Callable[[str], None] = print,
             progress: Callable[[str, int, int], None] | None = None, merge_only: bool = False,
             render_threads: int | None = None, measured: Callable[[], None] | None = None):
    """Scan ``config`` in shards on Dask; returns the merged ScanResult (files written in ``out_dir``).
    ``measured``: called once every shard is there, before they are merged and written (the
    command line's stop handling: a stop from then on waits for the results).
    ``merge_only``: compute nothing; merge the shards when all are there and valid (the
    last task of a render-farm job), else say which are missing or invalid.
    ``render_threads``: Cycles threads per worker (default: on a local cluster, the
    machine's cores shared out among the workers; on a scheduler, all of a worker's cores)."""
    from addon.core.geometry.cloud import Cloud
    from addon.core.scan.outputs import software_versions
    from addon.pipeline import assemble, merge_stats, plan_scan

    check_whole(workers, "--workers", 1, MAX_WORKERS)
    if render_threads is not None:
        check_whole(render_threads, "render threads", 1, 1024)
    if scheduler is not None:
        check_scheduler(scheduler)
    progress = progress or (lambda stage, done, total: None)
    t_all = time.perf_counter()
    t = time.perf_counter()
    plan = plan_scan(config)  # every refusal before any worker starts
    t_plan = time.perf_counter() - t
    fp = scan_fingerprint(config, plan)
    n = len(plan.q)
    size = shard_frames or shards.default_shard_frames(n, workers)
    # The workers write the shards: a relative folder would be read from each worker's own
    # working folder (a trial: a cluster's shards went there, none came back, and the merge
    # failed). Made absolute, it names the same folder on a shared disk.
    folder = Path(out_dir).absolute() / "shards"
    if shard_frames is None:  # the split follows --workers: a run resumed with others keeps the earlier one
        earlier = _earlier_split(folder, n, fp, size)
        if earlier is not None:
            log(f"farm: keeping the split of this scan's earlier run ({earlier} frames a shard, where --workers "
                f"{workers} gives {size}), whose finished shards are there")
            size = earlier
    parts = shards.split(n, size)
    todo = [(s, why) for s in parts if (why := _not_ready(folder, s, fp)) is not None]
    reused = len(parts) - len(todo)
    if not (merge_only and todo):  # a merge that cannot be made says only why (one line)
        log(f"farm: {n} frames in {len(parts)} shards of up to {size} frames; {reused} valid from an earlier run "
            f"(skipped), {len(todo)} to compute")
    if merge_only and todo:
        listed = "; ".join(f"{s.describe()}: {why}" for s, why in todo[:8])
        expected = {s.file_name() for s in parts}
        others = sorted(p.name for p in folder.glob("shard_*.npz") if p.name not in expected) if folder.is_dir() else []
        hint = (f"; {len(others)} shard files of another split are there (e.g. {others[0]}): merge with the "
                f"--shard-frames they were made with") if others else ""
        raise ScannerError(f"{len(todo)} of {len(parts)} shards are not ready in {folder} ({listed}"
                           f"{'; ...' if len(todo) > 8 else ''}); run them first{hint}")
    for s, why in todo:
        if why != "missing":
            log(f"  recomputing {s.describe()}: {why}")
        elif reused:  # a run resumed: say which are not there (a first run has none)
            log(f"  computing {s.describe()}: missing")
    address, worker_addresses = None, []
    t_farm = time.perf_counter()
    if todo:
        try:
            address, worker_addresses = _compute_shards(config, plan, todo, folder, fp, out_dir, workers, scheduler,
                                                        render_threads, log, progress)
        except KeyboardInterrupt as exc:  # the cluster is closed: what its workers finished is on disk
            exc.shards_finished = (sum(1 for s in parts if _not_ready(folder, s, fp) is None), len(parts))
            _drop_if_empty(folder)
            raise
        except BaseException:
            _drop_if_empty(folder)  # (a run that failed before any shard left OUT/shards/, and so OUT/)
            raise
    wall = time.perf_counter() - t_farm
    computed_frames = sum(len(s.frames) for s, _ in todo)
    if measured is not None:
        measured()
    results = []
    for s in parts:  # checked again before merging
        try:
            results.append(shards.read(folder / s.file_name(), s, fp))
        except shards.ShardInvalid as exc:  # another process wrote or removed it meanwhile (a --shard task)
            raise ScannerError(f"{s.describe()} in {folder} changed after it was computed ({exc}): another "
                               f"process wrote or removed it; nothing merged, run the scan again to recompute "
                               f"it") from None
    expected = {s.file_name() for s in parts}
    others = sorted(p.name for p in folder.glob("shard_*.npz") if p.name not in expected)
    if others:  # another split's (another scan, or --shard-frames): never read, never removed
        many = len(others) > 1
        log(f"farm: {len(others)} shard file{'s' if many else ''} in {folder} {'are' if many else 'is'} another "
            f"split's (e.g. {others[0]}), not this scan's: left as {'they are' if many else 'it is'}; remove "
            f"{'them' if many else 'it'} once that scan is done")
    cloud = Cloud.concatenate([r.cloud for r in results])
    stats = merge_stats([r.stats for r in results])
    timing = {"plan": t_plan}
    for r in results:
        for k in ("scene", "render", "detect", "triangulate"):
            timing[k] = timing.get(k, 0.0) + float(r.timing.get(k, 0.0))
    devices = {r.render_device for r in results if r.render_device}
    blenders = {r.blender for r in results if r.blender}  # the workers', not this process's (it has none)
    software = software_versions(", ".join(sorted(blenders)) if blenders else None)
    extra = {"render_device": ", ".join(sorted(devices)) if devices else None, "software": software,
             # A merge computes nothing: no workers; all its shards were there ("reused").
             # The workers that computed shards (a scheduler's, as it had them at the start); None
             # where none ran (every shard was there already: a merge).
             "farm": {"workers": len(worker_addresses) if todo else None, "scheduler": address or scheduler,
                      "worker_addresses": worker_addresses, "shards": len(parts), "shard_frames": size, "computed": len(todo), "reused": reused,
                      "wall_s": round(wall, 4),
                      # the frames computed here (a resumed run's reused shards took no time)
                      "profiles_per_s_wall": computed_frames / wall if wall > 0 and todo else None}}
    return assemble(config, plan, cloud, stats, timing, out_dir, t_all, extra)


def _drop_if_empty(folder: Path) -> None:
    """Remove the shards folder where no shard (nor anything else) is in it."""
    try:
        folder.rmdir()
    except OSError:
        pass


def _earlier_split(folder: Path, n: int, fp: str, size: int) -> int | None:
    """The frames per shard of this scan's shard files in ``folder`` where another split than
    ``size`` holds more of them valid (a stopped run resumed with other --workers recomputed
    every shard, and called the finished ones another split's); None where none does."""
    sizes = set()
    for p in folder.glob("shard_*.npz") if folder.is_dir() else ():
        try:
            first, last = (int(v) for v in p.stem.split("_")[1:3])
        except ValueError:
            continue
        k = last - first + 1
        if k > 0 and first % k == 0:  # a whole shard of a split of k (the last may be shorter)
            sizes.add(k)
    counted: dict = {}

    def valid(k: int) -> int:
        if k not in counted:
            counted[k] = sum(1 for s in shards.split(n, k)
                             if (folder / s.file_name()).exists() and _not_ready(folder, s, fp) is None)
        return counted[k]

    best = max(sorted(sizes - {size}), key=valid, default=None)
    return best if best is not None and valid(best) > valid(size) else None


def _not_ready(folder: Path, s: shards.Shard, fp: str) -> str | None:
    """Why shard ``s``'s file in ``folder`` cannot be merged into this scan ("missing", damaged,
    another scan's), None where it can."""
    try:
        shards.read(folder / s.file_name(), s, fp)
    except shards.ShardInvalid as exc:
        return str(exc)
    return None


def _compute_shards(config, plan, todo, folder: Path, fp: str, out_dir, workers: int, scheduler: str | None,
                    render_threads: int | None, log, progress) -> tuple[str, list]:
    """Compute the shards ``todo`` ((shard, why) pairs) on the cluster, each writing its file
    into ``folder``; returns the scheduler's address and the workers'."""
    workers = max(1, min(workers, len(todo)))  # a local cluster starts no worker that would have no shard
    threads = render_threads or (None if scheduler else max(1, usable_cpus() // workers))
    try:
        return _run_on_cluster(config, plan, todo, folder, fp, out_dir, workers, scheduler, threads, log, progress)
    except Exception as exc:  # Dask hands a worker's ImportError on wrapped in a plain Exception
        text = f"{type(exc).__name__}: {exc}"
        missing = re.search(r"No module named '([^'.]+)", text)
        if scheduler is None or (missing is None and "deserializ" not in text.lower()):
            raise  # a local cluster's workers import what this process does
        if missing is not None and missing.group(1) not in ("addon", "headless"):
            raise ScannerError(f"the cluster at {scheduler} lacks the package {missing.group(1)!r} ({text[:160]}): "
                               f"run its scheduler and workers with this project's set-up (.venv of the same "
                               f"commit, docs/farm.md)") from None
        # Started where Python cannot import this tool's code: the scheduler cannot read the task
        # graph, or the workers the tasks.
        repo = Path(__file__).resolve().parents[1]
        raise ScannerError(f"the cluster at {scheduler} cannot load the scanner's code ({text[:160]}): start its "
                           f"scheduler and its workers with PYTHONPATH={repo} (docs/farm.md)") from None


def _run_on_cluster(config, plan, todo, folder: Path, fp: str, out_dir, workers: int, scheduler: str | None,
                    threads: int | None, log, progress) -> tuple[str, list]:
    with cluster_client(workers, scheduler) as client:
        from dask.distributed import as_completed

        address = client.scheduler.address
        where = f"the scheduler at {address}"
        # From here on a stop (Ctrl-C) is looked at, and the stop's message knows the shards to
        # do (a stop was held until the first shard finished: minutes with Cycles).
        progress("shards", 0, len(todo))
        worker_addresses = sorted(_workers(client, where))
        log(f"farm: scheduler {address}, {len(worker_addresses)} workers"
            + ("" if worker_addresses else " (none yet: the shards wait for workers to join it)"))
        if not worker_addresses:
            _wait_for_workers(client, where, todo, progress)
            worker_addresses = sorted(_workers(client, where))  # those that joined

        def send_inputs(after=None):
            """The config (with its meshes) and the plan, to every worker once, not with every task;
            ``after``: the shard whose workers died, where the scan is sent again."""
            try:
                return client.scatter([config, plan], broadcast=True, hash=False)
            except Exception as exc:  # the workers went (died, or left the scheduler) while it sent
                why = f"they left while it was sent ({type(exc).__name__}: {str(exc)[:120]}); the shards finished are kept"
                if after is not None:  # they died in a shard: the same run would kill them again (exit 2)
                    raise ScannerError(f"could not send the scan again to the workers of {where} after "
                                       f"{after.describe()} was cancelled: {why}, nothing merged (do its workers "
                                       f"keep dying in it? out of memory, or a crash in Blender)") from None
                raise TemporaryFailure(f"could not send the scan to the workers of {where}: {why}, run the scan "
                                       f"again to go on") from None

        shared = send_inputs()
        tries = {s.index: 0 for s, _ in todo}
        owner = lock_holder(Path(out_dir))  # the command's lock: shards finishing after a stop write nothing
        def submit(s):
            return client.submit(run_shard, *shared, s, str(folder / s.file_name()), fp, threads, owner,
                                 key=shard_key(fp, folder, owner, s.index, tries[s.index]), pure=False)

        shard_of = {}
        for s, _ in todo:
            shard_of[submit(s)] = s
        done = 0
        pending = as_completed(list(shard_of))
        for fut in pending:
            s = shard_of.pop(fut)
            info = None
            if not fut.cancelled():
                try:
                    info = fut.result()  # a shard that raised raises here, with the worker's message
                except Exception as exc:
                    if type(exc).__name__ == "KilledWorker":  # the scheduler's own retries spent
                        raise ScannerError(f"{s.describe()}: every worker that took it died (Dask gave up after "
                                           f"its retries: out of memory, or a crash in Blender?); the shards "
                                           f"finished are kept, nothing merged") from None
                    # Cancelled on the way (its inputs or its result lost with a dying worker):
                    # as a cancelled one. Anything else is the shard's own error.
                    if not (fut.cancelled() or "Cancelled" in type(exc).__name__ or _lost_connection(exc)):
                        raise
                    if _lost_connection(exc) and client.status != "running":
                        raise TemporaryFailure(f"{where} stopped answering ({type(exc).__name__}); the shards finished "
                                           f"are kept, run the scan again to go on") from None
            fut.release()  # its result is read: nothing more to keep on a worker that may die
            if info is None:
                # Dask cancels a task whose scattered inputs went down with a dying worker
                # (they have no recipe to recompute them): scatter again and resubmit.
                _workers(client, where)  # a scheduler gone cancels every shard: that, not a dead worker
                tries[s.index] += 1
                if tries[s.index] > SHARD_RETRIES:
                    raise ScannerError(f"{s.describe()} was cancelled by the cluster {tries[s.index]} times "
                                       "(its workers keep dying); the shards finished are kept, nothing merged")
                log(f"  {s.describe()} cancelled by the cluster (a worker died); submitting it again")
                if not _workers(client, where):
                    _wait_for_workers(client, where, todo, progress, done)
                worker_addresses = sorted(set(worker_addresses) | set(_workers(client, where)))
                shared = send_inputs(after=s)
                again = submit(s)
                shard_of[again] = s
                pending.add(again)
                continue
            if not info["written"] and lock_holder(Path(out_dir)) == owner:
                # The scan still holds its folder, yet the worker found no lock there: it sees
                # another folder at that path (its own disk), where nothing would come back.
                raise ScannerError(f"shard {info['shard']} was computed by a worker (pid {info['pid']}) that "
                                   f"cannot see the output folder {out_dir}: give --out a folder on a disk every "
                                   f"worker shares, at the same path (docs/farm.md); nothing merged")
            done += 1
            progress("shards", done, len(todo))
            log(f"  shard {info['shard']} done: {info['points']} points in {info['seconds']:.1f} s "
                f"(worker pid {info['pid']}{', cell reused' if info['reused_cell'] else ''})")
    return address, worker_addresses


WORKER_WAIT_S = 600.0  # how long a scan waits for a first worker to join its scheduler


def _wait_for_workers(client, where: str, todo, progress, done: int = 0) -> None:
    """Wait until a worker joins (a stop is looked at every few seconds); none in WORKER_WAIT_S:
    one line saying so. (Sending the scan with no worker there failed after 30 s with Dask's
    "No valid workers found", though the log had said the shards would wait.)"""
    t = time.monotonic()
    while not _workers(client, where):
        if time.monotonic() - t > WORKER_WAIT_S:
            raise TemporaryFailure(f"no worker joined {where} in {WORKER_WAIT_S / 60:.0f} minutes: start workers on it "
                               f"(dask worker {client.scheduler.address}, docs/farm.md) and run the scan again")
        progress("shards", done, len(todo))
        try:
            client.wait_for_workers(1, timeout=2)
        except Exception:  # a timeout: look for a stop, and again
            pass


def _workers(client, where: str) -> dict:
    """The workers the scheduler knows, or ScannerError where the scheduler is gone (its
    answer then has no workers at all: a KeyError's traceback before)."""
    info = client.scheduler_info() if client.status == "running" else {}
    if "workers" not in info:
        raise TemporaryFailure(f"{where} stopped answering (the scheduler is gone); the shards finished are kept, run "
                           f"the scan again to go on")
    return info["workers"]


def _lost_connection(exc: BaseException) -> bool:
    """Whether ``exc`` is the connection to the cluster going (distributed's CommClosedError, a
    closed stream), not an error of the shard itself."""
    return type(exc).__name__ in ("CommClosedError", "StreamClosedError") or "Stream is closed" in str(exc)
