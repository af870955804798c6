"""What a scan command checks before its first render, so that a run that cannot finish is
refused in one line instead of failing after an hour (or taking the machine down).

- the output folder: creatable, writable, not a file, no folder where an output file goes
  (addon.core.files.check_output_folder);
- the render's size: memory for one frame's images against the memory this machine has
  free, and a time estimate against a limit (both refused unless ``--force``);
- the temporary folder: room for one render call's image files, and the process's
  file-size limit (a render that hits either crashes inside Blender; the raycast engine
  writes none);
- a Dask scheduler's address: something answers there within a few seconds.

The estimates are upper bounds from the full sensor (the band of rows a scan renders is
usually far smaller): they exist to catch a wrong order of magnitude, not to plan a farm.
"""

from __future__ import annotations

import os
import shutil
import socket
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path

from addon.core.errors import InputError
from addon.core.files import check_output_folder

# Memory per sensor pixel of one frame, both views: Blender's render result (RGBA float per
# view), Cycles' film buffers, the EXR written and the image read back.
MEMORY_BYTES_PER_PIXEL = 100
EXR_BYTES_PER_PIXEL = 12  # RGB float32, uncompressed, per view
PIXELS_PER_SECOND = 4e5  # Cycles at one sample, two CPU cores (bench scan: the demo at 160x160)
# The raycast engine casts rays, writes no image files and has no samples: the demo at
# 1280x1024 ran 23 profiles/s here (bench scan), 60 M sensor pixels a second; half that
# keeps the estimate an upper bound (the Cycles rate made an hour's raycast scan 8 h).
RAYCAST_PIXELS_PER_SECOND = 3e7
MAX_HOURS = 8.0  # a longer estimate is refused unless --force
# A local farm's worker: a Python process with bpy loaded and the cell built, before any frame
# (a Cycles worker of the demo peaked at 484 MB). The check counted only the frames, and let
# 64 workers start on a machine with 24 GB free that they needed 31 GB of.
WORKER_PROCESS_BYTES = 500_000_000
SCHEDULER_TIMEOUT_S = 5.0
SCHEDULER_GRACE_S = 5.0  # beyond Dask's own connect timeout, for its handshake


@dataclass(frozen=True)
class RenderBudget:
    width: int
    height: int
    frames: int
    cameras: int
    samples: int
    chunk_frames: int
    engine: str = "cycles"

    @property
    def writes_images(self) -> bool:
        """Whether its frames go through image files (the raycast engine's do not)."""
        return self.engine != "raycast"

    @property
    def memory_bytes(self) -> int:
        return self.width * self.height * MEMORY_BYTES_PER_PIXEL

    @property
    def exr_bytes(self) -> int:
        """One camera's image file of one frame."""
        return self.width * self.height * EXR_BYTES_PER_PIXEL + 65536

    @property
    def seconds(self) -> float:
        pixels = self.frames * self.cameras * self.width * self.height
        if not self.writes_images:
            return pixels / RAYCAST_PIXELS_PER_SECOND
        return pixels * max(self.samples, 1) / PIXELS_PER_SECOND


def folder_argument(text: str) -> str:
    """argparse type of an output folder option: an empty one names no folder (it used to fall
    back to the default folder without a word)."""
    import argparse

    if not text.strip():
        raise argparse.ArgumentTypeError("an empty name is no folder; leave the option out for the default")
    return text


def frames_argument(text: str) -> str:
    """argparse type of a ``--frames`` option: part of the path as A:B (checked as
    ``parse_frames`` reads it), never empty (an unset shell variable, ``--frames "$PART"``,
    scanned the whole path without a word)."""
    import argparse

    from addon.core.config.scan import parse_frames
    from addon.core.errors import InputError

    if not text.strip():
        raise argparse.ArgumentTypeError("an empty part of the path: give A:B (e.g. 0:40 or ::2), or leave "
                                         "--frames out for the whole path")
    try:
        parse_frames(text, "")
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc).strip()) from None
    return text


def render_budget(config) -> RenderBudget:
    from addon.core.config.render import with_sensor

    probe, r = config.probe, with_sensor(config.render, config.sensor)  # the samples a sensor model asks for
    w, h = probe.cols_px, probe.rows_px
    return RenderBudget(int(w), int(h), len(config.waypoints), 2, int(r.samples), config.leave_out.chunk_frames,
                        r.engine)


def available_memory() -> int | None:
    """Bytes of memory this machine can give a process now (None where that cannot be told)."""
    try:
        import psutil

        return int(psutil.virtual_memory().available)
    except ImportError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _size(n: float) -> str:
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if n >= scale:
            return f"{n / scale:.1f} {unit}"
    return f"{n / 1e3:.0f} kB"


def _duration(seconds: float) -> str:
    if seconds >= 86400:
        return f"{seconds / 86400:.0f} days"
    if seconds >= 3600:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 60:.0f} min"


def check_render_size(budget: RenderBudget, force: bool = False, memory: int | None = None, workers: int = 1) -> None:
    """Refuse a render whose frame needs more memory than is free (each of ``workers`` local
    processes rendering one at once), or whose time estimate exceeds MAX_HOURS, unless ``force``."""
    size = f"{budget.width}x{budget.height}"
    memory = available_memory() if memory is None else memory
    need = budget.memory_bytes * workers + (WORKER_PROCESS_BYTES * workers if workers > 1 else 0)
    if not force and memory is not None and need > memory:
        if workers > 1:
            raise InputError(f"{workers} local workers, each a Blender process (about "
                             f"{_size(WORKER_PROCESS_BYTES)}) rendering a {size} frame at once, need about "
                             f"{_size(need)} of memory, and this machine has {_size(memory)} free; use fewer "
                             f"--workers or a smaller --resolution (or --force)")
        raise InputError(f"a {size} frame needs about {_size(budget.memory_bytes)} of memory to render and this "
                         f"machine has {_size(memory)} free; use a smaller --resolution (or --force)")
    if not force and budget.seconds > MAX_HOURS * 3600:
        how = f"{budget.samples} sample(s)" if budget.writes_images else "ray cast"
        raise InputError(f"{budget.frames} frames at {size}, {how}, would take up to "
                         f"{_duration(budget.seconds)} on this CPU (more than {MAX_HOURS:g} h); use fewer frames "
                         f"or pixels, or --force to run it anyway")


def check_temp_room(budget: RenderBudget, folder: str | Path | None = None) -> None:
    """Refuse when the temporary folder cannot hold one render call's image files, or one
    image file is larger than the process may write (ulimit -f): Blender crashes on both."""
    if not budget.writes_images:
        return
    folder = Path(folder or tempfile.gettempdir())
    need = budget.exr_bytes * budget.cameras * budget.chunk_frames
    try:
        free = shutil.disk_usage(folder).free
    except OSError as exc:
        raise InputError(f"temporary folder {folder}: {exc.strerror or exc}") from None
    if free < need:
        raise InputError(f"temporary folder {folder} has {_size(free)} free and one render call writes up to "
                         f"{_size(need)} of images; free some space or point TMPDIR elsewhere")
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_FSIZE)
    except (ImportError, OSError, ValueError):
        return
    if soft != resource.RLIM_INFINITY and soft < budget.exr_bytes:
        raise InputError(f"this process may write files of at most {_size(soft)} (ulimit -f) and one "
                         f"{budget.width}x{budget.height} image file takes {_size(budget.exr_bytes)}; raise the limit "
                         f"or use a smaller --resolution")


def check_scheduler_answers(address: str, timeout_s: float = SCHEDULER_TIMEOUT_S) -> None:
    """Refuse a Dask scheduler address where nothing answers within ``timeout_s``."""
    from headless.farm import check_scheduler

    host, _, port = check_scheduler(address).split("://", 1)[1].rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise InputError(f"--scheduler {address!r}: expected an address like tcp://HOST:PORT")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s):
            pass
    except socket.timeout:
        raise InputError(f"--scheduler {address}: nothing answered within {timeout_s:g} s; is the scheduler "
                         f"running and reachable?") from None
    except OSError as exc:
        raise InputError(f"--scheduler {address}: cannot connect ({exc.strerror or exc}); start a scheduler "
                         f"there (dask scheduler) or use --workers N for a local cluster") from None
    _check_speaks_dask(address, timeout_s)


def _check_speaks_dask(address: str, timeout_s: float) -> None:
    """Something accepts connections at ``address``: refuse it unless a Dask scheduler answers
    there within ``timeout_s`` (+ a grace). A program that accepts and stays silent (a stopped
    scheduler, another service on the port) would hang Dask's client: its handshake has no
    time limit of its own, so it runs on a daemon thread that is given up on."""
    import threading

    answer: dict = {}

    def handshake():
        try:
            from dask.distributed import Client

            client = Client(address, timeout=f"{timeout_s}s", set_as_default=False)
            try:
                answer["workers"] = len(client.scheduler_info().get("workers", {}))
            finally:
                client.close()
        except BaseException as exc:  # noqa: BLE001 - whatever it is, it is not a scheduler answering
            answer["error"] = exc

    thread = threading.Thread(target=handshake, name="scheduler-handshake", daemon=True)
    thread.start()
    thread.join(timeout_s + SCHEDULER_GRACE_S)
    if thread.is_alive():
        raise InputError(f"--scheduler {address}: something accepts connections there but no Dask scheduler "
                         f"answered within {timeout_s + SCHEDULER_GRACE_S:g} s (a stopped scheduler, or another "
                         f"program on that port)")
    if "error" in answer:
        exc = answer["error"]
        raise InputError(f"--scheduler {address}: what answers there is not a Dask scheduler "
                         f"({type(exc).__name__}); give the address `dask scheduler` prints") from None


def check_scan(config, out: str | Path, *, names=(), farm: bool = False, scheduler: str | None = None,
               force: bool = False, local_workers: int = 1, frames: int | None = None,
               profiles: int | None = None) -> None:
    """Every check above for a scan of ``config`` into ``out`` (``local_workers``: the processes a
    local farm renders in side by side; ``frames``: the frames this machine renders, where not
    the whole path: a farm task's shard, none for a merge or where a scheduler's workers
    render; ``profiles``: the frames rendered in place of the path's, an adaptive scan's
    budget, which ignores the config's [[path]])."""
    check_output_folder(out, names, "--out", config.input_files())
    if farm:
        shards = Path(out) / "shards"
        if shards.exists() and not shards.is_dir():
            raise InputError(f"--out {out}: {shards} is a file where the farm keeps its shard files; move it away")
        if shards.is_dir():  # (made by the farm otherwise, where --out is writable)
            check_output_folder(shards, (), "the farm's shards folder")
    if scheduler is not None:
        check_scheduler_answers(scheduler)
    budget = render_budget(config)
    if profiles is not None:
        budget = replace(budget, frames=int(profiles))
    if frames is not None:
        if frames < 1:
            return  # nothing rendered here
        budget = replace(budget, frames=min(int(frames), budget.frames))
    check_render_size(budget, force, workers=max(1, min(int(local_workers), budget.frames)))
    check_temp_room(budget)
