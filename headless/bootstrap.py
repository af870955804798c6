"""Set up ``.venv`` from the lock file, then run a command inside it.

Usage (from the repository root, with CPython 3.11)::

    python3.11 -m headless.bootstrap demo            # set up, then: python -m headless demo
    python3.11 -m headless.bootstrap test [ARGS]     # set up, then: python -m pytest [ARGS]
    python3.11 -m headless.bootstrap ANY ARGS        # set up, then: python -m headless ANY ARGS

Set-up creates ``.venv`` and installs ``requirements.txt`` into it. A stamp file in
``.venv`` records a hash of the lock file and the interpreter, so a second run on a
machine that is already set up skips straight to the command. An interrupted install
leaves no stamp and is repeated on the next run.

This module uses the standard library only: it runs before anything is installed.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import venv
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
VENV = REPO / ".venv"
LOCK = REPO / "requirements.txt"
STAMP = VENV / ".installed-lock.sha256"
REQUIRED_PYTHON = (3, 11)  # bpy 5.0.1 wheels exist for CPython 3.11 only

# pytest's exit code when it collected no tests at all.
PYTEST_NO_TESTS = 5


def venv_python() -> Path:
    if os.name == "nt":
        return VENV / "Scripts" / "python.exe"
    return VENV / "bin" / "python"


def lock_digest() -> str:
    h = hashlib.sha256()
    h.update(LOCK.read_bytes())
    h.update(sys.version.encode())
    return h.hexdigest()


def ensure_python() -> None:
    """Re-run under python3.11 when started with another interpreter."""
    if sys.version_info[:2] == REQUIRED_PYTHON:
        return
    want = "python%d.%d" % REQUIRED_PYTHON
    other = shutil.which(want)
    if other and os.environ.get("_SCANNER_BOOTSTRAP_REEXEC") != "1":
        os.environ["_SCANNER_BOOTSTRAP_REEXEC"] = "1"
        sys.exit(subprocess.call([other, "-m", "headless.bootstrap", *sys.argv[1:]], cwd=REPO))
    sys.exit(
        f"error: this project needs CPython {REQUIRED_PYTHON[0]}.{REQUIRED_PYTHON[1]} "
        f"(bpy 5.0.1 is built for it only); found {sys.version.split()[0]} and no "
        f"'{want}' on PATH. Install it (e.g. 'pyenv install 3.11') and run "
        f"'{want} -m headless.bootstrap ...'."
    )


def ensure_venv() -> None:
    digest = lock_digest()
    if venv_python().exists() and STAMP.exists() and STAMP.read_text().strip() == digest:
        return
    if not venv_python().exists():
        print(f"[setup] creating {VENV.relative_to(REPO)} with Python {sys.version.split()[0]}", flush=True)
        venv.EnvBuilder(with_pip=True, clear=True).create(VENV)
    print(
        "[setup] installing the pinned packages from requirements.txt "
        "(the first time downloads about 500 MB, mostly bpy)",
        flush=True,
    )
    STAMP.unlink(missing_ok=True)
    cmd = [str(venv_python()), "-m", "pip", "install", "--disable-pip-version-check",
           "--progress-bar", "off", "-r", str(LOCK)]
    rc = subprocess.call(cmd, cwd=REPO)
    if rc != 0:
        sys.exit(f"error: installing requirements.txt into .venv failed (pip exit code {rc}); "
                 "fix the cause above and run the same command again")
    STAMP.write_text(digest + "\n")
    print("[setup] done", flush=True)


def main(argv: list[str]) -> int:
    if not argv or argv[0] in ("-h", "--help"):
        print(__doc__)
        return 0 if argv else 2
    ensure_python()
    ensure_venv()
    py = str(venv_python())
    if argv[0] == "test":
        rc = subprocess.call([py, "-m", "pytest", *argv[1:]], cwd=REPO)
        if rc == PYTEST_NO_TESTS:
            print("[test] pytest collected no tests for this selection; nothing failed", flush=True)
            return 0
        return rc
    return subprocess.call([py, "-m", "headless", *argv], cwd=REPO)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
