"""Set up ``.venv`` from the lock file, then run a command inside it.

Usage (from the repository root, with any Python 3; set-up finds CPython 3.13)::

    python3 -m headless.bootstrap demo            # set up, then: python -m headless demo
    python3 -m headless.bootstrap test [ARGS]     # set up, then: python -m pytest [ARGS] on every CPU (up to 4)
    python3 -m headless.bootstrap ANY ARGS        # set up, then: python -m headless ANY ARGS
    python3 -m headless.bootstrap blender-env 4.5 # set up a bare bpy of that Blender, print its python

The pipeline runs on Blender 5.2 LTS (bpy 5.2.x), which is built for CPython 3.13
only. Started with another interpreter, set-up looks for a CPython 3.13 (on PATH,
then in pyenv's and the usual install folders) and runs itself again under it; with
none, it stops with one line naming what it needs.

Set-up creates ``.venv`` and installs ``requirements.txt`` into it. A stamp file in
``.venv`` records a hash of the lock file and the interpreter, so a second run on a
machine that is already set up skips straight to the command. An interrupted install
leaves no stamp and is repeated on the next run.

``blender-env`` makes the bare Blender environments that tests/extension installs the
built extension into (``.venv-blender/<version>``: bpy and what bpy itself needs,
nothing of the project's), one per supported Blender release, each with its own
interpreter and lock (``headless/locks/blender-<version>.txt``).

This module uses the standard library only: it runs before anything is installed.
"""

from __future__ import annotations

import glob
import hashlib
import os
import signal
import subprocess
import sys
import venv
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
VENV = REPO / ".venv"
LOCK = REPO / "requirements.txt"
STAMP = VENV / ".installed-lock.sha256"
REQUIRED_PYTHON = (3, 13)  # bpy 5.2 LTS wheels exist for CPython 3.13 only

# The bare Blender environments of tests/extension: Blender release -> its CPython. The
# suite installs the extension into the two long-term releases; SCANNER_BLENDERS=all
# adds the others the extension supports.
BLENDER_ENVS = {"4.5": (3, 11), "5.0": (3, 11), "5.1": (3, 13), "5.2": (3, 13)}
LTS_RELEASES = ("4.5", "5.2")
BLENDER_ENV_ROOT = REPO / ".venv-blender"
LOCKS = Path(__file__).resolve().parent / "locks"

# pytest's exit code when it collected no tests at all.
PYTEST_NO_TESTS = 5


def venv_python(venv_dir: Path = None) -> Path:
    venv_dir = VENV if venv_dir is None else venv_dir
    if os.name == "nt":
        return venv_dir / "Scripts" / "python.exe"
    return venv_dir / "bin" / "python"


def _identify(python: str) -> tuple[tuple[int, int], str] | None:
    """The (major, minor) an interpreter reports and its real executable (not a pyenv
    shim), or None where it does not run (a shim for a version not selected fails)."""
    try:
        out = subprocess.run([python, "-c", "import sys; print(sys.version_info[0], sys.version_info[1], "
                                            "sys.implementation.name, sys.executable)"],
                             capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return None
    parts = out.stdout.strip().split(" ", 3)
    if out.returncode != 0 or len(parts) != 4 or parts[2] != "cpython":
        return None
    return (int(parts[0]), int(parts[1])), parts[3]


def find_python(version: tuple[int, int]) -> str | None:
    """A CPython of ``version`` on this machine: ``pythonX.Y`` on PATH, then pyenv's and
    the usual install folders. None if there is none that runs."""
    if sys.version_info[:2] == version and sys.implementation.name == "cpython":
        return sys.executable
    name = "python%d.%d" % version
    candidates = []
    for folder in os.environ.get("PATH", "").split(os.pathsep):
        if folder:
            candidates.append(os.path.join(folder, name))
    pyenv_root = os.environ.get("PYENV_ROOT") or os.path.expanduser("~/.pyenv")
    candidates += sorted(glob.glob(os.path.join(pyenv_root, "versions", "%d.%d*" % version, "bin", name)),
                         reverse=True)
    candidates += [f"/usr/local/bin/{name}", f"/usr/bin/{name}", f"/opt/homebrew/bin/{name}"]
    seen = set()
    for cand in candidates:
        if cand in seen or not os.path.isfile(cand):
            continue
        seen.add(cand)
        found = _identify(cand)
        if found and found[0] == version:
            return found[1]
    return None


def ensure_python() -> None:
    """Re-run under CPython 3.13 when started with another interpreter."""
    if sys.version_info[:2] == REQUIRED_PYTHON:
        return
    want = "%d.%d" % REQUIRED_PYTHON
    other = find_python(REQUIRED_PYTHON)
    if other and os.environ.get("_SCANNER_BOOTSTRAP_REEXEC") != "1":
        os.environ["_SCANNER_BOOTSTRAP_REEXEC"] = "1"
        # Replaced, not waited for: a Ctrl-C then reaches one process, not a parent that
        # would kill the command when its own wait is interrupted.
        sys.stdout.flush()
        sys.stderr.flush()
        os.chdir(REPO)
        os.execv(other, [other, "-m", "headless.bootstrap", *sys.argv[1:]])
    sys.exit(f"error: this project needs CPython {want} (bpy 5.2 LTS is built for it only); found "
             f"{sys.version.split()[0]} and no python{want} on PATH or in pyenv: install CPython {want} "
             f"(e.g. 'pyenv install {want}') and run the same command again")


def _digest(lock: Path, python_version: str) -> str:
    h = hashlib.sha256()
    h.update(lock.read_bytes())
    h.update(python_version.encode())
    return h.hexdigest()


def ensure_venv() -> None:
    _ensure_env(VENV, LOCK, STAMP, sys.executable, sys.version,
                "the first time downloads about 600 MB, mostly bpy")


# Import names of the lock's packages that differ from the package's name.
PACKAGE_OF_MODULE = {"cv2": "opencv-contrib-python-headless", "fcl": "python-fcl", "igl": "libigl",
                     "yaml": "pyyaml", "PIL": "pillow", "sklearn": "scikit-learn"}


def _locked(package: str) -> bool:
    """Whether the lock (requirements.txt) pins this package."""
    def norm(text: str) -> str:
        return text.strip().lower().replace("_", "-")

    try:
        lines = LOCK.read_text(encoding="utf-8").splitlines()
    except OSError:
        return False
    return any(norm(line.split("==")[0]) == norm(package) for line in lines if "==" in line)


def missing_package_line(exc: ModuleNotFoundError) -> str | None:
    """One line for ``python -m headless`` started with a Python that lacks a package of the
    lock: outside .venv, which one and the two commands that have it; inside .venv (a package
    removed after set-up, which the stamp cannot see), how to install the lock again. None
    where the module missing is the project's own or one the lock does not pin (a bug, shown
    as one)."""
    name = (exc.name or "").split(".")[0]
    if not name or name in ("addon", "headless"):
        return None  # the project's own module: a bug, shown as one
    package = PACKAGE_OF_MODULE.get(name, name)
    if Path(sys.prefix).resolve() == VENV.resolve():
        if not _locked(package):
            return None
        return (f"error: .venv has no '{name}' (package {package}), which {_shown(LOCK)} pins: the environment "
                f"was changed after set-up; delete {_shown(STAMP)} and run 'python3 -m headless.bootstrap ...', "
                f"which installs the lock again")
    here = _shown(venv_python())
    return (f"error: this Python ({sys.executable}) has no '{name}' (package {package}); the project's "
            f"packages are in .venv: run '{here} -m headless ...', or 'python3 -m headless.bootstrap ...', "
            f"which sets .venv up first")


def _shown(path: Path) -> Path:
    """A path as the user would type it from the repository root."""
    return path.relative_to(REPO) if path.is_relative_to(REPO) else path


def _ensure_env(venv_dir: Path, lock: Path, stamp: Path, python: str, python_version: str, size_hint: str) -> None:
    digest = _digest(lock, python_version)
    py = venv_python(venv_dir)
    if py.exists() and stamp.exists() and stamp.read_text().strip() == digest:
        return
    where = _shown(venv_dir)
    why = _unusable(venv_dir, py, python_version)
    if why is not None:
        _make_env(venv_dir, python, python_version, why)
    print(f"[setup] installing the pinned packages of {_shown(lock)} into {where} ({size_hint})",
          flush=True)
    try:
        stamp.unlink(missing_ok=True)
    except OSError as exc:
        sys.exit(f"error: cannot write in {where}: {exc.strerror or exc}; run the set-up in a checkout you can "
                 f"write to")
    cmd = [str(py), "-m", "pip", "install", "--disable-pip-version-check", "--progress-bar", "off",
           "-r", str(lock)]
    rc = subprocess.call(cmd, cwd=REPO)
    if rc != 0 and not _has_pip(venv_dir):  # a set-up stopped while it made the environment: made again
        _make_env(venv_dir, python, python_version, " (the one there has no pip: a set-up stopped while making it)")
        rc = subprocess.call(cmd, cwd=REPO)
    if rc != 0:
        sys.exit(f"error: installing {_shown(lock)} into {where} failed (pip exit code {rc}); "
                 "fix the cause above and run the same command again")
    try:
        stamp.write_text(digest + "\n")
    except OSError as exc:
        sys.exit(f"error: cannot write {_shown(stamp)}: {exc.strerror or exc}")
    print("[setup] done", flush=True)


def _make_env(venv_dir: Path, python: str, python_version: str, why: str) -> None:
    """Make the environment afresh (``why``: words for the log)."""
    where = _shown(venv_dir)
    print(f"[setup] creating {where} with Python {python_version.split()[0]}{why}", flush=True)
    try:
        if python == sys.executable:
            venv.EnvBuilder(with_pip=True, clear=True).create(venv_dir)
        else:
            rc = subprocess.call([python, "-m", "venv", "--clear", str(venv_dir)], cwd=REPO)
            if rc != 0:
                sys.exit(f"error: creating {where} with {python} failed (exit code {rc})")
    except OSError as exc:  # a read-only checkout, a full disk
        sys.exit(f"error: cannot create {where}: {exc.strerror or exc}; run the set-up in a checkout you can "
                 f"write to")


def _unusable(venv_dir: Path, py: Path, python_version: str) -> str | None:
    """Why the environment must be made afresh (words for the log; None: it can take the
    packages): none there (""), or made by another Python (its packages would not fit this
    one's lock, and bpy needs this one)."""
    if not py.exists():
        return "" if not venv_dir.exists() else " (the one there has no Python)"
    want = ".".join(python_version.split()[0].split(".")[:2])
    made = ""
    try:
        for line in (venv_dir / "pyvenv.cfg").read_text().splitlines():
            key, _, value = line.partition("=")
            if key.strip() in ("version", "version_info"):
                made = ".".join(value.strip().split(".")[:2])
                break
    except OSError:
        pass
    return f" (the one there was made by Python {made})" if made and made != want else None


def _has_pip(venv_dir: Path) -> bool:
    return any(venv_dir.glob("lib/python*/site-packages/pip"))


def ensure_blender_env(release: str) -> Path:
    """The interpreter of the bare bpy environment for a Blender release ("4.5", "5.2"),
    set up on first use and cached under ``.venv-blender/<release>``."""
    if release not in BLENDER_ENVS:
        sys.exit(f"error: no bare environment for Blender {release!r}; supported: {', '.join(BLENDER_ENVS)}")
    version = BLENDER_ENVS[release]
    python = find_python(version)
    if python is None:
        want = "%d.%d" % version
        sys.exit(f"error: Blender {release}'s bpy needs CPython {want}; no python{want} on PATH or in pyenv "
                 f"(install it, e.g. 'pyenv install {want}')")
    venv_dir = BLENDER_ENV_ROOT / release
    full_version = subprocess.run([python, "-c", "import sys; print(sys.version)"], capture_output=True,
                                  text=True).stdout.strip()
    _ensure_env(venv_dir, LOCKS / f"blender-{release}.txt", venv_dir / ".installed-lock.sha256", python,
                full_version, "about 400 MB the first time: bpy and what it needs")
    return venv_python(venv_dir)


def main(argv: list[str]) -> int:
    if not argv or argv[0] in ("-h", "--help"):
        print(__doc__)
        return 0 if argv else 2
    if argv[0] == "blender-env":
        if len(argv) != 2:
            sys.exit(f"error: blender-env takes one Blender release ({', '.join(BLENDER_ENVS)})")
        print(ensure_blender_env(argv[1]), flush=True)
        return 0
    ensure_python()
    ensure_venv()
    py = str(venv_python())
    if argv[0] == "test":
        args = spread_over_cpus(argv[1:])
        rc = run_in_foreground([py, "-m", "pytest", *args])
        if rc == PYTEST_NO_TESTS and args != argv[1:]:
            # Spread, pytest says "no tests ran" of a path that does not exist too: collected
            # again in one process, such a path is the usage error it is (exit 4).
            rc = run_in_foreground([py, "-m", "pytest", "--collect-only", "-q", *argv[1:]])
        if rc == PYTEST_NO_TESTS:
            print("[test] pytest collected no tests for this selection; nothing failed", flush=True)
            return 0
        return rc
    # The command becomes this process: a Ctrl-C or SIGTERM then reaches the scan alone, which
    # stops as it promises (the frames under way finished, nothing half-written, exit 130),
    # instead of a parent that would kill it when its own wait is interrupted.
    sys.stdout.flush()
    sys.stderr.flush()
    os.chdir(REPO)
    os.execv(py, [py, "-m", "headless", *argv])
    return 1  # not reached


# The suite's test files spread over the CPUs (pytest-xdist), each file on one worker so
# that its module fixtures (a built extension, a calibration's renders) are made once; at
# most SUITE_WORKERS workers, each of which may hold a Blender and its renders in memory.
SUITE_WORKERS = 4


def spread_over_cpus(args: list[str]) -> list[str]:
    """pytest's arguments with a worker per CPU this process may use added (its affinity
    mask: a batch job's share, not the node's count), unless there is one CPU, or the
    arguments (or PYTEST_ADDOPTS) choose their own workers or distribution (``-n 0`` runs
    the suite in one process, ``-p no:xdist`` leaves xdist out), or want the terminal
    (``--pdb``, ``--trace``; ``-s``, whose output workers would keep)."""
    import shlex

    from addon.core.machine import usable_cpus  # (standard library only, as here)

    workers = min(SUITE_WORKERS, usable_cpus())
    try:
        added = shlex.split(os.environ.get("PYTEST_ADDOPTS", ""))
    except ValueError:  # (pytest itself will say what is wrong with it)
        added = []
    for a in [*args, *added]:
        if (a in ("--pdb", "--trace", "-s", "--capture=no", "-d", "--tx") or a.endswith("no:xdist")
                or a.startswith(("-n", "--numprocesses", "--dist", "--tx="))):
            return list(args)
    if workers < 2:
        return list(args)
    return [*args, "-n", str(workers), "--dist", "loadfile"]


def run_in_foreground(cmd: list[str]) -> int:
    """Run ``cmd`` and wait for it, its exit code back (a signal's as 128 + its number). A
    Ctrl-C at the terminal reaches the child too (one process group): the parent ignores its
    own meanwhile and lets the child decide; a SIGTERM sent to the parent is passed on."""
    proc = subprocess.Popen(cmd, cwd=REPO)
    old = {signal.SIGINT: signal.signal(signal.SIGINT, signal.SIG_IGN),
           signal.SIGTERM: signal.signal(signal.SIGTERM, lambda signum, frame: proc.send_signal(signum))}
    try:
        rc = proc.wait()
    finally:
        for signum, handler in old.items():
            signal.signal(signum, handler)
    return 128 - rc if rc < 0 else rc


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
