"""``python -m headless``: see headless/cli.py."""

import os
import sys

from headless.bootstrap import missing_package_line

try:
    from headless.cli import main

    code = main(exiting=True)
except ModuleNotFoundError as exc:
    line = missing_package_line(exc)
    if line is None:  # one of the project's own modules: a bug, not the user's set-up
        raise
    print(line, file=sys.stderr)
    code = 2
# The command is over and everything it writes is written: leave now. The interpreter's own
# teardown (modules, Blender's and Dask's exit hooks) takes tens of milliseconds in which a
# Ctrl-C, with Python's handler back, kills the process by the signal (or prints a traceback
# from a thread's join) after a scan that finished and wrote its results.
try:
    sys.stdout.flush()
    sys.stderr.flush()
except (BrokenPipeError, OSError):  # whoever read the output has gone (see cli.main)
    pass
os._exit(code)
