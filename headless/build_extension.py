"""``python -m headless build-extension``: the extension zips, one per platform.

The manifest lists the wheels of every platform, pinned by file name. This
downloads the wheels the requested platforms need into ``wheels/`` (not in git),
checks that every compiled package has a wheel for each supported Blender's Python
on each platform, stages the add-on with a manifest trimmed to those platforms, and
builds and validates with Blender's own extension tool (``blender_ext.py``).

Nothing here names a Blender or Python version: the Pythons come from the supported
Blender releases (``headless.bootstrap.BLENDER_ENVS``, or ``--pythons``), and the
extension tool is the one inside the installed bpy (or ``--blender-ext`` /
``$BLENDER_EXT_TOOL``).
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

from headless.preflight import folder_argument

REPO = Path(__file__).resolve().parent.parent
WHEELS = REPO / "wheels"
PLATFORMS = ("linux-x64", "windows-x64", "macos-arm64", "macos-x64")


def supported_pythons() -> list[str]:
    """The CPython versions of the supported Blender releases, e.g. ["3.11", "3.13"]."""
    from headless.bootstrap import BLENDER_ENVS

    return sorted({"%d.%d" % v for v in BLENDER_ENVS.values()}, key=lambda s: tuple(map(int, s.split("."))))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--platforms", nargs="+", default=list(PLATFORMS), choices=PLATFORMS,
                        help="platforms to build for (default: all four)")
    parser.add_argument("--out", default="dist", type=folder_argument, help="folder for the zips (default dist/)")
    parser.add_argument("--pythons", nargs="+", default=None, metavar="X.Y", type=python_version,
                        help="CPython versions the zip must carry compiled wheels for "
                             "(default: those of the supported Blender releases)")
    parser.add_argument("--blender-ext", default=os.environ.get("BLENDER_EXT_TOOL"), metavar="PATH",
                        help="Blender's blender_ext.py (default: $BLENDER_EXT_TOOL, else the one in the installed bpy)")
    parser.set_defaults(run=run)


def python_version(text: str) -> str:
    """argparse type of --pythons: a CPython version as X.Y (3.11)."""
    if not re.fullmatch(r"3\.\d{1,2}", text):
        raise argparse.ArgumentTypeError(f"expected a CPython version as X.Y (e.g. 3.11), got {text!r}")
    return text


def blender_ext_tool(explicit: str | None = None) -> Path:
    """Blender's own extension tool: the given path, else the one inside the installed bpy
    (``bpy/<major.minor>/scripts/addons_core/bl_pkg/cli/blender_ext.py``)."""
    if explicit:
        tool = Path(explicit)
        if not tool.is_file():
            from addon.core.errors import InputError

            raise InputError(f"--blender-ext {tool}: no such file (Blender's blender_ext.py, inside bpy at "
                             f"<version>/scripts/addons_core/bl_pkg/cli/)")
        return tool
    spec = importlib.util.find_spec("bpy")  # locate the package without starting Blender
    if spec is None or not spec.origin:
        sys.exit("error: bpy is not installed; run the set-up first (python3 -m headless.bootstrap test) "
                 "or give --blender-ext PATH")
    found = sorted(Path(spec.origin).parent.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
    if not found:
        sys.exit(f"error: no blender_ext.py inside {Path(spec.origin).parent}; give --blender-ext PATH")
    return found[-1]


def _cpython(filename: str) -> tuple[tuple[int, int] | None, str]:
    """(the CPython version of a wheel's python tag, (3, 13), or None where it names none; its
    abi tag)."""
    python_tag, abi_tag = filename[:-4].split("-")[-3:-1]
    return ((int(python_tag[2]), int(python_tag[3:])) if python_tag.startswith("cp") else None), abi_tag


def wheel_python(filename: str) -> str | None:
    """The CPython version a compiled wheel is for ("3.13"), or None for abi3 and pure-Python wheels."""
    version, abi_tag = _cpython(filename)
    return None if version is None or abi_tag in ("abi3", "none") else "%d.%d" % version


def wheel_serves(filename: str, python: str) -> bool:
    """Whether a wheel installs on CPython ``python`` ("3.13"), as Blender judges it: a
    compiled wheel on its own version, a stable-ABI one (cp312-abi3) on its version and later,
    a pure-Python one on any."""
    version, abi_tag = _cpython(filename)
    if version is not None and abi_tag == "abi3":
        return tuple(int(x) for x in python.split(".")) >= version
    return wheel_python(filename) in (None, python)


def check_pythons(wheels: list[str], platforms: list[str], pythons: list[str]) -> None:
    """Every compiled package has a wheel for each Python on each platform, or Blender will
    refuse to enable the extension on the releases that lack one."""
    missing = []
    for platform in platforms:
        for_platform = [w for w in wheels if wheel_for(w, [platform])]
        # (compiled: a CPython tag, for one version or, abi3, from one version on)
        compiled = {w.split("-")[0] for w in for_platform if _cpython(w)[0] is not None}
        for package in sorted(compiled):
            own = [w for w in for_platform if w.split("-")[0] == package]
            missing += [f"{package} for CPython {py} on {platform}" for py in pythons
                        if not any(wheel_serves(w, py) for w in own)]
    if missing:
        raise SystemExit("error: blender_manifest.toml lists no wheel of " + "; ".join(missing))


def wheel_platforms(filename: str) -> tuple[str, ...] | None:
    """The Blender platforms a wheel file is for; None for pure-Python wheels (all platforms).
    A macOS universal2 wheel serves both Macs, as Blender's own tool reads it."""
    tag = filename[:-4].split("-")[-1]
    if tag == "any":
        return None
    if "manylinux" in tag or "linux" in tag:
        return ("linux-x64",)
    if "win_amd64" in tag:
        return ("windows-x64",)
    if "macosx" in tag:
        if tag.endswith("universal2"):
            return ("macos-arm64", "macos-x64")
        return ("macos-arm64",) if tag.endswith("arm64") else ("macos-x64",)
    raise SystemExit(f"error: cannot tell the platform of wheel {filename}")


def wheel_for(filename: str, platforms) -> bool:
    """Whether the wheel belongs in a build for any of ``platforms``."""
    served = wheel_platforms(filename)
    return served is None or any(p in served for p in platforms)


def requirement_of(filename: str) -> str:
    name, version = filename.split("-")[:2]
    return f"{name.replace('_', '-')}=={version}"


def fetch(wheel: str) -> Path:
    """Make sure ``wheels/<wheel>`` exists, downloading that exact file if needed (pip is
    given the file's own platform tags, so it finds that file and no other)."""
    target = WHEELS / wheel
    if target.is_file():
        return target
    WHEELS.mkdir(exist_ok=True)
    python = wheel_python(wheel) or "%d.%d" % sys.version_info[:2]
    cmd = [sys.executable, "-m", "pip", "download", "--disable-pip-version-check", "--no-deps", "--only-binary=:all:",
           "--python-version", python, "--implementation", "cp", "-d", str(WHEELS), requirement_of(wheel)]
    tags = wheel[:-4].split("-")[-1]
    for tag in (tags.split(".") if tags != "any" else []):
        cmd += ["--platform", tag]
    print(f"[wheels] downloading {wheel}", flush=True)
    if subprocess.call(cmd) != 0 or not target.is_file():
        raise SystemExit(f"error: could not download {wheel} (pip {' '.join(cmd[3:])})")
    return target


def staged_manifest(text: str, platforms: list[str], wheels: list[str]) -> str:
    """The manifest with only the given platforms and wheels."""
    text = re.sub(r"(?ms)^platforms\s*=\s*\[.*?\]", "platforms = [" + ", ".join(f'"{p}"' for p in platforms) + "]", text)
    return re.sub(r"(?ms)^wheels\s*=\s*\[.*?\]", "wheels = [\n" + "".join(f'  "./wheels/{w}",\n' for w in wheels) + "]",
                  text)


def build(platforms: list[str], out: Path, pythons: list[str] | None = None, tool: str | None = None) -> list[Path]:
    manifest_text = (REPO / "blender_manifest.toml").read_text()
    manifest = tomllib.loads(manifest_text)
    wheels = [Path(w).name for w in manifest.get("wheels", [])]
    needed = [w for w in wheels if wheel_for(w, platforms)]
    check_pythons(needed, platforms, pythons or supported_pythons())
    tool = blender_ext_tool(tool)
    from addon.core.files import check_output_folder

    check_output_folder(out, (), "--out")  # before the downloads
    for w in needed:
        fetch(w)
    out.mkdir(parents=True, exist_ok=True)
    made = []
    with tempfile.TemporaryDirectory(prefix="scanner-ext-") as tmp:
        stage = Path(tmp) / manifest["id"]
        stage.mkdir()
        shutil.copy2(REPO / "__init__.py", stage / "__init__.py")
        for folder in ("addon", "rigs"):
            shutil.copytree(REPO / folder, stage / folder, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        (stage / "wheels").mkdir()
        for w in needed:
            shutil.copy2(WHEELS / w, stage / "wheels" / w)
        (stage / "blender_manifest.toml").write_text(staged_manifest(manifest_text, platforms, needed))
        built = Path(tmp) / "built"  # then moved into --out: the zips of this run, not others there
        built.mkdir()
        for step in (["validate", str(stage)],
                     ["build", "--source-dir", str(stage), "--output-dir", str(built)]
                     + (["--split-platforms"] if len(platforms) > 1 else [])):
            res = subprocess.run([sys.executable, str(tool), *step], capture_output=True, text=True)
            if res.returncode != 0:
                raise SystemExit(f"error: blender_ext {step[0]} failed:\n{res.stdout}{res.stderr}")
        for z in sorted(built.glob("*.zip")):
            made.append(Path(shutil.move(str(z), str(out / z.name))))
    return made


def run(args: argparse.Namespace) -> int:
    zips = build(list(args.platforms), Path(args.out), args.pythons, args.blender_ext)
    for z in zips:
        print(f"built {z} ({z.stat().st_size / 1e6:.0f} MB)")
    return 0
