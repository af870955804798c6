"""The extension manifest passes Blender's own validator and the zip ships the right files."""

import importlib.util
import subprocess
import sys
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

# The built zip's contents, its install and removal: tests/extension/test_install.py.
