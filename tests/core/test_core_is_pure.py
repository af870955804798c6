"""addon.core must import without Blender: no bpy, no mathutils, anywhere."""

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

SCRIPT = """
import importlib, pkgutil, sys
sys.modules["bpy"] = None        # any 'import bpy' now raises ImportError
sys.modules["mathutils"] = None
import addon.core
names = [m.name for m in pkgutil.walk_packages(addon.core.__path__, "addon.core.")]
for name in names:
    importlib.import_module(name)
print(len(names))
"""


def test_every_core_module_imports_without_bpy():
    out = subprocess.run([sys.executable, "-c", SCRIPT], cwd=REPO, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert int(out.stdout.strip()) >= 30


def test_no_core_source_mentions_bpy_imports():
    for path in (REPO / "addon" / "core").rglob("*.py"):
        for line in path.read_text().splitlines():
            stripped = line.strip()
            assert not stripped.startswith(("import bpy", "from bpy", "import mathutils", "from mathutils")), path
