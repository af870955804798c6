"""Output files: a set appears together or not at all, output folders are checked and claimed."""

import json
import os
import re
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from addon.core.errors import FolderBusy, InputError
from addon.core.files import OutputLock, check_output_folder, write_set
from addon.core.scan.report import report_json


def test_write_set_puts_every_file_in_place(tmp_path):
    files = write_set(tmp_path / "out", {"a.bin": b"1", "b.txt": b"two"})
    assert files["b.txt"].read_bytes() == b"two" and files["a.bin"].read_bytes() == b"1"
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["a.bin", "b.txt"]  # no staging left


def test_write_set_leaves_nothing_when_one_file_cannot_be_placed(tmp_path):
    out = tmp_path / "out"
    (out / "b.txt").mkdir(parents=True)  # a folder where the second file goes: its rename fails
    with pytest.raises(OSError):
        write_set(out, {"a.bin": b"1", "b.txt": b"two"})
    assert sorted(p.name for p in out.iterdir()) == ["b.txt"]  # a.bin taken out again, no staging


def test_a_stop_at_once_while_the_files_are_written_leaves_no_staging_folder(tmp_path):
    """A second Ctrl-C while the results are written runs the command's clean-ups (the lock's
    release) and ends the process there, inside write_set: the lock's owner clears the
    staging folder write_set had made, and no one else's."""
    out = tmp_path / "out"
    out.mkdir()
    theirs = out / ".staging-999999-xyz"  # another writer's (a farm shard's): left alone
    theirs.mkdir()
    script = (
        "import os, sys\n"
        f"sys.path.insert(0, {str(Path(__file__).resolve().parents[2])!r})\n"
        "from addon.core.files import OutputLock, write_set\n"
        f"lock = OutputLock({str(out)!r}).acquire()\n"
        "def stop_at_once(*a):\n"
        "    lock.release()\n"   # what the stop handler's clean-ups do, then it leaves
        "    os._exit(130)\n"
        "os.replace = stop_at_once\n"
        "write_set(lock.folder, {'cloud.ply': b'x' * 1000, 'report.json': b'{}'})\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert done.returncode == 130, done.stderr
    assert sorted(p.name for p in out.iterdir()) == [theirs.name]


def test_output_folder_checks_name_the_problem(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(InputError, match="is a file"):
        check_output_folder(tmp_path / "file")
    with pytest.raises(InputError, match="no folder can be made below it"):
        check_output_folder(tmp_path / "file" / "out")
    (tmp_path / "out" / "cloud.ply").mkdir(parents=True)
    with pytest.raises(InputError, match="cloud.ply"):
        check_output_folder(tmp_path / "out", ["cloud.ply"])
    assert check_output_folder(tmp_path / "new" / "deeper") == tmp_path / "new" / "deeper"
    assert not (tmp_path / "new").exists()  # checking creates nothing


def test_lock_refuses_a_live_owner_and_takes_over_a_dead_ones(tmp_path):
    out = tmp_path / "out"
    with OutputLock(out):
        assert (out / ".scanner.lock").read_text().split()[0] == str(os.getpid())
    assert not out.exists()  # made by the lock, left empty: removed with it
    out.mkdir()
    (out / ".scanner.lock").write_text(f"{os.getppid()}\n")  # a live process
    with pytest.raises(FolderBusy, match=rf"running scan \(process {os.getppid()} on this host, "
                                         rf"{re.escape(socket.gethostname())}\)"):
        OutputLock(out).acquire()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (out / ".scanner.lock").write_text(f"{dead.pid}\n")
    lock = OutputLock(out).acquire()
    assert (out / ".scanner.lock").read_text().split()[0] == str(os.getpid())
    lock.release()
    assert out.is_dir() and not (out / ".scanner.lock").exists()  # the folder was there before: kept


def test_a_failed_scan_leaves_none_of_the_folders_it_made(tmp_path):
    (tmp_path / "a").mkdir()
    with OutputLock(tmp_path / "a" / "b" / "c" / "out"):
        pass
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a"]  # b, c and out gone; a was there
    assert not any((tmp_path / "a").iterdir())
    with OutputLock(tmp_path / "x" / "y"):
        (tmp_path / "x" / "kept.txt").write_text("another's file")  # written beside it meanwhile
    assert sorted(p.name for p in (tmp_path / "x").iterdir()) == ["kept.txt"]


def test_a_set_that_fails_midway_leaves_the_last_complete_set(tmp_path, monkeypatch):
    """The report's rename refused (a file held open on Windows, an immutable file): the new
    cloud and preview were taken out again, and with them the old ones, which the renames had
    replaced; the old report was left describing a cloud that was gone."""
    import addon.core.files as files

    out = tmp_path / "out"
    write_set(out, {"cloud.ply": b"old cloud", "preview.png": b"old picture", "report.json": b"old report"})
    replace = os.replace

    def refusing(src, dst):
        if Path(dst).name == "report.json" and Path(dst).parent == out and ".old" not in str(src):
            raise PermissionError(1, "Operation not permitted", str(src))
        return replace(src, dst)

    monkeypatch.setattr(files.os, "replace", refusing)
    with pytest.raises(PermissionError) as caught:
        write_set(out, {"cloud.ply": b"new cloud", "preview.png": b"new picture", "report.json": b"new report"})
    assert caught.value.filename == str(out / "report.json")  # the user's file, not a staging one
    assert {p.name: p.read_bytes() for p in out.iterdir()} == {
        "cloud.ply": b"old cloud", "preview.png": b"old picture", "report.json": b"old report"}
    # Where no hard link can be made (FAT, some shares) the old files are copied aside instead.
    def no_links(*args, **kwargs):
        raise OSError(1, "Operation not permitted")

    monkeypatch.setattr(files.os, "link", no_links)
    with pytest.raises(PermissionError):
        write_set(out, {"cloud.ply": b"new cloud", "preview.png": b"new picture", "report.json": b"new report"})
    assert {p.name: p.read_bytes() for p in out.iterdir()} == {
        "cloud.ply": b"old cloud", "preview.png": b"old picture", "report.json": b"old report"}
    monkeypatch.setattr(files.os, "replace", replace)
    write_set(out, {"cloud.ply": b"new cloud", "preview.png": b"new picture"})  # a new file beside the old ones
    write_set(out, {"extra.txt": b"x"})
    assert sorted(p.name for p in out.iterdir()) == ["cloud.ply", "extra.txt", "preview.png", "report.json"]


def test_a_take_over_guard_left_by_a_killed_scan_is_cleared_at_once(tmp_path):
    """A scan killed while it held the guard (removing a dead scan's lock) left it: the next
    scan retried for 2 s and said the lock "keeps coming back". A live holder's guard is
    waited on, and named when it outlasts the retries."""
    import time

    from addon.core.files import GUARD_NAME

    out = tmp_path / "out"
    out.mkdir()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    host = socket.gethostname()
    (out / ".scanner.lock").write_text(f"{dead.pid} {host}\n")
    (out / GUARD_NAME).write_text(f"{dead.pid} {host}\n")
    t = time.perf_counter()
    lock = OutputLock(out).acquire()
    assert time.perf_counter() - t < 1.0 and not (out / GUARD_NAME).exists()
    lock.release()
    assert sorted(p.name for p in out.iterdir()) == []
    (out / ".scanner.lock").write_text(f"{dead.pid} {host}\n")
    (out / GUARD_NAME).write_text(f"{os.getppid()} {host}\n")  # held, by a live process
    with pytest.raises(FolderBusy, match=rf"{GUARD_NAME} is held by process {os.getppid()}"):
        OutputLock(out).acquire()


def _claim(folder, barrier, results):
    barrier.wait()
    try:
        lock = OutputLock(folder).acquire()
    except FolderBusy:
        results.put("busy")
        return
    except Exception as exc:  # said, not lost (the test would wait for it)
        results.put(f"{type(exc).__name__}: {exc}")
        return
    import time

    start = time.monotonic()
    time.sleep(0.3)
    try:
        still = (Path(folder) / ".scanner.lock").read_text().split()[0] == str(os.getpid())
    except OSError:
        still = False
    end = time.monotonic()
    lock.release()
    results.put(("held" if still else "held, lock lost", start, end))


@pytest.mark.parametrize("stale", [False, True])
def test_scans_started_together_never_both_hold_a_folder(tmp_path, stale):
    """Six processes claiming one folder at once (on an empty folder, and over a dead scan's
    lock): the lock was created empty and written after, and a scan arriving in between took
    the empty lock for a dead one's, so two held the folder in 11 of 30 such trials (15 of 20
    over a stale lock). One holds it; the others are told it is busy."""
    import multiprocessing

    ctx = multiprocessing.get_context("fork")
    for trial in range(20):  # (a race: before, two held it in about one trial of three)
        folder = tmp_path / f"t{trial}"
        folder.mkdir()
        if stale:
            (folder / ".scanner.lock").write_text(f"4000000 {socket.gethostname()}\n")  # no such process
        barrier, results = ctx.Barrier(6), ctx.Queue()
        workers = [ctx.Process(target=_claim, args=(folder, barrier, results)) for _ in range(6)]
        for w in workers:
            w.start()
        for w in workers:
            w.join()
        said = [results.get(timeout=60) for _ in workers]
        assert all(r == "busy" or isinstance(r, tuple) for r in said), said
        held = sorted((r for r in said if r != "busy"), key=lambda r: r[1])
        assert held and all(r[0] == "held" for r in held), said  # each holder kept its own lock
        for a, b in zip(held, held[1:]):  # one after another (a late starter may claim it once freed)
            assert b[1] >= a[2], said
        assert not (folder / ".scanner.lock").exists()


def test_a_lock_from_another_host_is_never_taken_over_and_says_whose_it_is(tmp_path):
    """On a disk shared by render nodes a process id from another host says nothing here:
    such a lock is refused (naming the host), not taken over as a dead process's."""
    from addon.core.errors import FolderBusy

    out = tmp_path / "out"
    out.mkdir()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (out / ".scanner.lock").write_text(f"{dead.pid} node-17\n")  # not alive here; may be there
    with pytest.raises(FolderBusy, match="host node-17 .process {}".format(dead.pid)):
        OutputLock(out).acquire()
    assert (out / ".scanner.lock").read_text().split() == [str(dead.pid), "node-17"]
    # Untouched for longer than a running scan's heartbeat allows: that scan died; taken over.
    import time

    from addon.core.files import LOCK_STALE_S

    old = time.time() - LOCK_STALE_S - 5
    os.utime(out / ".scanner.lock", (old, old))
    import socket

    with OutputLock(out):
        assert (out / ".scanner.lock").read_text().split() == [str(os.getpid()), socket.gethostname()]
    (out / ".scanner.lock").write_text(f"{dead.pid} {socket.gethostname()}\n")  # this host's, dead: taken over
    with OutputLock(out):
        assert (out / ".scanner.lock").read_text().split() == [str(os.getpid()), socket.gethostname()]
    for junk in ("99999999999999999999 node-17", "-1 node-17", "-1", "x y z", ""):  # no process: taken over
        (out / ".scanner.lock").write_text(junk)
        with OutputLock(out):
            assert (out / ".scanner.lock").read_text().split()[0] == str(os.getpid())


def test_a_running_scans_lock_is_touched_while_it_runs(tmp_path, monkeypatch):
    import time

    import addon.core.files as files

    monkeypatch.setattr(files, "LOCK_HEARTBEAT_S", 0.05)
    with OutputLock(tmp_path / "out") as lock:
        old = time.time() - 1000
        os.utime(lock.path, (old, old))
        time.sleep(0.3)
        assert time.time() - lock.path.stat().st_mtime < 5
    assert not (tmp_path / "out").exists()


def test_a_full_disk_names_the_file_it_stopped_on(tmp_path, monkeypatch):
    import errno

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(OSError, match="No space left") as err:
        write_set(tmp_path / "out", {"cloud.ply": b"x", "report.json": b"{}"})
    assert err.value.filename == str(tmp_path / "out" / "cloud.ply")
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == []  # nothing half-written


def test_report_json_is_strict():
    text = report_json({"rms_um": float("nan"), "max": float("inf"), "list": [1.0, np.float64("nan")]})
    data = json.loads(text, parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))
    assert data == {"rms_um": None, "max": None, "list": [1.0, None]}


def test_a_folder_that_cannot_be_written_is_refused_with_the_reason(tmp_path, monkeypatch):
    import os

    from addon.core import files

    locked = tmp_path / "locked"
    locked.mkdir(mode=0o555)
    monkeypatch.setattr(files.os, "access", lambda path, mode: Path(path) != locked)
    with pytest.raises(InputError, match=r"locked cannot be written: this user may not write there \(its permissions "
                                         r"dr-xr-xr-x"):
        files.check_output_folder(locked)
    flags = type("V", (), {"f_flag": os.ST_RDONLY})
    monkeypatch.setattr(files.os, "statvfs", lambda path: flags)
    with pytest.raises(InputError, match=r"locked/out cannot be written \(its nearest existing parent .*locked is not "
                                         r"writable\): it is on a read-only file system"):
        files.check_output_folder(locked / "out")


def test_an_ascii_ply_cloud_is_read_with_its_attributes(tmp_path):
    """A PLY written as text (other tools' usual form): trimesh gives its columns as a dict, not
    one array, and load_ply failed with an AttributeError's traceback on every such file."""
    from addon.core.geometry.cloud import load_ply

    path = tmp_path / "text.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
                    "property int frame\nproperty uchar camera\nproperty float quality\nend_header\n"
                    "1 2 3 7 1 0.5\n4 5 6 8 3 0.25\n")
    cloud = load_ply(path)
    np.testing.assert_allclose(cloud.points, [[1, 2, 3], [4, 5, 6]])
    assert cloud.frame.tolist() == [7, 8] and cloud.camera.tolist() == [1, 3]
    np.testing.assert_allclose(cloud.quality, [0.5, 0.25])
    plain = tmp_path / "plain.ply"
    plain.write_text("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                     "property float z\nend_header\n1 2 3\n")
    assert load_ply(plain).frame.tolist() == [0]
