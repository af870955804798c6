"""A command's process from start to end: its own temporary folder, Ctrl-C, and nothing left behind.

Temporary folder: every command gets ``<temp>/scanner-run-<pid>-<random>`` and points
TMPDIR (and TEMP, TMP, Python's tempfile) at it before Blender is loaded, so that
Blender's session folder (``blender_*``), the render's image files and a local Dask
cluster's scratch space all land inside it. It is removed when the command ends,
however it ends; a folder whose process no longer exists (killed with SIGKILL, a
power cut) is removed by the next command that starts.

Signals: Blender's Python render engines (Cycles and Eevee run Python callbacks
during a render) catch every exception raised inside them, KeyboardInterrupt
included, so Python's own Ctrl-C handling cannot stop a render: the interrupt is
printed and swallowed and the scan runs on. ``StopRequests`` takes SIGINT and
SIGTERM instead: the first one asks the scan to stop, which it does when the
frames being rendered are done (render calls are sized to last about a second,
see ``addon.pipeline``); the second stops at once. Either way the command exits
128 + the signal's number (130 for Ctrl-C) and writes nothing into ``--out``.
Once every frame is measured (``StopRequests.finish``), a stop waits for the results
to be written and the command finishes (exit 0); once the command is over, a signal
ends the process with the command's own exit code.
"""

from __future__ import annotations

import os
import shutil
import signal
import sys
import tempfile
from pathlib import Path

from addon.core.files import pid_alive

RUN_PREFIX = "scanner-run-"
_ENV = ("TMPDIR", "TEMP", "TMP")


def stale_run_folders(base: Path) -> list[Path]:
    """Folders of earlier commands in ``base`` whose process no longer exists."""
    out = []
    for folder in base.glob(RUN_PREFIX + "*"):
        pid = folder.name[len(RUN_PREFIX):].split("-", 1)[0]
        if folder.is_dir() and pid.isdigit() and int(pid) != os.getpid() and not pid_alive(int(pid)):
            out.append(folder)
    return out


class PrivateTemp:
    """This command's temporary folder (see the module's docstring); ``close()`` removes it."""

    def __init__(self, base: str | Path | None = None):
        base = Path(base or tempfile.gettempdir())
        for folder in stale_run_folders(base):
            shutil.rmtree(folder, ignore_errors=True)
        self.path = Path(tempfile.mkdtemp(prefix=f"{RUN_PREFIX}{os.getpid()}-", dir=base))
        self._saved = ({k: os.environ.get(k) for k in _ENV}, tempfile.tempdir)
        for k in _ENV:
            os.environ[k] = str(self.path)
        tempfile.tempdir = str(self.path)

    def close(self) -> None:
        env, tempdir = self._saved
        for k, v in env.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
        tempfile.tempdir = tempdir
        shutil.rmtree(self.path, ignore_errors=True)


SIGNAL_NAMES = {signal.SIGINT: "Ctrl-C", signal.SIGTERM: "SIGTERM"}


class Interrupted(KeyboardInterrupt):
    """The user (or a job manager) stopped the command: ``signum``, and how far it had got."""

    def __init__(self, signum: int, done: int = 0, total: int = 0, unit: str = "frames"):
        super().__init__(SIGNAL_NAMES.get(signum, f"signal {signum}"))
        self.signum, self.done, self.total, self.unit = signum, done, total, unit

    @property
    def exit_code(self) -> int:
        return 128 + int(self.signum)

    def describe(self) -> str:
        what = SIGNAL_NAMES.get(self.signum, f"signal {self.signum}")
        if self.unit == "profiles":  # an adaptive scan's total is a budget, not a plan
            return f"interrupted ({what}) after {self.done} profiles of a budget of {self.total}"
        if self.total:
            return f"interrupted ({what}) after {self.done} of {self.total} {self.unit}"
        return f"interrupted ({what}) before the first {self.unit.rstrip('s')}"  # frame, shard


def _importing(frame) -> bool:
    """Whether the interrupted code is inside an import: an exception raised there can leave an
    extension module (Blender's bpy, as it loads) half made, and the process crashes on its
    way out. The stop is then only recorded, and the next ``check()`` raises it."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


class StopRequests:
    """SIGINT and SIGTERM as requests to stop (see the module's docstring).

    ``progress(stage, done, total)`` is the scan's progress callback: it records how far the
    scan has got and raises Interrupted when a stop was asked for. In a process that has not
    loaded Blender (a farm's coordinator, which waits on its workers; the kinematics
    commands) nothing swallows exceptions, so the first signal raises Interrupted at once."""

    def __init__(self, temp: PrivateTemp | None = None, stream=None, exiting: bool = False):
        self.temp = temp
        # The process ends right after the command (``python -m headless``), so a stop's
        # handler may stay to the end; in a caller that goes on (main() called in-process) the
        # signals are always given back.
        self.exiting = exiting
        self.stream = stream or sys.stderr
        self.cleanups: list = []  # what a stop "at once" must still undo (an output folder's lock)
        self.signum: int | None = None
        self.done, self.total, self.unit = 0, 0, "frames"
        self._old: dict = {}
        # While the command starts (its imports), a signal is only recorded, and ``check()``
        # raises it once they are done: a library that imports its optional parts under a
        # catch-all ``except`` (trimesh does) would otherwise swallow the KeyboardInterrupt,
        # and the command would run on as if nobody had asked.
        self.record_only = False
        # Once every frame is measured (``finishing``) a stop waits for the results to be
        # written, as a stop under way waits for the frames being rendered: raised anywhere in
        # the metrics or the writing, it would leave a lock behind, or say "nothing written"
        # of files that were. ``leaving``: the command is over and exits with this code; a
        # signal now ends the process with it at once, without a traceback from the teardown.
        self.finishing = False
        self.leaving: int | None = None

    def install(self) -> "StopRequests":
        """Take SIGINT and SIGTERM, except one the process was started with ignored: a job a
        script put in the background (its shell ignores SIGINT for it) is not the terminal's to
        stop, and stays so, as Python itself leaves such a signal ignored."""
        for s in SIGNAL_NAMES:
            try:
                if signal.getsignal(s) == signal.SIG_IGN:
                    continue
                self._old[s] = signal.signal(s, self._on_signal)
            except ValueError:  # not the main thread: leave the signals alone
                pass
        return self

    def restore(self, code: int | None = None) -> None:
        """Give the signals back to their old handlers, unless the process exits after the
        command (``exiting``): it is then on its way out, and a signal before it is gone ends it
        with the command's ``code`` (see ``leaving``), or, after a stop with no code, as that one
        stop (exit 128 + signal), never as Python's KeyboardInterrupt from wherever it lands."""
        if self.exiting and code is not None:
            self.leaving = int(code)
            return
        if self.signum is not None and self.exiting:
            return
        for s, old in self._old.items():
            signal.signal(s, old)
        self._old.clear()

    def __enter__(self) -> "StopRequests":
        return self.install()

    def __exit__(self, *exc) -> None:
        self.restore()

    def _on_signal(self, signum, frame) -> None:
        if self.leaving is not None:  # the command is over: its results stand, its code too
            for stream in (sys.stdout, sys.stderr):
                try:
                    stream.flush()
                except (OSError, ValueError):  # a closed pipe or stream: nothing more to say there
                    pass
            if self.temp is not None:
                self.temp.close()
            os._exit(self.leaving)
        if self.signum is not None:  # the second one: stop now
            said = ("stopped at once while the results were being written (the output folder may hold them)"
                    if self.finishing else
                    # a farm's shards finished so far stay on disk for the next run to keep
                    f"stopped at once, no cloud or report written; the shards finished (at least {self.done}: others "
                    f"may have finished since) stay in the output folder's shards/, for the next run to keep" if self.unit == "shards" and self.done else
                    "stopped at once, nothing written")
            # (once every frame is measured, how far the frames got says nothing: a merge's stop
            # read "before the first frame")
            head = (f"interrupted ({SIGNAL_NAMES.get(signum, f'signal {signum}')})" if self.finishing
                    else self.interrupted().describe())
            print(f"\n{head}: {said}", file=self.stream, flush=True)
            for undo in reversed(self.cleanups):
                try:
                    undo()
                except Exception:
                    pass
            if self.temp is not None:
                self.temp.close()
            os._exit(128 + int(signum))
        self.signum = signum
        if self.record_only:
            return
        if self.finishing:
            print(f"\n{SIGNAL_NAMES.get(signum)}: every frame is measured, so the results are written first "
                  f"({SIGNAL_NAMES.get(signum)} again to stop at once)", file=self.stream, flush=True)
            return
        if "bpy" not in sys.modules and not _importing(frame):
            raise self.interrupted()
        print(f"\nstopping when the frames being rendered are done ({SIGNAL_NAMES.get(signum)} again to stop "
              f"at once)", file=self.stream, flush=True)

    def interrupted(self) -> Interrupted:
        return Interrupted(self.signum or signal.SIGINT, self.done, self.total, self.unit)

    def check(self) -> None:
        if self.signum is not None and not self.finishing:
            raise self.interrupted()

    def finish(self) -> None:
        """Every frame is measured: a stop asked for before now ends the command (nothing
        written); one from now on waits for the results to be written (see ``finishing``)."""
        self.check()
        self.finishing = True

    def progress(self, stage: str, done: int, total: int) -> None:
        self.done, self.total = done, total
        self.unit = {"shards": "shards", "adaptive": "profiles"}.get(stage, "frames")
        self.check()
