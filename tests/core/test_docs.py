"""The code in the subsystem pages runs as written (no Blender needed for these)."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("page", ["kinematics.md", "optics.md"])
def test_the_pages_first_example_runs(page):
    text = (REPO / "docs" / page).read_text()
    code = re.search(r"```python\n(.*?)```", text, re.S).group(1)
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
