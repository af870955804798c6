"""Writing output files so that a failed run never leaves a half-written one.

One file is written atomically (a temporary file beside it, renamed into place); a set
of files (a scan's cloud, report and preview) is written into a staging folder inside
the output folder and moved in together, so that either all appear or none. Before a
scan starts, its output folder is checked (``check_output_folder``) and claimed
(``OutputLock``): a second scan into a folder that a running scan owns is refused.
"""

from __future__ import annotations

import os
import secrets
import shutil
import socket
import tempfile
import threading
import time
from pathlib import Path

from .errors import FolderBusy, InputError

LOCK_NAME = ".scanner.lock"
LOCK_HEARTBEAT_S = 60   # a running scan touches its lock this often
LOCK_STALE_S = 600      # a lock from another host not touched for this long is a dead scan's
LOCK_UNREADABLE_S = 2.0  # a lock naming no process is waited on this long (being written) before taken over
LOCK_GUARD_STALE_S = 10.0  # a take-over guard older than this was left by a killed process (another host's)
GUARD_NAME = f"{LOCK_NAME}.takeover"  # held while a dead scan's lock is removed
MAX_PID = 2 ** 22       # the largest process id Linux gives (pid_max's ceiling)


def write_bytes_atomic(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to a temporary file beside ``path`` and rename it into place.

    A crash or error mid-way leaves the old file (or none), never a partial one.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    except OSError as exc:  # named for the file asked for, not for the folder or the temporary file
        raise type(exc)(exc.errno, exc.strerror, str(path)) from None
    try:
        with os.fdopen(fd, "wb") as fh:
            _write_synced(fh, data, path)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the file the usual mode
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise type(exc)(exc.errno, exc.strerror, str(path)) from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


STAGING_PREFIX = ".staging-"  # then the writing process's id: write_set's folder for files not yet in place


def write_set(folder: str | Path, contents: dict[str, bytes]) -> dict[str, Path]:
    """Write files {name: bytes} into ``folder`` so that all of them appear or none: each is
    written into a staging folder inside ``folder`` first, then all are renamed into place."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f"{STAGING_PREFIX}{os.getpid()}-", dir=folder))
    old = staging / ".old"  # the files being replaced, kept until every new one is in place
    old.mkdir()
    kept: list[str] = []
    moved: list[str] = []
    try:
        for name, data in contents.items():
            with open(staging / name, "wb") as fh:
                _write_synced(fh, data, folder / name)
            os.chmod(staging / name, 0o666 & ~_umask())
        for name in contents:
            try:
                if (folder / name).is_file():
                    try:
                        os.link(folder / name, old / name)  # (the file stays in place, under a second name)
                        kept.append(name)
                    except OSError:  # a file system without hard links, or a file that refuses one: a copy
                        try:
                            shutil.copy2(folder / name, old / name)
                            kept.append(name)
                        except OSError:
                            pass  # (nor a copy: replaced without one to put back, as a plain rename is)
                os.replace(staging / name, folder / name)
            except OSError as exc:  # named for the user's file, not the staging folder's
                raise type(exc)(exc.errno, exc.strerror, str(folder / name)) from None
            moved.append(name)
    except BaseException:
        # A rename failed after others worked: the new files out again and the old ones back, so
        # that the folder holds the last complete set (the old cloud and preview were lost, and
        # an old report stood beside nothing).
        for name in moved:
            try:
                if name in kept:
                    os.replace(old / name, folder / name)
                else:
                    (folder / name).unlink(missing_ok=True)
            except OSError:
                pass
        raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return {name: folder / name for name in contents}


def _write_synced(fh, data: bytes, path: Path) -> None:
    """Write, flush and sync; an error (a full disk) names ``path``, the file it was for."""
    try:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())
    except OSError as exc:
        if exc.filename is not None:
            raise
        raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from exc


def png_bytes(bgr) -> bytes:
    """A BGR uint8 picture encoded as PNG."""
    import cv2

    from .errors import ScannerError

    ok, png = cv2.imencode(".png", bgr)
    if not ok:
        raise ScannerError(f"could not encode a {getattr(bgr, 'shape', '?')} picture as PNG")
    return png.tobytes()


def write_png(path: str | Path, bgr) -> Path:
    """Encode a BGR uint8 picture as PNG and write it atomically."""
    return write_bytes_atomic(path, png_bytes(bgr))


def check_output_file(path: str | Path, what: str = "output file") -> Path:
    """Refuse, in one line, a file that could not be written at ``path`` (a folder there, a
    file or an unwritable place above it): before the work that makes it, not after."""
    p = Path(path)
    # (a name ending in a slash is a folder's: "x/" wrote a file x)
    if not p.name or p.is_dir() or str(path).endswith(("/", os.sep)):
        raise InputError(f"{what} {str(path)!r} is a folder; give the name of the file to write")
    if p.exists() and not p.is_file():  # a device or a pipe: the file written beside it would replace it
        raise InputError(f"{what} {str(path)!r} is {_not_a_file(p)}, not a file; give the name of a file to write")
    check_output_folder(p.parent, (), f"{what} {p}: its folder")
    return p


def check_output_folder(folder: str | Path, names=(), what: str = "output folder", inputs=()) -> Path:
    """Refuse, in one line, an output folder a scan could not write into: a file where the
    folder should be or above it, a place that is not writable, a sub-folder where one of
    the files ``names`` goes, or one of ``inputs`` (files the scan reads: its part's mesh)
    where one of them goes. Nothing is left behind (a trial folder is made and removed)."""
    p = Path(folder)
    if p.exists() and not p.is_dir():
        kind = "a file" if p.is_file() else _not_a_file(p)  # (/dev/null was called "a file")
        raise InputError(f"{what} {p} is {kind}; give a folder (it is made when missing)")
    if p.is_symlink() and not p.exists():
        raise InputError(f"{what} {p} is a link to {os.readlink(p)}, which does not exist; make that folder first, "
                         f"or give another")
    existing = p
    while not existing.exists() and existing.parent != existing:
        existing = existing.parent
    if not existing.is_dir():
        raise InputError(f"{what} {p}: {existing} is a file, so no folder can be made below it")
    if not os.access(existing, os.W_OK | os.X_OK):
        where = "" if existing == p else f" (its nearest existing parent {existing} is not writable)"
        raise InputError(f"{what} {p} cannot be written{where}: {_why_not_writable(existing)}; choose a folder "
                         f"you can write to")
    # Permission bits do not tell everything (root passes os.access; /proc and /sys refuse
    # anyway): try a folder there, and take it away again.
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".scanner-check-", dir=existing))
    except OSError as exc:
        where = "" if existing == p else f" (in {existing})"
        raise InputError(f"{what} {p} cannot be written{where}: {exc.strerror or exc}; "
                         f"choose a folder you can write to") from None
    for name in names:
        target = p / name
        if target.exists() and not target.is_file():
            raise InputError(f"{what} {p}: {target} is {_not_a_file(target)} where the scan writes its {name}; "
                             f"move it away or choose another folder")
        for source in inputs:
            try:
                same = target.is_file() and Path(source).is_file() and os.path.samefile(target, source)
            except OSError:
                same = False
            if same:
                raise InputError(f"{what} {p}: the scan would write its {name} over {source}, a file it reads; "
                                 f"choose another folder (or move that file)")
    return p


def _why_not_writable(folder: Path) -> str:
    """Why this process may not write into ``folder``: a read-only file system, or its
    permissions (as ls shows them) and owner."""
    import stat

    try:
        if os.statvfs(folder).f_flag & os.ST_RDONLY:
            return "it is on a read-only file system"
        st = folder.stat()
    except (OSError, AttributeError):  # AttributeError: no statvfs (Windows)
        return "this user may not write there"
    return f"this user may not write there (its permissions {stat.filemode(st.st_mode)}, owner uid {st.st_uid})"


def _not_a_file(path: Path) -> str:
    """What stands at ``path`` that is not a plain file, in words."""
    import stat

    try:
        mode = path.stat().st_mode
    except OSError:
        return "something other than a file"
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a pipe (FIFO)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "something other than a file"


def pid_alive(pid: int) -> bool:
    """Whether a process ``pid`` exists (True where the platform cannot tell)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True  # another user's process, or a platform without that query
    return True


class OutputLock:
    """A running scan's claim on its output folder (a ``.scanner.lock`` file with its process
    id and host, touched every LOCK_HEARTBEAT_S while the scan runs). ``acquire()`` refuses
    when a live process of this host holds it, or a process on another host (a folder on a
    shared disk) whose lock was touched within LOCK_STALE_S; a lock left by a dead process of
    this host, or not touched for that long, is taken over. ``release()`` removes the lock,
    and the folder too when this scan made it and left it empty (an interrupted or failed
    scan leaves nothing behind)."""

    def __init__(self, folder: str | Path):
        self.folder = Path(folder)
        self.path = self.folder / LOCK_NAME
        self.made_folders: list[Path] = []  # the folders acquire() made, the deepest first
        self.held = False
        self._beat: threading.Event | None = None

    def acquire(self) -> "OutputLock":
        host = socket.gethostname()
        mine = f"{os.getpid()} {host}\n"
        self.made_folders = _missing_folders(self.folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        for _ in range(200):
            # The lock appears whole or not at all: written beside it, then linked to its name
            # (created empty and written after, a scan arriving in between read an empty lock as
            # a dead scan's, took it over, and two scans held the folder).
            if self._link_new_lock(mine):
                self.held = True
                self._start_heartbeat()
                return self
            owner, owner_host = _lock_owner(self.path)
            if not owner:
                if _age_s(self.path) < LOCK_UNREADABLE_S:  # (written by a version that wrote it after creating it)
                    time.sleep(0.02)
                    continue
            elif owner_host not in (None, host):
                age = _age_s(self.path)
                if age < LOCK_STALE_S:
                    self.release()
                    raise FolderBusy(f"output folder {self.folder}: a scan on host {owner_host} (process "
                                     f"{owner}) holds it, its lock touched {age:.0f} s ago; wait for it to end "
                                     f"or choose another folder (a lock not touched for {LOCK_STALE_S} s is "
                                     f"taken over)") from None
            elif owner != os.getpid() and pid_alive(owner):
                self.release()
                raise FolderBusy(f"output folder {self.folder}: a running scan (process {owner} on this host, "
                                 f"{host}) is writing there; wait for it to end or choose another folder (or, "
                                 f"if no scan runs there, delete {self.path})") from None
            self._take_over_stale(owner, owner_host)
        guard = self.folder / GUARD_NAME
        held = f"; {guard} is held by process {_lock_owner(guard)[0]}" if guard.exists() else ""
        raise FolderBusy(f"output folder {self.folder}: could not claim it ({self.path} keeps coming back{held}); "
                         f"try again, or, if no scan runs there, delete those files")

    def _link_new_lock(self, content: str, path: Path | None = None) -> bool:
        """Make the lock file (or ``path``) with ``content`` in one step; False where one is
        there already."""
        path = path or self.path
        temp = self.folder / f"{LOCK_NAME}.{os.getpid()}.{secrets.token_hex(4)}"
        try:
            temp.write_text(content)
            try:
                os.link(temp, path)
            except FileExistsError:
                return False
            except OSError:  # a file system without hard links (FAT): created, then written
                try:
                    fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
                except FileExistsError:
                    return False
                with os.fdopen(fd, "w") as fh:
                    fh.write(content)
            return True
        finally:
            temp.unlink(missing_ok=True)

    def _take_over_stale(self, owner: int, owner_host: str | None) -> None:
        """Remove a dead scan's lock, and its staging folders. Only the holder of a guard file
        beside the lock removes one, after reading it again: a lock can be made only where none
        is, so the one read under the guard is the one removed. (Moved aside without a guard, a
        scan that had judged the dead lock a moment earlier moved the new owner's lock instead,
        and another scan claimed the folder before it was put back: two held it.) The guard is
        held for a read and an unlink; one left by a process killed meanwhile is cleared at
        once where its process is gone (this host), else once LOCK_GUARD_STALE_S old."""
        host = socket.gethostname()
        guard = self.folder / GUARD_NAME
        if not self._link_new_lock(f"{os.getpid()} {host}\n", guard):
            self._clear_dead_guard(guard, host)
            time.sleep(0.01)
            return
        try:
            if _lock_owner(self.path) != (owner, owner_host):
                return  # taken over and claimed by another scan since it was read: judged again
            self.path.unlink(missing_ok=True)
        finally:
            guard.unlink(missing_ok=True)
        if owner:  # (outside the guard: only the dead owner's, which nobody else writes)
            for staging in self.folder.glob(f"{STAGING_PREFIX}{owner}-*"):
                shutil.rmtree(staging, ignore_errors=True)

    def _clear_dead_guard(self, guard: Path, host: str) -> None:
        """Remove a take-over guard whose holder is gone: a process of this host that no longer
        runs, or one not touched for LOCK_GUARD_STALE_S. Moved aside first under a name of its
        own and read there, so that of several scans judging it at once only one removes it,
        and a guard made since (another's, alive) is put back rather than removed."""
        pid, guard_host = _lock_owner(guard)
        dead = (pid and guard_host in (None, host) and not pid_alive(pid)) or _age_s(guard) > LOCK_GUARD_STALE_S
        if not dead:
            return
        aside = self.folder / f"{GUARD_NAME}.stale.{os.getpid()}.{secrets.token_hex(4)}"
        try:
            os.rename(guard, aside)
        except OSError:
            return  # gone already (another scan cleared it)
        try:
            if _lock_owner(aside) != (pid, guard_host):  # a new guard, made since it was read: put back
                try:
                    os.link(aside, guard)
                except OSError:
                    pass
        finally:
            aside.unlink(missing_ok=True)

    def _start_heartbeat(self) -> None:
        """Touch the lock every LOCK_HEARTBEAT_S from a daemon thread, so that other hosts can
        tell a running scan from one that died."""
        stop = self._beat = threading.Event()
        path = self.path

        def beat():
            while not stop.wait(LOCK_HEARTBEAT_S):
                try:
                    os.utime(path)
                except OSError:
                    return

        threading.Thread(target=beat, name="scanner-lock-heartbeat", daemon=True).start()

    def release(self) -> None:
        if self._beat is not None:
            self._beat.set()
            self._beat = None
        if self.held:
            # A stop at once (a second Ctrl-C) while the results were being written ends the
            # process before write_set can clear its staging folder: the lock's owner clears it.
            for staging in self.folder.glob(f"{STAGING_PREFIX}{os.getpid()}-*"):
                shutil.rmtree(staging, ignore_errors=True)
            if _lock_owner(self.path) == (os.getpid(), socket.gethostname()):  # still ours (not taken over)
                self.path.unlink(missing_ok=True)
            self.held = False
        for folder in self.made_folders:  # the folder and those made above it ('--out a/b' made a)
            try:
                folder.rmdir()  # only when empty
            except OSError:
                break
        self.made_folders = []

    def __enter__(self) -> "OutputLock":
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


def _missing_folders(folder: Path) -> list[Path]:
    """``folder`` and those above it that do not exist yet, the deepest first."""
    missing = []
    for p in (folder.absolute(), *folder.absolute().parents):
        if p.exists() or p.is_symlink():
            break
        missing.append(p)
    return missing


def _lock_owner(path: Path) -> tuple[int, str | None]:
    """(process id, host) written in a lock file; (0, None) where it cannot be read or holds
    no process id a system gives (1 .. MAX_PID), the host None in locks written before hosts
    were (this host's, then)."""
    try:
        words = path.read_text().split()
        pid = int(words[0])
    except (OSError, ValueError, IndexError):
        return 0, None
    if not 0 < pid <= MAX_PID:
        return 0, None
    return pid, (words[1] if len(words) > 1 else None)


def _age_s(path: Path) -> float:
    """Seconds since ``path`` was last modified (0 where it cannot be read)."""
    try:
        return max(0.0, time.time() - path.stat().st_mtime)
    except OSError:
        return 0.0


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
