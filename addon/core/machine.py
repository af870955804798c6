"""What this process may use of the machine it runs on."""

from __future__ import annotations

import os


def usable_cpus() -> int:
    """The CPUs this process may run on: its affinity mask (taskset, a batch system's cgroup
    cpuset), not the machine's count, which a Slurm job on a large node would oversubscribe
    with one thread per core it does not have. CPython 3.13's ``os.process_cpu_count``,
    or the affinity mask where that is missing (Blender 4.5's CPython 3.11)."""
    counted = getattr(os, "process_cpu_count", None)
    if counted is not None:
        return max(1, counted() or 1)
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # (no affinity on macOS, Windows)
        return max(1, os.cpu_count() or 1)
