"""``python -m headless``: see headless/cli.py."""

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
sys.exit(code)
