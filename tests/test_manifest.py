"""The extension manifest passes Blender's own validator and the zip ships the right files."""

import importlib.util
import subprocess
import sys
import zipfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def blender_ext_tool() -> Path:
    spec = importlib.util.find_spec("bpy")  # locate the wheel without importing Blender
    assert spec is not None and spec.origin
    tool = Path(spec.origin).parent / "5.0" / "scripts" / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py"
    assert tool.is_file(), tool
    return tool


def test_manifest_validates():
    out = subprocess.run([sys.executable, str(blender_ext_tool()), "validate", str(REPO)],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "Success" in out.stdout


def test_built_zip_ships_addon_and_rigs_only(tmp_path):
    out = subprocess.run([sys.executable, str(blender_ext_tool()), "build", "--source-dir", str(REPO),
                          "--output-dir", str(tmp_path)], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr
    (zip_path,) = tmp_path.glob("*.zip")
    names = set(zipfile.ZipFile(zip_path).namelist())
    for needed in ("blender_manifest.toml", "__init__.py", "addon/core/kinematics.py",
                   "rigs/robots/adept_viper_s650.toml", "rigs/robots/ur5.toml"):
        assert needed in names
    assert not [n for n in names if n.startswith(("tests/", "headless/", ".venv/", ".ci/", ".git"))]
    assert not [n for n in names if "__pycache__" in n or n.endswith(".pyc")]
