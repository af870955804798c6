"""The set-up step installs once and is skipped while the lock file is unchanged."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from headless import bootstrap

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def fake_repo(tmp_path, monkeypatch):
    venv = tmp_path / ".venv"
    (venv / "bin").mkdir(parents=True)
    (venv / "bin" / "python").write_text("")
    lock = tmp_path / "requirements.txt"
    lock.write_text("numpy==1.26.4\n")
    monkeypatch.setattr(bootstrap, "VENV", venv)
    monkeypatch.setattr(bootstrap, "LOCK", lock)
    monkeypatch.setattr(bootstrap, "STAMP", venv / ".installed-lock.sha256")
    calls = []
    monkeypatch.setattr(bootstrap.subprocess, "call", lambda cmd, cwd=None: calls.append(cmd) or 0)
    return lock, calls


def test_installs_once_then_skips(fake_repo):
    lock, calls = fake_repo
    bootstrap.ensure_venv()
    assert len(calls) == 1 and "install" in calls[0]
    bootstrap.ensure_venv()
    bootstrap.ensure_venv()
    assert len(calls) == 1  # nothing re-installed


def test_reinstalls_when_the_lock_changes(fake_repo):
    lock, calls = fake_repo
    bootstrap.ensure_venv()
    lock.write_text("numpy==1.26.4\ntrimesh==4.12.2\n")
    bootstrap.ensure_venv()
    assert len(calls) == 2


def test_failed_install_leaves_no_stamp(fake_repo, monkeypatch):
    lock, calls = fake_repo
    monkeypatch.setattr(bootstrap.subprocess, "call", lambda cmd, cwd=None: 1)
    with pytest.raises(SystemExit, match="failed"):
        bootstrap.ensure_venv()
    assert not bootstrap.STAMP.exists()


def test_no_tests_collected_is_not_a_failure(fake_repo, monkeypatch):
    monkeypatch.setattr(bootstrap, "ensure_python", lambda: None)
    monkeypatch.setattr(bootstrap, "run_in_foreground",
                        lambda cmd: bootstrap.PYTEST_NO_TESTS if "pytest" in cmd else 0)
    assert bootstrap.main(["test", "-k", "nothing_matches"]) == 0


@pytest.mark.parametrize("args, spread", [
    ((), True), (("tests/core", "-k", "ik"), True), (("-n", "0"), False), (("-n3",), False),
    (("--numprocesses=2",), False), (("--pdb",), False), (("-p", "no:xdist"), False), (("-pno:xdist",), False),
    (("-s",), False), (("--dist", "load"), False), (("--dist=worksteal",), False),
])
def test_the_suite_is_spread_over_the_cpus_unless_the_arguments_choose(fake_repo, monkeypatch, args, spread):
    import addon.core.machine

    ran = []
    monkeypatch.setattr(addon.core.machine, "usable_cpus", lambda: 2)
    monkeypatch.setattr(bootstrap, "ensure_python", lambda: None)
    monkeypatch.setattr(bootstrap, "run_in_foreground", lambda cmd: ran.append(cmd) or 0)
    assert bootstrap.main(["test", *args]) == 0
    pytest_args = ran[0][ran[0].index("pytest") + 1:]
    assert pytest_args[:len(args)] == list(args)
    assert ("--dist" in pytest_args and "loadfile" in pytest_args) == spread, pytest_args
    assert pytest_args.count("-n") + sum(a.startswith("-n") and a != "-n" for a in pytest_args) <= 1
    assert pytest_args[pytest_args.index("-n") + 1] == "2" if spread else True


def test_pytest_addopts_that_choose_workers_are_kept(fake_repo, monkeypatch):
    import addon.core.machine

    monkeypatch.setattr(addon.core.machine, "usable_cpus", lambda: 2)
    monkeypatch.setenv("PYTEST_ADDOPTS", "-p no:xdist")
    assert bootstrap.spread_over_cpus(["tests/core"]) == ["tests/core"]
    monkeypatch.setenv("PYTEST_ADDOPTS", "-x")
    assert "-n" in bootstrap.spread_over_cpus(["tests/core"])


def test_a_path_that_does_not_exist_fails_spread_or_not(fake_repo, monkeypatch):
    """Spread over workers, pytest says "no tests ran" (exit 5) of a missing path, which the
    test command took for a selection without tests and passed (a review)."""
    import addon.core.machine

    ran = []

    def pytest_says(cmd):
        ran.append(cmd)
        return 5 if "-n" in cmd else 4  # as pytest 9 with xdist 3.8 answer a missing path

    monkeypatch.setattr(addon.core.machine, "usable_cpus", lambda: 2)
    monkeypatch.setattr(bootstrap, "ensure_python", lambda: None)
    monkeypatch.setattr(bootstrap, "run_in_foreground", pytest_says)
    assert bootstrap.main(["test", "tests/renamed.py"]) == 4
    assert "--collect-only" in ran[1] and "-n" not in ran[1]


@pytest.mark.parametrize("cpus, workers", [(1, None), (3, "3"), (64, "4")])
def test_the_suite_takes_a_worker_per_usable_cpu_up_to_four(fake_repo, monkeypatch, cpus, workers):
    import addon.core.machine

    ran = []
    monkeypatch.setattr(addon.core.machine, "usable_cpus", lambda: cpus)
    monkeypatch.setattr(bootstrap, "ensure_python", lambda: None)
    monkeypatch.setattr(bootstrap, "run_in_foreground", lambda cmd: ran.append(cmd) or 0)
    assert bootstrap.main(["test"]) == 0
    got = ran[0][ran[0].index("-n") + 1] if "-n" in ran[0] else None
    assert got == workers, ran[0]


def test_a_child_in_the_foreground_gets_the_ctrl_c_and_its_exit_code_comes_back():
    # The terminal's Ctrl-C reaches parent and child alike; the parent must neither die of it
    # nor kill the child, which stops in its own time and whose exit code comes back.
    import signal
    import time

    script = (
        "import os, signal, sys, time\n"
        "from headless import bootstrap\n"
        "child = ('import signal, sys, time\\n'\n"
        "         'signal.signal(signal.SIGINT, lambda s, f: (time.sleep(0.5), sys.exit(130)))\\n'\n"
        "         'print(\"ready\", flush=True); time.sleep(30)')\n"
        "sys.exit(bootstrap.run_in_foreground([sys.executable, '-c', child]))\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", script], cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    assert proc.stdout.readline().strip() == "ready"
    time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGINT)  # as the terminal does: the whole foreground group
    out, err = proc.communicate(timeout=20)
    assert proc.returncode == 130, (proc.returncode, err)
    assert "Traceback" not in err


def test_help_runs_on_plain_python():
    out = subprocess.run([sys.executable, "-m", "headless.bootstrap", "--help"], cwd=REPO,
                         capture_output=True, text=True)
    assert out.returncode == 0 and "python3 -m headless.bootstrap test" in out.stdout


def test_finds_the_running_interpreter_and_refuses_a_missing_one(monkeypatch):
    assert bootstrap.find_python(tuple(sys.version_info[:2])) == sys.executable
    monkeypatch.setenv("PATH", "")
    monkeypatch.setenv("PYENV_ROOT", "/nonexistent")
    assert bootstrap.find_python((2, 1)) is None


def test_a_wrong_python_gets_one_line_naming_the_one_needed(tmp_path):
    # Pretend no CPython 3.13 exists anywhere: only the wrong interpreter is there to run.
    # The wrong interpreter is Blender 4.5's CPython 3.11, which the extension tests need anyway.
    wrong = bootstrap.find_python((3, 11))
    assert wrong, "CPython 3.11 (Blender 4.5 LTS's Python) is needed by this suite"
    env = {"PATH": str(tmp_path), "PYENV_ROOT": str(tmp_path), "HOME": str(tmp_path)}
    out = subprocess.run([wrong, "-m", "headless.bootstrap", "test"], cwd=REPO, env=env,
                         capture_output=True, text=True)
    assert out.returncode != 0
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "needs CPython 3.13" in lines[0], out.stderr


def test_a_pyenv_shim_that_does_not_run_is_passed_over(tmp_path, monkeypatch):
    shim = tmp_path / "bin" / "python3.13"
    shim.parent.mkdir()
    shim.write_text("#!/bin/sh\necho 'pyenv: python3.13: command not found' >&2\nexit 127\n")
    shim.chmod(0o755)
    monkeypatch.setenv("PATH", str(shim.parent))
    monkeypatch.setenv("PYENV_ROOT", str(tmp_path / "pyenv"))
    monkeypatch.setattr(bootstrap.sys, "version_info", (3, 0, 0))
    assert bootstrap.find_python((3, 13)) in (None, "/usr/local/bin/python3.13", "/usr/bin/python3.13")


def test_python_m_headless_outside_the_venv_says_in_one_line_which_package_is_missing_and_where_it_is():
    # The interpreter .venv was made from stands in for the system's python3: it lacks the
    # project's packages (numpy, OpenCV, ...).
    base = Path(sys.base_prefix) / ("python.exe" if os.name == "nt" else "bin/python3")
    done = subprocess.run([str(base), "-m", "headless", "demo"], cwd=bootstrap.REPO, capture_output=True, text=True,
                          timeout=120, env={k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")})
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    assert "has no '" in lines[0] and "(package " in lines[0], lines[0]
    assert "-m headless" in lines[0] and "headless.bootstrap" in lines[0]


def test_a_missing_module_is_blamed_on_the_set_up_only_where_the_lock_pins_it(monkeypatch):
    # Inside .venv: a package the lock pins but .venv lacks (removed after set-up, which the
    # stamp cannot see) is named with how to install the lock again; a module the lock does
    # not pin, or the project's own, is a bug and shown as one.
    monkeypatch.setattr(sys, "prefix", str(bootstrap.VENV))
    line = bootstrap.missing_package_line(ModuleNotFoundError("no", name="cv2"))
    assert line.startswith("error: .venv has no 'cv2' (package opencv-contrib-python-headless), which "
                           "requirements.txt pins") and ".installed-lock.sha256" in line, line
    assert bootstrap.missing_package_line(ModuleNotFoundError("no", name="fcl.collision")) is not None
    assert bootstrap.missing_package_line(ModuleNotFoundError("no", name="nothing_we_pin")) is None
    assert bootstrap.missing_package_line(ModuleNotFoundError("no", name="addon.core.nothing")) is None
    monkeypatch.setattr(sys, "prefix", "/usr")
    assert bootstrap.missing_package_line(ModuleNotFoundError("no", name="addon.core.nothing")) is None
    line = bootstrap.missing_package_line(ModuleNotFoundError("no", name="cv2"))
    assert "'cv2' (package opencv-contrib-python-headless)" in line
    assert "package python-fcl" in bootstrap.missing_package_line(ModuleNotFoundError("no", name="fcl"))


def test_an_environment_made_by_another_python_or_without_pip_is_made_again(tmp_path):
    """A set-up stopped while it made .venv left one without pip, which every later run failed
    on ("No module named pip"); a .venv made by another Python took the packages of this one's
    lock (bpy 5.2 has none for 3.12) and was never named as the cause."""
    import subprocess
    import sys

    from headless import bootstrap

    assert bootstrap._unusable(tmp_path / "none", tmp_path / "none" / "bin" / "python", sys.version) == ""
    other = tmp_path / "other"
    (other / "bin").mkdir(parents=True)
    (other / "bin" / "python").write_text("")
    (other / "pyvenv.cfg").write_text("home = /usr/bin\nversion = 3.11.2\n")
    assert "made by Python 3.11" in bootstrap._unusable(other, other / "bin" / "python", "3.13.0 (main)")
    assert bootstrap._unusable(Path(sys.prefix), Path(sys.executable), sys.version) is None  # this very one
    bare = tmp_path / "bare"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(bare)], check=True)
    assert not bootstrap._has_pip(bare) and bootstrap._has_pip(Path(sys.prefix))


def test_an_install_that_fails_for_want_of_pip_makes_the_environment_again(fake_repo, monkeypatch):
    lock, calls = fake_repo
    made = []
    monkeypatch.setattr(bootstrap, "_make_env", lambda venv_dir, python, version, why: made.append(why))
    results = iter([1, 0])  # pip missing the first time, the install through after the environment is made
    monkeypatch.setattr(bootstrap.subprocess, "call", lambda cmd, cwd=None: calls.append(cmd) or next(results))
    bootstrap.ensure_venv()
    assert len(calls) == 2 and made == [" (the one there has no pip: a set-up stopped while making it)"]
    assert bootstrap.STAMP.exists()
