"""The extension builds from the manifest, and Blender's own installer installs, enables, runs,
disables and removes it, leaving nothing registered behind.

Runs in subprocesses with their own Blender user folder (BLENDER_USER_RESOURCES),
so the installed extension never touches the developer's Blender.
"""

import json
import os
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

pytest.importorskip("bpy", reason="the extension tests need bpy (installed by the README's set-up)")

REPO = Path(__file__).resolve().parents[2]

INSTALL = r"""
import json, sys
from pathlib import Path
import bpy, addon_utils
zip_path, pkg = sys.argv[1], "laser_scanner_sim"
module = "bl_ext.user_default." + pkg
out = {}
bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
out["enabled"] = module in bpy.context.preferences.addons
local = Path(bpy.utils.user_resource("EXTENSIONS")) / ".local" / "lib" / "python3.11" / "site-packages"
out["wheels"] = sorted(p.name for p in local.iterdir()) if local.is_dir() else []
import trimesh, cv2
out["trimesh_from"] = trimesh.__file__
out["ops"] = [str(bpy.ops.scanner.build_cell())]
s = bpy.context.scene.scanner
s.scan_config = "step_block"
s.output_dir = sys.argv[2]
out["ops"].append(str(bpy.ops.scanner.scan(frames="0:100:20")))
out["cloud_points"] = len(bpy.data.objects["Scan cloud"].data.vertices)
out["prefs"] = type(bpy.context.preferences.addons[module].preferences).__name__
bpy.ops.preferences.addon_disable(module=module)
out["after_disable"] = {"scene_prop": hasattr(bpy.types.Scene, "scanner"),
                        "classes": [n for n in dir(bpy.types) if n.startswith("SCANNER_")],
                        "enabled": module in bpy.context.preferences.addons}
repo_index = [r.module for r in bpy.context.preferences.extensions.repos].index("user_default")
bpy.ops.extensions.package_uninstall(repo_index=repo_index, pkg_id=pkg)
out["installed_after_uninstall"] = (Path(bpy.utils.user_resource("EXTENSIONS")) / "user_default" / pkg).exists()
print("RESULT " + json.dumps(out))
"""


@pytest.fixture(scope="module")
def linux_zip(tmp_path_factory):
    out = tmp_path_factory.mktemp("dist")
    res = subprocess.run([sys.executable, "-m", "headless", "build-extension", "--platforms", "linux-x64",
                          "--out", str(out)], cwd=REPO, capture_output=True, text=True)
    assert res.returncode == 0, res.stdout + res.stderr
    (zip_path,) = out.glob("*.zip")
    return zip_path


def test_manifest_pins_wheels_for_every_platform_and_never_numpy():
    manifest = tomllib.loads((REPO / "blender_manifest.toml").read_text())
    wheels = [Path(w).name for w in manifest["wheels"]]
    assert not [w for w in wheels if w.startswith("numpy")]
    for package in ("opencv_contrib_python_headless-4.11.0.86", "trimesh-4.12.2", "rtree-1.4.1", "scipy-1.17.1"):
        assert any(w.startswith(package) for w in wheels), package
    from headless.build_extension import wheel_platform

    covered = {wheel_platform(w) for w in wheels}
    assert set(manifest["platforms"]) <= covered | {None}
    for platform in manifest["platforms"]:
        names = {w.split("-")[0] for w in wheels if wheel_platform(w) in (platform, None)}
        assert {"opencv_contrib_python_headless", "trimesh", "rtree", "scipy"} <= names, platform


def test_zip_ships_the_addon_its_rigs_and_linux_wheels_only(linux_zip):
    names = set(zipfile.ZipFile(linux_zip).namelist())
    for needed in ("blender_manifest.toml", "__init__.py", "addon/core/kinematics.py", "addon/ui/ops.py",
                   "addon/pipeline.py", "rigs/robots/adept_viper_s650.toml", "rigs/scenes/demo.toml"):
        assert needed in names
    wheels = [n for n in names if n.startswith("wheels/")]
    assert wheels and all(("linux" in w or "-any" in w) for w in wheels)
    assert not [n for n in names if n.startswith(("tests/", "headless/", ".venv/", ".ci/", ".git"))]
    assert not [n for n in names if "__pycache__" in n or n.endswith(".pyc")]


def test_install_enable_use_disable_uninstall(linux_zip, tmp_path):
    env = {**os.environ, "BLENDER_USER_RESOURCES": str(tmp_path / "blender-user")}
    res = subprocess.run([sys.executable, "-c", INSTALL, str(linux_zip), str(tmp_path / "scans")],
                         env=env, capture_output=True, text=True, cwd=tmp_path)
    lines = [ln for ln in res.stdout.splitlines() if ln.startswith("RESULT ")]
    assert res.returncode == 0 and lines, res.stdout[-3000:] + res.stderr[-3000:]
    out = json.loads(lines[0][len("RESULT "):])
    assert out["enabled"]
    assert {"trimesh", "cv2", "rtree", "scipy"} <= set(out["wheels"])  # Blender unpacked the bundled wheels
    assert out["ops"] == ["{'FINISHED'}", "{'FINISHED'}"]
    assert out["cloud_points"] > 500
    assert out["prefs"] == "ScannerPreferences"
    assert out["after_disable"] == {"scene_prop": False, "classes": [], "enabled": False}
    assert out["installed_after_uninstall"] is False
