"""Blender's own log on file descriptor 1, kept off the terminal of a headless run.

Blender writes its log ("Fra: ...", "Saved: '...exr'", Cycles' "CUEW initialization failed",
the colour management's "Using OCIO=..." when the OCIO variable is set) from C, below
Python's ``sys.stdout``; a command whose stdout is its report must not carry it. This module
needs nothing of Blender's itself: the package's ``__init__`` imports bpy through it.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile


@contextlib.contextmanager
def blender_output_captured(kept: list | None = None):
    """Keep Blender's per-frame log lines ("Fra: ...", "Saved: '...exr'") off the terminal.

    Blender writes them to file descriptor 1 from C, below Python's ``sys.stdout``, so the
    descriptor itself is pointed at a temporary file for the call; should the render fail,
    the last lines of that log go into the error. ``kept``: a list that gets what was written,
    as text, for a caller that passes some of it on.
    """
    if sys.stdout is not None:  # (None with stdout closed: a daemon's, a cron job's)
        sys.stdout.flush()
    try:
        saved = os.dup(1)
    except OSError:  # no descriptor 1 (a GUI without a console): nothing to keep quiet
        yield
        return
    with tempfile.TemporaryFile(prefix="scanner-blender-log-") as log:
        os.dup2(log.fileno(), 1)
        try:
            yield
        except Exception as exc:
            os.dup2(saved, 1)
            log.seek(0)
            tail = log.read()[-2000:].decode(errors="replace").strip()
            if tail:
                exc.add_note("Blender's log ended with:\n" + tail)
            raise
        finally:
            os.dup2(saved, 1)
            os.close(saved)
            if kept is not None:
                log.seek(0)
                kept.append(log.read().decode(errors="replace"))
