"""The extension manifest passes Blender's own validator and lists wheels for every supported Python."""

import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from headless.build_extension import (blender_ext_tool, check_pythons, supported_pythons, wheel_for, wheel_platforms,
                                      wheel_python, wheel_serves)

REPO = Path(__file__).resolve().parents[1]
MANIFEST = tomllib.loads((REPO / "blender_manifest.toml").read_text())
WHEELS = [Path(w).name for w in MANIFEST["wheels"]]


def test_manifest_validates():
    pytest.importorskip("bpy", reason="Blender's extension tool ships inside bpy (installed by the README's set-up)")
    out = subprocess.run([sys.executable, str(blender_ext_tool()), "validate", str(REPO)],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "Success" in out.stdout


def test_oldest_blender_is_the_older_lts():
    assert MANIFEST["blender_version_min"] == "4.5.0"


def test_every_compiled_wheel_comes_for_each_supported_python():
    assert supported_pythons() == ["3.11", "3.13"]
    check_pythons(WHEELS, MANIFEST["platforms"], supported_pythons())  # raises with the gaps named
    for platform in MANIFEST["platforms"]:
        for package in ("scipy", "lxml"):  # lxml (for URDF files) serves both Macs with universal2 wheels
            wheels = [w for w in WHEELS if w.startswith(package + "-") and wheel_for(w, [platform])]
            assert sorted(wheel_python(w) for w in wheels) == ["3.11", "3.13"], (package, platform)


def test_a_missing_python_is_named():
    only_311 = [w for w in WHEELS if wheel_python(w) != "3.13"]
    with pytest.raises(SystemExit, match=r"scipy for CPython 3.13 on linux-x64"):
        check_pythons(only_311, ["linux-x64"], ["3.11", "3.13"])


def test_a_stable_abi_wheel_serves_its_python_and_later_ones_only():
    """libigl ships cp311 for Blender 4.5 and cp312-abi3 for 5.1 and 5.2, as Blender's installer
    picks them; without its cp311 wheel, 3.11 has none."""
    abi3 = "libigl-2.6.3-cp312-abi3-win_amd64.whl"
    assert wheel_serves(abi3, "3.13") and wheel_serves(abi3, "3.12") and not wheel_serves(abi3, "3.11")
    assert wheel_serves("libigl-2.6.3-cp311-cp311-win_amd64.whl", "3.11")
    assert not wheel_serves("libigl-2.6.3-cp311-cp311-win_amd64.whl", "3.13")
    assert wheel_serves("trimesh-5.2.0-py3-none-any.whl", "3.11")
    without = [w for w in WHEELS if not w.startswith("libigl-2.6.3-cp311")]
    with pytest.raises(SystemExit, match=r"libigl for CPython 3.11 on linux-x64"):
        check_pythons(without, ["linux-x64"], ["3.11", "3.13"])


def test_wheel_tags_are_read_from_file_names():
    assert wheel_python("scipy-1.17.1-cp313-cp313-win_amd64.whl") == "3.13"
    assert wheel_python("opencv_contrib_python_headless-5.0.0.93-cp37-abi3-win_amd64.whl") is None
    assert wheel_python("trimesh-5.2.0-py3-none-any.whl") is None
    assert wheel_platforms("trimesh-5.2.0-py3-none-any.whl") is None
    assert wheel_platforms("lxml-6.1.3-cp313-cp313-macosx_10_13_universal2.whl") == ("macos-arm64", "macos-x64")
    assert wheel_platforms("scipy-1.17.1-cp313-cp313-macosx_12_0_arm64.whl") == ("macos-arm64",)
    assert not wheel_for("scipy-1.17.1-cp313-cp313-win_amd64.whl", ["linux-x64"])

# The built zip's contents, its install and removal: tests/extension/test_install.py.
